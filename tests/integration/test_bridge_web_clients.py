"""Which web pages may open a WebSocket to a real endpoint (--websocket-origin), and the clients' own addresses
behind a trusted proxy that proves itself (--trusted-proxy, --proxy-secret): at the wire, with raw WebSocket
clients."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.integration.bridge_helpers import (
    DiagnosticsInbox,
    RawWebSocket,
    start_endpoint,
    status_values,
)
from tests.rosenv import EndpointProcess, RosCore, wait_for

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))

ATTACKER = (("Origin", "https://attacker.example"),)
SECRET = "the-proxys-secret"
PROVEN = (("X-Proxy-Secret", SECRET),)  # what the proxy adds to prove itself


@pytest.fixture(scope="module")
def bridge(roscore: RosCore, ros_node, tmp_path_factory) -> Iterator[EndpointProcess]:
    """An endpoint with no page allowed; 127.0.0.1 trusted as a proxy, spelled as a dual-stack socket shows it
    (matched as an address), with the proxy's secret from the environment; at most 2 clients an address."""
    process = start_endpoint(
        roscore,
        tmp_path_factory.mktemp("bridge"),
        *("--websocket-port", "0", "--max-clients-per-address", "2", "--trusted-proxy", "::ffff:127.0.0.1"),
        env={"ROS_TCP_PROXY_SECRET": SECRET},
    )
    try:
        yield process
    finally:
        process.stop()


def refusal(port: int, *headers: tuple[str, str]) -> str:
    """The HTTP answer to an upgrade with these headers, which must be a refusal (the connection then closed)."""
    with pytest.raises(ConnectionError) as refused:
        RawWebSocket(port, headers=headers)
    return str(refused.value)


def test_a_page_of_another_origin_is_refused_and_said_and_counted(bridge, ros_node) -> None:
    diagnostics = DiagnosticsInbox(ros_node, "/" + bridge.name)
    try:
        answer = refusal(bridge.websocket_port, *ATTACKER)
        assert "HTTP 403" in answer and "https://attacker.example" in answer and "--websocket-origin" in answer
        wait_for(
            lambda: "its Origin https://attacker.example is not allowed (--websocket-origin)" in bridge.output(),
            10,
            "the refusal in the endpoint's log",
        )
        wait_for(
            lambda: (
                (status := diagnostics.find("endpoint"))
                and int(status_values(status)["WebSocket upgrades refused for their origin"]) >= 1
            ),
            10,
            "the refusal counted on /diagnostics",
        )
        # a client that is not a browser (no Origin) is served as before; so is one after the refusal
        with RawWebSocket(bridge.websocket_port) as ws:
            ws.sync()
    finally:
        diagnostics.close()


def test_a_page_is_served_once_its_origin_is_allowed(roscore, ros_node, tmp_path) -> None:
    endpoint = start_endpoint(
        roscore,
        tmp_path,
        "--websocket-port",
        "0",
        "--websocket-origin",
        "http://localhost:8000",
        "--websocket-origin",
        "https://*.lab.example",
        "--websocket-origin",
        "http://[::1]:8000",  # an IPv6 literal: its brackets are brackets, not a character class
    )
    try:
        for origin in ("http://localhost:8000", "https://VR.Lab.Example", "http://[::1]:8000"):
            with RawWebSocket(endpoint.websocket_port, headers=(("Origin", origin),)) as ws:
                ws.sync()
        assert "HTTP 403" in refusal(endpoint.websocket_port, ("Origin", "http://localhost:8001"))
        assert "HTTP 403" in refusal(endpoint.websocket_port, ("Origin", "http://[::1]:8001"))
        assert "HTTP 403" in refusal(endpoint.websocket_port, ("Origin", "null"))  # a file:// page
    finally:
        endpoint.stop()


def test_allowed_origins_come_from_the_rosparam_too(roscore, ros_node, tmp_path) -> None:
    endpoint = start_endpoint(
        roscore, tmp_path, "--websocket-port", "0", "_websocket_origins:=http://a.example, http://b.example"
    )
    try:
        for origin in ("http://a.example", "http://b.example"):
            with RawWebSocket(endpoint.websocket_port, headers=(("Origin", origin),)) as ws:
                ws.sync()
        assert "HTTP 403" in refusal(endpoint.websocket_port, ("Origin", "http://c.example"))
    finally:
        endpoint.stop()


def test_behind_a_trusted_proxy_each_browser_counts_by_its_own_address(bridge, ros_node) -> None:
    """Three browsers through one local proxy: two from one address fill that address's share (2 here), the other
    address is still served; without the proxy's word all three would be 127.0.0.1, the third refused."""
    diagnostics = DiagnosticsInbox(ros_node, "/" + bridge.name)
    port = bridge.websocket_port
    first = RawWebSocket(port, headers=(("X-Forwarded-For", "192.168.1.7"), *PROVEN))
    second = RawWebSocket(port, headers=(("X-Forwarded-For", "6.6.6.6, 192.168.1.7"), *PROVEN))  # the proxy's is last
    try:
        with RawWebSocket(port, headers=(("X-Forwarded-For", "192.168.1.8"), *PROVEN)) as other:
            other.sync()
        answer = refusal(port, ("X-Forwarded-For", "192.168.1.7"), *PROVEN)
        assert "HTTP 503" in answer and "from 192.168.1.7" in answer and "--max-clients-per-address" in answer
        first.sync()
        local = first.sock.getsockname()[1]
        status = wait_for(lambda: diagnostics.find(f"192.168.1.7 via 127.0.0.1:{local}"), 10, "the client's status")
        assert status_values(status)["address"] == f"192.168.1.7 via 127.0.0.1:{local}"
    finally:
        first.sock.close()
        second.sock.close()
        diagnostics.close()


def test_a_trusted_proxys_address_that_is_none_is_refused(bridge) -> None:
    answer = refusal(bridge.websocket_port, ("X-Forwarded-For", "192.168.1.7, somewhere"), *PROVEN)
    assert "HTTP 400" in answer and "'somewhere'" in answer


def test_an_untrusted_peer_cannot_choose_its_address(roscore, ros_node, tmp_path) -> None:
    """With another proxy trusted, 127.0.0.1's X-Forwarded-For is ignored: its clients count as 127.0.0.1, and the
    limit per address holds at connect."""
    endpoint = start_endpoint(
        roscore,
        tmp_path,
        *("--websocket-port", "0", "--trusted-proxy", "10.9.9.9", "--max-clients-per-address", "1"),
    )
    try:
        with RawWebSocket(endpoint.websocket_port, headers=(("X-Forwarded-For", "192.168.1.7"),)) as ws:
            ws.sync()
            answer = refusal(endpoint.websocket_port, ("X-Forwarded-For", "192.168.1.8"))
            assert "HTTP 503" in answer and "from 127.0.0.1" in answer
    finally:
        endpoint.stop()


def test_without_the_secret_a_trusted_address_cannot_choose_its_clients_address(roscore, ros_node, tmp_path) -> None:
    """The attack: a local process (127.0.0.1, the trusted proxy's address) guesses tokens, each connection naming
    another X-Forwarded-For to dodge the back-off after wrong tokens. Without the proxy's secret, or with a wrong
    one, the header is ignored (and said): every wrong token counts against 127.0.0.1, so the back-off doubles each
    time. (The 5th failure is logged although such lines are throttled to one a second: its verdict was held back
    1.6 s. Were the header believed, each address would have 1 failure and the line would not be there.)"""
    endpoint = start_endpoint(
        roscore,
        tmp_path,
        *("--websocket-port", "0", "--auth-token", "right-token", "--proxy-secret", SECRET),
    )
    try:
        for attempt in range(1, 6):
            secret = () if attempt % 2 else (("X-Proxy-Secret", "a-guess"),)
            headers = (("X-Forwarded-For", f"10.0.0.{attempt}"), *secret)
            with RawWebSocket(endpoint.websocket_port, headers=headers) as ws:
                ws.command("__auth", token="a-wrong-token")
                ws.expect_error("authentication required")
                ws.wait_eof()
        wait_for(
            lambda: "a wrong token, 5 in a row from 127.0.0.1" in endpoint.output(),
            10,
            "5 wrong tokens from one address",
        )
        output = endpoint.output()
        assert (
            "X-Forwarded-For ignored, its request carries no X-Proxy-Secret; the client counts as 127.0.0.1" in output
        )
        assert " via 127.0.0.1" not in output and "from 10.0.0." not in output
        # the proxy that proves itself is believed: its client is backed off by its own address
        with RawWebSocket(endpoint.websocket_port, headers=(("X-Forwarded-For", "10.0.0.9"), *PROVEN)) as ws:
            ws.command("__auth", token="right-token")
            ws.sync()
            wait_for(lambda: "10.0.0.9 via 127.0.0.1:" in endpoint.output(), 10, "the proxy's client by its address")
    finally:
        endpoint.stop()


def test_with_no_proxy_secret_set_no_forwarded_address_is_believed(roscore, ros_node, tmp_path) -> None:
    """127.0.0.1 is trusted by default, but without --proxy-secret nothing can prove itself that proxy: its
    X-Forwarded-For is ignored, and its clients count as 127.0.0.1 (the limit per address holds at connect)."""
    endpoint = start_endpoint(roscore, tmp_path, *("--websocket-port", "0", "--max-clients-per-address", "1"))
    try:
        with RawWebSocket(endpoint.websocket_port, headers=(("X-Forwarded-For", "192.168.1.7"), *PROVEN)) as ws:
            ws.sync()
            answer = refusal(endpoint.websocket_port, ("X-Forwarded-For", "192.168.1.8"), *PROVEN)
            assert "HTTP 503" in answer and "from 127.0.0.1" in answer
        assert "X-Forwarded-For ignored, no --proxy-secret is set" in endpoint.output()
    finally:
        endpoint.stop()
