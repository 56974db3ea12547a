"""bridge.web_clients: which pages may open a WebSocket, and the client's address behind a trusted proxy."""

from __future__ import annotations

import pytest

from bridge.web_clients import forwarded_client, origin_allowed


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
