"""bridge.admission.web_clients: which pages may open a WebSocket, and the client's address behind a trusted proxy."""

from __future__ import annotations

import pytest

from bridge.admission.web_clients import (
    forwarded_client,
    normal_address,
    origin_allowed,
    proxy_doubt,
    trusted_addresses,
)


@pytest.mark.parametrize(
    "origin, patterns, allowed",
    [
        (None, (), True),  # not a browser: served as a TCP client is
        ("https://attacker.example", (), False),  # by default no page may
        ("http://localhost:8000", ("http://localhost:8000",), True),
        ("HTTP://LocalHost:8000/", ("http://localhost:8000",), True),  # scheme and host are case-insensitive
        ("http://localhost:8001", ("http://localhost:8000",), False),  # another port is another origin
        ("https://vr.lab.example", ("https://*.lab.example",), True),
        ("https://lab.example.attacker.example", ("https://*.lab.example",), False),
        ("https://anything.example", ("*",), True),
        ("null", ("*",), False),  # an opaque origin (a file, a sandboxed frame) only by name
        ("null", ("null",), True),
        # an IPv6 literal's brackets are brackets, not a character class
        ("http://[::1]:8000", ("http://[::1]:8000",), True),
        ("http://[::1]:8000", ("http://[0:0::1]:8000",), False),  # origins are compared as written, not as addresses
        ("http://:", ("http://[::1]",), False),
        ("http://[::1]:8001", ("http://[::1]:*",), True),  # `*` is still a wildcard beside them
        ("http://[fe80::1]:8000", ("http://[::1]:*",), False),
        # `*` is the only wildcard: `?` and brackets in a pattern stand for themselves
        ("http://a.example", ("http://?.example",), False),
        ("http://a.example", ("http://[ab].example",), False),
        ("http://a.example", ("http://*.example",), True),
    ],
)
def test_an_origin_is_allowed_only_by_a_pattern(origin, patterns, allowed) -> None:
    assert origin_allowed(origin, patterns) is allowed


def test_the_proxys_own_entry_names_the_client() -> None:
    assert forwarded_client(None) is None
    assert forwarded_client("192.168.1.7") == "192.168.1.7"
    # what the client itself wrote comes first and proves nothing; the proxy appended the last entry
    assert forwarded_client("6.6.6.6, 192.168.1.7") == "192.168.1.7"
    assert forwarded_client(" fe80::1 ") == "fe80::1"


@pytest.mark.parametrize("header", ["", "192.168.1.7, unknown", "example.org", "1.2.3.4:5678"])
def test_an_entry_that_is_no_address_is_an_error_that_names_it(header: str) -> None:
    with pytest.raises(ValueError, match="not an IP address"):
        forwarded_client(header)


@pytest.mark.parametrize(
    "text, normal",
    [
        ("127.0.0.1", "127.0.0.1"),
        ("::ffff:127.0.0.1", "127.0.0.1"),  # a dual-stack socket's view of an IPv4 peer
        ("::FFFF:7f00:1", "127.0.0.1"),
        ("0:0:0:0:0:0:0:1", "::1"),
        (" FE80::0001 ", "fe80::1"),
    ],
)
def test_addresses_are_compared_as_addresses_not_as_strings(text: str, normal: str) -> None:
    assert normal_address(text) == normal
    assert normal in trusted_addresses([text])


def test_an_address_that_is_none_cannot_be_made_normal() -> None:
    with pytest.raises(ValueError):
        normal_address("localhost")


def test_a_forwarded_address_is_kept_normal() -> None:
    assert forwarded_client("6.6.6.6, ::ffff:192.168.1.7") == "192.168.1.7"


@pytest.mark.parametrize(
    "secret, given, doubt",
    [
        (None, None, "no --proxy-secret is set"),
        (None, "anything", "no --proxy-secret is set"),  # without a secret of its own the endpoint believes no one
        ("s3cret", None, "carries no X-Proxy-Secret"),
        ("s3cret", "guess", "X-Proxy-Secret is wrong"),
        ("s3cret", "s3cret ", "X-Proxy-Secret is wrong"),
        ("s3cret", "", "X-Proxy-Secret is wrong"),
    ],
)
def test_a_proxy_that_does_not_prove_itself_is_doubted_and_said_why(secret, given, doubt) -> None:
    found = proxy_doubt(secret, given)
    assert found is not None and doubt in found


def test_a_proxy_with_the_secret_proves_itself() -> None:
    assert proxy_doubt("s3cret", "s3cret") is None
