"""Who the page's server answers (sim.study.views.vr.access) and what it tells the endpoint for a page
(sim.study.views.vr.relay), as pure decisions: the Host allow-list, the launch's key, the WebSocket's Origin, the
upgrade passed on and the `__auth` sent for the page."""

from __future__ import annotations

import json
import struct

import pytest
from wsproto.frame_protocol import FrameProtocol, Opcode

from sim.study.views.vr.access import Access, host_name, is_host_name, normal_names
from sim.study.views.vr.relay import auth_message, upgrade_request

KEY = "k3y-of-this-launch"
NAMES = ["labpc", "labpc.lab.example", "192.168.1.10", "fe80::1", "vr.lab.example."]  # the machine's, and one given
ACCESS = Access(KEY, normal_names(NAMES), "https")
COOKIE = f"{ACCESS.cookie}={KEY}"


@pytest.mark.parametrize(
    ("host", "name"),
    [
        ("localhost:8443", "localhost"),
        ("LabPC", "labpc"),
        ("vr.lab.example.:8443", "vr.lab.example"),
        ("[::1]:8443", "::1"),
        ("[fe80::1]", "fe80::1"),
        ("192.168.1.10:8443", "192.168.1.10"),
        ("", ""),
        ("[::1", ""),
    ],
)
def test_the_name_in_a_host_header(host: str, name: str) -> None:
    assert host_name(host) == name


@pytest.mark.parametrize(
    ("name", "valid"),
    [
        ("lab.example", True),
        ("labpc", True),
        ("vr-lab.local.", True),
        ("192.168.1.10", True),
        ("fe80::1", True),
        ("https://lab.example", False),
        ("lab.example:8443", False),
        ("lab.example/", False),
        ("-lab", False),
        ("", False),
    ],
)
def test_a_name_given_to_allow_is_a_host_name_or_an_address_alone(name: str, valid: bool) -> None:
    assert is_host_name(name) is valid


@pytest.mark.parametrize(
    "host",
    [
        "localhost:8443",
        "127.0.0.1:8443",
        "127.0.0.2",  # every loopback address is this machine
        "[::1]:8443",
        "LABPC:8443",
        "labpc.lab.example",
        "192.168.1.10:9999",  # any port: adb reverse or a forwarded port may show the browser another
        "[fe80:0:0::1]:8443",  # an address as written any way
        "vr.lab.example:8443",  # a name the user gave
    ],
)
def test_this_machines_names_and_addresses_and_the_names_given_are_served(host: str) -> None:
    assert ACCESS.refusal(host, "/", COOKIE, "", websocket=False) is None


@pytest.mark.parametrize(
    "host",
    [
        "evil.example:8443",  # a forged Host, or a rebinding page's own name
        "labpc.evil.example",
        "localhost.evil.example",
        "192.168.1.99:8443",  # a LAN address that is not this machine's
        "10.0.0.5",
        "[fe80::2]:8443",
        "",
    ],
)
def test_any_other_host_is_refused_even_with_the_key(host: str) -> None:
    refusal = ACCESS.refusal(host, f"/?key={KEY}", COOKIE, "", websocket=False)
    assert refusal is not None and repr(host) in refusal and "--allow-host" in refusal


@pytest.mark.parametrize(
    ("target", "cookie", "served"),
    [
        (f"/?key={KEY}", "", True),  # the printed address
        (f"/app/page.js?x=1&key={KEY}", "", True),
        ("/settings.json", COOKIE, True),  # the page's own requests, by the cookie set from the address
        ("/settings.json", f"other=1; {COOKIE}; more=2", True),
        ("/settings.json", f"{ACCESS.cookie}=stale; {COOKIE}", True),  # an old launch's cookie beside this one's
        ("/settings.json", "", False),
        ("/", f"{ACCESS.cookie}=stale", False),
        ("/?key=guess", "", False),
        (f"/?key={KEY}x", "", False),
        (f"/?KEY={KEY}", "", False),
        ("/", f"sim_study_key_1={KEY}x", False),
        ("/", f"elsewhere={KEY}", False),  # the key in another server's cookie does not count
    ],
)
def test_a_request_needs_the_launchs_key_in_its_query_or_cookie(target: str, cookie: str, served: bool) -> None:
    refusal = ACCESS.refusal("localhost:8443", target, cookie, "", websocket=False)
    assert (refusal is None) == served, refusal
    if not served:
        assert "key" in refusal and KEY not in refusal


def test_a_websocket_opens_only_for_the_servers_own_page() -> None:
    assert ACCESS.refusal("localhost:8443", "/ros", COOKIE, "https://localhost:8443", websocket=True) is None
    assert ACCESS.refusal("localhost:8443", "/ros", COOKIE, "", websocket=True) is None  # not a browser: by the key
    # another page of this machine carries the cookie (cookies are not kept apart by port), not its origin
    for origin in ("https://localhost:8000", "http://localhost:8443", "https://evil.example"):
        refusal = ACCESS.refusal("localhost:8443", "/ros", COOKIE, origin, websocket=True)
        assert refusal is not None and origin in refusal
    # the rebinding page: its Host and Origin agree with each other, its name is not this machine's
    refusal = ACCESS.refusal("evil.example:8443", "/ros", "", "https://evil.example:8443", websocket=True)
    assert refusal is not None and "evil.example" in refusal


def test_the_cookie_and_the_printed_address() -> None:
    assert ACCESS.set_cookie() == f"{ACCESS.cookie}={KEY}; Path=/; HttpOnly; SameSite=Strict; Secure"
    plain = Access(KEY, frozenset(), "http", cookie="sim_study_key_8444")
    assert plain.set_cookie() == f"sim_study_key_8444={KEY}; Path=/; HttpOnly; SameSite=Strict"
    assert plain.page_address("localhost", 8444) == f"http://localhost:8444/?key={KEY}"
    assert ACCESS.page_address("fe80::1", 8443) == f"https://[fe80::1]:8443/?key={KEY}"


def test_the_upgrade_passed_on_is_the_servers_word_not_the_clients() -> None:
    headers = [
        (b"Host", b"localhost:8443"),
        (b"Upgrade", b"websocket"),
        (b"Origin", b"https://localhost:8443"),
        (b"Cookie", COOKIE.encode()),
        (b"X-Forwarded-For", b"6.6.6.6"),
        (b"x-proxy-secret", b"guessed"),
        (b"Forwarded", b"for=6.6.6.6"),
        (b"Sec-WebSocket-Key", b"dGhlIHNhbXBsZSBub25jZQ=="),
    ]
    head = upgrade_request(b"GET", b"/ros", headers, "192.168.1.7", "proxy-secret")
    assert head == (
        b"GET /ros HTTP/1.1\r\nHost: localhost:8443\r\nUpgrade: websocket\r\n"
        b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nX-Forwarded-For: 192.168.1.7\r\n"
        b"X-Proxy-Secret: proxy-secret\r\n\r\n"
    )
    without = upgrade_request(b"GET", b"/ros", headers, "127.0.0.1", None)
    assert b"X-Proxy-Secret" not in without and b"guessed" not in without and KEY.encode() not in without


@pytest.mark.parametrize("token", ["s3cret", "t" * 200, "t" * 70_000, "ünïcode"])
def test_the_auth_message_is_one_masked_binary_websocket_message_of_the_auth_command(token: str) -> None:
    mask = b"\x01\x02\xfe\xff"
    message = auth_message(token, mask)
    reader = FrameProtocol(client=False, extensions=[])  # the endpoint's side: it requires masked frames
    reader.receive_bytes(message)
    (frame,) = list(reader.received_frames())
    assert frame.opcode is Opcode.BINARY and frame.frame_finished and frame.message_finished
    payload = bytes(frame.payload)
    (length,) = struct.unpack_from("<I", payload)
    assert payload[4 : 4 + length] == b"__auth"
    (body_length,) = struct.unpack_from("<I", payload, 4 + length)
    body = payload[8 + length :]
    assert len(body) == body_length and json.loads(body) == {"token": token}
    with pytest.raises(ValueError, match="4 bytes"):
        auth_message(token, b"\x00")
