"""The page's server (`python -m sim.study button`, the VR page's server) in front of a token-protected endpoint, at
the wire on loopback: only a client that carries the launch's key, names this machine in its Host and, as a browser,
comes from the server's own page reaches the endpoint, and it is authenticated there by the server. A forged Host, a
client without the key, a DNS-rebinding page (its Host and Origin agree with each other, not with this machine), a
LAN address that is not this machine's in Host, and another page of this machine each get an HTTP 403 that says
why; the server listens on 127.0.0.1 alone unless told, which a headset on a LAN of network namespaces sees. The
pages' whole session in browsers is test_study_browser_session.py's, with a token too."""

from __future__ import annotations

import json
import os
import socket
import subprocess
from pathlib import Path

import pytest

from bridge.client import ClientError, TcpClient
from measuring.browser import chromium, launch_secrets
from sim.launchers import ButtonServer, start
from sim.processes import PYTHON, EndpointProcess, ManagedProcess, plain_env
from sim.study.views.vr.relay import AUTH_TOKEN_ENV
from tests.rosenv import RosCore, wait_for

pytestmark = pytest.mark.lane("beside", on=("project",))

TOKEN = "the-endpoints-token"


def start_page_server(endpoint: EndpointProcess, log_dir: Path, env: dict[str, str]) -> tuple[ManagedProcess, str]:
    """The button page's server over plain HTTP on a free port of 127.0.0.1; with the printed address's key."""
    launcher = ButtonServer(endpoint.websocket_port or 0, plain_http=True)
    server = start(launcher, {**plain_env(), **env}, log_dir, "button")
    return server, launcher.page_url(server.output())


def ask(port: int, request: str, address: str = "127.0.0.1") -> tuple[str, str, str]:
    """Send one raw HTTP request; the answer's status line, its head, and its body, read to the server's close or
    the end of a 101's head."""
    with socket.create_connection((address, port), timeout=10) as sock:
        sock.sendall(request.encode("latin-1"))
        answer = b""
        while b"\r\n\r\n" not in answer or not answer.startswith(b"HTTP/1.1 101"):
            data = sock.recv(65536)
            if not data:
                break
            answer += data
    head, _, body = answer.decode("latin-1").partition("\r\n\r\n")
    return head.split("\r\n", 1)[0], head, body


def get(target: str, host: str, *headers: str) -> str:
    return "\r\n".join([f"GET {target} HTTP/1.1", f"Host: {host}", "Connection: close", *headers, "", ""])


def upgrade(target: str, host: str, *headers: str) -> str:
    return get(
        target,
        host,
        "Upgrade: websocket",
        "Connection: Upgrade",
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==",
        "Sec-WebSocket-Version: 13",
        *headers,
    ).replace("Connection: close\r\n", "")


def test_only_the_printed_address_reaches_the_token_protected_endpoint(roscore: RosCore, tmp_path: Path) -> None:
    secrets = launch_secrets(TOKEN)
    endpoint = EndpointProcess(
        {**roscore.env, **secrets}, tmp_path, "endpoint_pages", extra=["--websocket-port", "0", "--auth-token", TOKEN]
    )
    processes: list[ManagedProcess] = [endpoint]
    try:
        server, url = start_page_server(endpoint, tmp_path / "server", secrets)
        processes.append(server)
        port = int(url.split(":")[2].split("/")[0])
        key = url.split("?key=")[1]
        here = f"localhost:{port}"
        assert url == f"http://{here}/?key={key}" and len(key) >= 20

        # Loopback only by default: the server is not there on another address of this machine
        with pytest.raises(ConnectionRefusedError):
            socket.create_connection(("127.0.0.2", port), timeout=10).close()

        # The printed address serves the page and sets the key's cookie; the page's own requests carry the cookie
        status, head, body = ask(port, get(f"/?key={key}", here))
        assert status == "HTTP/1.1 200 OK" and "button.js" in body, (status, body)
        cookie = next(line for line in head.split("\r\n") if line.startswith("Set-Cookie: ")).split(": ", 1)[1]
        assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
        cookie = cookie.split(";", 1)[0]
        assert ask(port, get("/settings.json", here, f"Cookie: {cookie}"))[0] == "HTTP/1.1 200 OK"

        refused = {
            # a client without the key: the page, what reveals the endpoint, and the WebSocket
            "no key, the page": get("/", here),
            "no key, the settings": get("/settings.json", here),
            "no key, the WebSocket": upgrade("/ros", here, f"Origin: http://{here}"),
            "a wrong key": upgrade("/ros?key=guessed", here, "Cookie: sim_study_key_1=guessed"),
            # a forged Host, with the key
            "a forged Host": get(f"/?key={key}", f"evil.example:{port}"),
            # DNS rebinding: a foreign page whose name now points here, its Host and Origin agreeing
            "a rebinding page": upgrade("/ros", f"rebind.example:{port}", f"Origin: http://rebind.example:{port}"),
            "a rebinding page with the key": upgrade(
                f"/ros?key={key}", f"rebind.example:{port}", f"Origin: http://rebind.example:{port}"
            ),
            # a LAN address that is not this machine's
            "a LAN address": get(f"/?key={key}", f"192.168.77.5:{port}"),
            # another page of this machine's name carries the cookie (not kept apart by port), not the server's origin
            "another local page": upgrade("/ros", here, "Origin: http://localhost:8000", f"Cookie: {cookie}"),
        }
        answers = {what: ask(port, request) for what, request in refused.items()}
        assert {what: status for what, (status, _, _) in answers.items()} == dict.fromkeys(
            refused, "HTTP/1.1 403 Forbidden"
        )
        for what in ("no key, the page", "no key, the settings", "no key, the WebSocket", "a wrong key"):
            assert "does not carry this launch's key" in answers[what][2], (what, answers[what])
        for what in ("a forged Host", "a rebinding page", "a rebinding page with the key", "a LAN address"):
            assert "this machine's names and addresses only" in answers[what][2], (what, answers[what])
        assert "'192.168.77.5:" in answers["a LAN address"][2] and "--allow-host" in answers["a LAN address"][2]
        assert "not the page http://localhost:8000" in answers["another local page"][2]
        assert key not in "".join(body for _, _, body in answers.values())
        wait_for(lambda: "button: refused / to 127.0.0.1: " in server.output(), 10, "a refusal in the server's log")

        # The server's own client, with the key, is authenticated to the endpoint by the server: it never sends the
        # token, and its ping (which the endpoint answers only once authenticated) comes back
        with TcpClient("127.0.0.1", port, websocket=True, websocket_path=f"/ros?key={key}", reconnect=False) as client:
            client.connect(timeout=10)
            assert client.ping(timeout=10).round_trip_s > 0
        assert TOKEN not in server.output()
        wait_for(lambda: "authenticated" in endpoint.output(), 10, "the page's client authenticated")

        # Without the token the same client is refused by the endpoint: the server's __auth is what let it in
        server.stop()
        tokenless = {name: value for name, value in secrets.items() if name != AUTH_TOKEN_ENV}
        server, url = start_page_server(endpoint, tmp_path / "tokenless", tokenless)
        processes.append(server)
        port = int(url.split(":")[2].split("/")[0])
        key = url.split("?key=")[1]
        with TcpClient("127.0.0.1", port, websocket=True, websocket_path=f"/ros?key={key}", reconnect=False) as client:
            client.connect(timeout=10)
            with pytest.raises(ClientError):
                client.ping(timeout=5)
            wait_for(lambda: any("authentication required" in error for error in client.errors), 10, "the refusal")
    finally:
        for process in reversed(processes):
            process.stop()


@pytest.mark.lane("alone", on=("project",))
def test_a_browser_that_opened_the_printed_address_is_served_and_one_without_its_key_is_not(
    roscore: RosCore, tmp_path: Path
) -> None:
    """In a real browser (headless Chromium) the cookie that keeps the key carries the page's modules, settings and
    WebSocket: the button page connects to the token-protected endpoint and its clock's pings are answered. The same
    page opened without the key gets the refusal, and no module of it runs."""
    secrets = launch_secrets(TOKEN)
    endpoint = EndpointProcess(
        {**roscore.env, **secrets}, tmp_path, "endpoint_browser", extra=["--websocket-port", "0", "--auth-token", TOKEN]
    )
    processes: list[ManagedProcess] = [endpoint]
    try:
        launcher = ButtonServer(endpoint.websocket_port or 0, emulate_gamepad=True, certificate_dir=tmp_path / "cert")
        server = start(launcher, {**plain_env(), **secrets}, tmp_path, "button")
        processes.append(server)
        url = launcher.page_url(server.output())
        key = url.split("?key=")[1]
        with chromium(tmp_path / "chromium", accept_insecure_certs=True) as browser:
            browser.get(url.split("?")[0])
            assert "does not carry this launch's key" in browser.page_source
            assert browser.execute_script("return window.buttonPage === undefined;")
            browser.get(url)
            state = "return window.buttonPage ? window.buttonPage.state() : null;"
            wait_for(
                lambda: (s := browser.execute_script(state)) and s["connected"] and s["clockRoundTripMs"] is not None,
                60,
                "the page to connect and its clock to be answered",
            )
            # the page has used the key (its settings came by the cookie), so the key has left the tab's address and
            # its back/forward list (DevTools' view of it): the entry was replaced
            assert browser.execute_script("return location.href;") == url.split("?")[0]
            visited = [entry["url"] for entry in browser.execute_cdp_cmd("Page.getNavigationHistory", {})["entries"]]
            assert visited[-2:] == [url.split("?")[0]] * 2 and not any(key in entry for entry in visited), visited
            # the address without its key now works too, by the cookie: a reload of the page, or a bookmark of it
            browser.get(url.split("?")[0])
            wait_for(lambda: (s := browser.execute_script(state)) and s["connected"], 60, "the page by its cookie")
            assert TOKEN not in browser.page_source
    finally:
        for process in reversed(processes):
            process.stop()


# What a headset on the LAN asks the lab machine's page server, run in the headset's network namespace: the status of
# each GET (argv: the scheme, the server's address, its port, then Host and target pairs), or "refused" when the
# connection is refused; over HTTPS it accepts the server's self-signed certificate, as the headset's user does once
_HEADSET = """
import http.client, json, ssl, sys
scheme, address, port, asks = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
answers = []
for host, target in zip(asks[::2], asks[1::2]):
    if scheme == "https":
        connection = http.client.HTTPSConnection(
            address, port, timeout=10, context=ssl._create_unverified_context()
        )
    else:
        connection = http.client.HTTPConnection(address, port, timeout=10)
    try:
        connection.putrequest("GET", target, skip_host=True)
        connection.putheader("Host", host)
        connection.endheaders()
        answers.append(connection.getresponse().status)
    except ConnectionRefusedError:
        answers.append("refused")
    finally:
        connection.close()
print(json.dumps(answers))
"""


@pytest.fixture
def lan(tmp_path: Path):
    """Two network namespaces, the lab machine and a headset, on a LAN of their own (a veth pair); the lab machine's
    default route leaves by it, as a LAN address's does. Yields (lab, headset, the lab's address, the headset's);
    removed afterwards."""
    tag = f"{os.getpid() % 100000}"
    lab, headset = f"pslab{tag}", f"pshead{tag}"
    lab_address, headset_address = "10.77.0.1", "10.77.0.2"
    made = []
    try:
        for namespace in (lab, headset):
            subprocess.run(["ip", "netns", "add", namespace], check=True, capture_output=True)
            made.append(namespace)
            subprocess.run(["ip", "-n", namespace, "link", "set", "lo", "up"], check=True)
        subprocess.run(
            [
                "ip",
                "link",
                "add",
                f"pl{tag}",
                "netns",
                lab,
                "type",
                "veth",
                "peer",
                "name",
                f"ph{tag}",
                "netns",
                headset,
            ],
            check=True,
        )
        for namespace, device, address in ((lab, f"pl{tag}", lab_address), (headset, f"ph{tag}", headset_address)):
            subprocess.run(["ip", "-n", namespace, "addr", "add", f"{address}/24", "dev", device], check=True)
            subprocess.run(["ip", "-n", namespace, "link", "set", device, "up"], check=True)
        subprocess.run(["ip", "-n", lab, "route", "add", "default", "via", headset_address], check=True)
        yield lab, headset, lab_address, headset_address
    finally:
        for namespace in made:
            subprocess.run(["ip", "netns", "delete", namespace], capture_output=True)


def test_a_headset_on_the_lan_gets_the_page_by_the_machines_address_only_when_the_server_is_told_to_listen(
    lan, tmp_path: Path
) -> None:
    """By default the server is not on the LAN at all; with --host 0.0.0.0 (over HTTPS: plain HTTP is for loopback
    only) a headset that names the machine's LAN address (which the server finds itself) and carries the key gets the
    page, and one that names another address, or carries no key, gets a 403."""
    lab, headset, lab_address, _ = lan
    inside = ("ip", "netns", "exec", lab)
    processes: list[ManagedProcess] = []
    try:
        default = ButtonServer(9, plain_http=True)
        # on the LAN over HTTPS only: plain HTTP is refused with any host but a loopback one
        everywhere = ButtonServer(9, host="0.0.0.0", certificate_dir=tmp_path / "certificate")
        closed = start(default, plain_env(), tmp_path, "default", prefix=inside)
        processes.append(closed)
        opened = start(everywhere, plain_env(), tmp_path, "everywhere", prefix=inside)
        processes.append(opened)
        closed_port = int(default.page_url(closed.output()).split(":")[2].split("/")[0])
        printed = [line.split("the page: ")[1] for line in opened.output().splitlines() if "the page: " in line]
        assert f"https://{lab_address}:" in " ".join(printed), printed  # the machine's LAN address, found and printed
        url = next(address for address in printed if lab_address in address)
        port, key = int(url.split(":")[2].split("/")[0]), url.split("?key=")[1]

        def from_headset(scheme: str, address: str, port: int, *asks: str) -> list[object]:
            done = subprocess.run(
                ["ip", "netns", "exec", headset, PYTHON, "-c", _HEADSET, scheme, address, str(port), *asks],
                capture_output=True,
                text=True,
                timeout=60,
            )
            assert done.returncode == 0, done.stderr
            return json.loads(done.stdout)

        assert from_headset("http", lab_address, closed_port, f"{lab_address}:{closed_port}", "/") == ["refused"]
        here = f"{lab_address}:{port}"
        assert from_headset(
            "https",
            lab_address,
            port,
            *(here, f"/?key={key}"),  # the machine's LAN address, with the key
            *(here, "/"),  # without it
            *(f"10.77.0.99:{port}", f"/?key={key}"),  # another address of the LAN
            *(f"lab.evil.example:{port}", f"/?key={key}"),  # a rebinding page's name
        ) == [200, 403, 403, 403]
    finally:
        for process in reversed(processes):
            process.stop()
