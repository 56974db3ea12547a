"""The VR page's web server (and the stop button page's, sim.study.views.vr.site): HTTPS (or plain HTTP for
localhost) serving the page, the robot's meshes and the settings, and `/ros`, a WebSocket passed through byte for
byte to the endpoint's WebSocket port.

A headset's browser reaches the machine by a LAN address, and WebXR needs a secure context: an https:// page, whose
WebSocket must then be wss:// too. The endpoint speaks plain ws://, so this server ends TLS and hands the WebSocket
on: the page and its WebSocket share one origin and one certificate, and the endpoint sees one more WebSocket
client, which does the whole ROS-TCP conversation itself.

Only the pages this server served, in the browsers that loaded them, reach the endpoint: every request must name
this machine in its Host and carry this launch's key, and a WebSocket's Origin must be the server's own
(sim.study.views.vr.access says why each; HTTP 403 otherwise). The upgrade goes on without the Origin and the
cookie, with the browser's address in X-Forwarded-For and the endpoint's proxy secret when it has one
(sim.study.views.vr.relay), and, when the endpoint wants a token, this server's `__auth` first: the page never
holds the token.

asyncio, so one thread serves every connection, TLS included; h11 parses the requests.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import dataclasses
import hashlib
import json
import os
import re
import signal
import ssl
import time
from collections.abc import Callable
from urllib.parse import unquote

import h11

from sim.study.views.vr.access import Access
from sim.study.views.vr.relay import auth_message, upgrade_request
from sim.study.views.vr.site import ROS_PATH, Site, content_type

__all__ = ["PageServer", "serve"]

MAX_HEAD_BYTES = 16 * 1024  # a request's line and headers
HEAD_TIMEOUT_S = 30.0  # for a request to arrive on an open connection (browsers keep idle connections a while)
CHUNK = 64 * 1024
_REASONS = {200: b"OK", 404: b"Not Found", 405: b"Method Not Allowed"}
REFUSALS_LOGGED_EVERY_S = 1.0  # a program knocking on the port must not flood the log


class PageServer:
    """Serves `site` on (host, port) to the requests `access` admits until `stop()`; the WebSocket at /ros goes to
    the endpoint at `endpoint`, authenticated with `auth_token` and shown `proxy_secret` when they are given."""

    def __init__(
        self,
        site: Site,
        endpoint: tuple[str, int],
        host: str,
        port: int,
        tls: ssl.SSLContext | None,
        access: Access,
        auth_token: str | None = None,
        proxy_secret: str | None = None,
        log: Callable[[str], None] = print,
    ) -> None:
        self.site, self.endpoint, self.host, self.port, self.tls, self.log = site, endpoint, host, port, tls, log
        self.access, self.auth_token, self.proxy_secret = access, auth_token, proxy_secret
        self._server: asyncio.AbstractServer | None = None
        self._policy = _content_security_policy((site.web_dir / site.entry).read_text())
        self._refusals_unlogged = 0
        self._refusal_logged_at = -REFUSALS_LOGGED_EVERY_S

    async def start(self) -> int:
        """Listen; the port (the one picked, for port 0), which names the cookie that keeps the key: a browser keeps
        one machine's cookies together whatever their port, and two servers must not overwrite each other's."""
        self._server = await asyncio.start_server(self._connection, self.host, self.port, ssl=self.tls)
        port = int(self._server.sockets[0].getsockname()[1])
        self.access = dataclasses.replace(self.access, cookie=f"sim_study_key_{port}")
        return port

    async def serve_until(self, stopped: asyncio.Event) -> None:
        await stopped.wait()
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()

    async def _connection(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        http = h11.Connection(h11.SERVER, max_incomplete_event_size=MAX_HEAD_BYTES)
        try:
            while True:
                request = await _read_request(http, reader)
                if request is None:
                    return
                target = request.target.decode("ascii", "replace")
                path = unquote(target.split("?", 1)[0])
                websocket = path == ROS_PATH and _header(request, b"upgrade").lower() == b"websocket"
                refusal = self.access.refusal(
                    _text(request, b"host"), target, _text(request, b"cookie"), _text(request, b"origin"), websocket
                )
                if refusal is not None:
                    self._log_refusal(writer, path, refusal)
                    _refuse(writer, "403 Forbidden", refusal)
                    await writer.drain()
                    return
                if websocket:
                    await self._pass_through(request, http.trailing_data[0], reader, writer)
                    return
                await self._respond(http, writer, request, path, self.access.secret_in_query(target))
                if http.our_state is h11.MUST_CLOSE:
                    return
                http.start_next_cycle()
        except h11.RemoteProtocolError as error:  # not HTTP, or too long a head: say so, and end this connection
            with contextlib.suppress(ConnectionError, OSError, ssl.SSLError):
                body = f"bad request: {error}\n".encode()
                writer.write(
                    f"HTTP/1.1 {error.error_status_hint} Bad Request\r\nConnection: close\r\n"
                    f"Content-Type: text/plain; charset=utf-8\r\nContent-Length: {len(body)}\r\n\r\n".encode()
                    + body
                )
                await writer.drain()
        except (ConnectionError, asyncio.TimeoutError, ssl.SSLError, OSError):
            return  # a client that went away or stalled: only its connection ends
        finally:
            writer.close()

    def _log_refusal(self, writer: asyncio.StreamWriter, path: str, refusal: str) -> None:
        """One line for a refused request, at most one a second (with how many went unlogged since)."""
        now = time.monotonic()
        if now - self._refusal_logged_at < REFUSALS_LOGGED_EVERY_S:
            self._refusals_unlogged += 1
            return
        unlogged = f" ({self._refusals_unlogged} more refused since the last line)" if self._refusals_unlogged else ""
        self._refusal_logged_at, self._refusals_unlogged = now, 0
        peer = writer.get_extra_info("peername")
        self.log(f"{self.site.page}: refused {path} to {peer[0] if peer else '?'}: {refusal}{unlogged}")

    async def _respond(
        self, http: h11.Connection, writer: asyncio.StreamWriter, request: h11.Request, path: str, keep: bool
    ) -> None:
        """Answer a GET or HEAD; `keep`: the request named the key in its query, which the page keeps as a cookie
        for its own requests."""
        if request.method not in (b"GET", b"HEAD"):
            status, body, kind = 405, b"only GET and HEAD\n", "text/plain; charset=utf-8"
        else:
            status, body, kind = await self._content(path)
        headers = [
            ("Content-Type", kind),
            ("Content-Length", str(len(body))),
            ("Cache-Control", "no-cache"),
            ("Content-Security-Policy", self._policy),
            ("X-Content-Type-Options", "nosniff"),
            ("Referrer-Policy", "same-origin"),  # the page's address holds the key
        ]
        if keep:
            headers.append(("Set-Cookie", self.access.set_cookie()))
        writer.write(http.send(h11.Response(status_code=status, headers=headers, reason=_REASONS[status])))
        if request.method != b"HEAD":
            writer.write(http.send(h11.Data(data=body)))
        writer.write(http.send(h11.EndOfMessage()))
        await writer.drain()

    async def _content(self, path: str) -> tuple[int, bytes, str]:
        if path == "/settings.json":
            return 200, json.dumps(self.site.settings).encode(), "application/json"
        if path == "/robot.urdf" and self.site.urdf:
            return 200, self.site.urdf.encode(), "application/xml; charset=utf-8"
        file = self.site.file_for(path)
        if file is None or not file.is_file():
            return 404, f"nothing at {path}\n".encode(), "text/plain; charset=utf-8"
        data = await asyncio.get_running_loop().run_in_executor(None, file.read_bytes)
        if file.name == self.site.entry:
            data = self._with_instruments(data)
        return 200, data, content_type(file)

    def _with_instruments(self, page: bytes) -> bytes:
        """The page, with the modules this server was asked for (the emulated headset or gamepad, the tests' probe,
        the frame-time instrument) loaded before the page's own: without them, not a word of them is in the page."""
        tags = "".join(f'<script type="module" src="/app/{name}"></script>' for name in self.site.instruments)
        return page.replace(b"<!-- instruments -->", tags.encode())

    async def _pass_through(
        self, request: h11.Request, rest: bytes, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> None:
        """Hand an admitted WebSocket upgrade to the endpoint and, once it has answered 101, copy both ways; the
        endpoint's token goes first when there is one."""
        host, port = self.endpoint
        try:
            upstream_reader, upstream_writer = await asyncio.open_connection(host, port)
        except OSError as error:
            self.log(
                f"{self.site.page}: a page's WebSocket could not reach the endpoint at ws://{host}:{port}/: {error}"
            )
            _refuse(writer, "502 Bad Gateway", f"the endpoint's WebSocket port {host}:{port} is not reachable: {error}")
            await writer.drain()
            return
        try:
            browser = str(writer.get_extra_info("peername")[0])
            head = upgrade_request(b"GET", ROS_PATH.encode(), request.headers.raw_items(), browser, self.proxy_secret)
            upstream_writer.write(head)
            try:
                answer = await _read_answer_head(upstream_reader)
            except (ConnectionError, OSError, asyncio.TimeoutError) as error:
                self.log(f"{self.site.page}: the endpoint at ws://{host}:{port}/ did not answer an upgrade: {error}")
                _refuse(writer, "502 Bad Gateway", f"the endpoint did not answer the WebSocket upgrade: {error}")
                await writer.drain()
                return
            writer.write(answer)  # the endpoint's 101, or its refusal (403, 503, ...) for the browser to see
            if not answer.startswith(b"HTTP/1.1 101"):
                await writer.drain()
                return
            if self.auth_token is not None:
                upstream_writer.write(auth_message(self.auth_token, os.urandom(4)))
            upstream_writer.write(rest)
            copies = [
                asyncio.ensure_future(_copy(reader, upstream_writer)),
                asyncio.ensure_future(_copy(upstream_reader, writer)),
            ]
            try:
                await asyncio.wait(copies, return_when=asyncio.FIRST_COMPLETED)
            finally:
                for copy in copies:
                    copy.cancel()
        finally:
            upstream_writer.close()


async def _read_request(http: h11.Connection, reader: asyncio.StreamReader) -> h11.Request | None:
    """The next request, read through the end of its body (a GET has none); None once the client has closed."""
    request: h11.Request | None = None
    while True:
        event = http.next_event()
        if event is h11.NEED_DATA:
            http.receive_data(await asyncio.wait_for(reader.read(CHUNK), HEAD_TIMEOUT_S))
        elif isinstance(event, h11.Request):
            request = event
        elif isinstance(event, h11.EndOfMessage):
            return request
        elif not isinstance(event, h11.Data):  # ConnectionClosed, or PAUSED between requests
            return None


def _content_security_policy(index_html: str) -> str:
    """The page may run only what this server serves (no CDN), and open its WebSocket only to this origin. The
    import map is the one inline script; it is allowed by its hash."""
    found = re.search(r'<script type="importmap">(.*?)</script>', index_html, re.DOTALL)
    allowed = ""
    if found:
        digest = base64.b64encode(hashlib.sha256(found.group(1).encode()).digest()).decode()
        allowed = f" 'sha256-{digest}'"
    return (
        f"default-src 'self'; script-src 'self'{allowed}; style-src 'self'; connect-src 'self'; "
        "img-src 'self' blob: data:"
    )


def serve(server: PageServer, ready: Callable[[int], None]) -> None:
    """Run `server` until SIGINT or SIGTERM; `ready(port)` once it listens."""

    async def main() -> None:
        stopped = asyncio.Event()
        loop = asyncio.get_running_loop()
        for signum in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(signum, stopped.set)
        ready(await server.start())
        await server.serve_until(stopped)

    asyncio.run(main())


def _header(request: h11.Request, name: bytes) -> bytes:
    return next((value for key, value in request.headers if key == name), b"")


def _text(request: h11.Request, name: bytes) -> str:
    return _header(request, name).decode("latin-1")


async def _read_answer_head(reader: asyncio.StreamReader) -> bytes:
    """The endpoint's answer to the upgrade through its blank line, with whatever came after it in the same read
    (the endpoint's first frames may): at most MAX_HEAD_BYTES of head, within HEAD_TIMEOUT_S."""
    answer = b""
    while b"\r\n\r\n" not in answer:
        if len(answer) > MAX_HEAD_BYTES:
            raise ConnectionError(f"the endpoint's answer to the upgrade is longer than {MAX_HEAD_BYTES} bytes")
        data = await asyncio.wait_for(reader.read(CHUNK), HEAD_TIMEOUT_S)
        if not data:
            raise ConnectionError("the endpoint closed the connection before answering the upgrade")
        answer += data
    return answer


def _refuse(writer: asyncio.StreamWriter, status: str, reason: str) -> None:
    body = f"{reason}\n".encode()
    writer.write(
        f"HTTP/1.1 {status}\r\nContent-Type: text/plain; charset=utf-8\r\nConnection: close\r\n".encode()
        + f"Content-Length: {len(body)}\r\n\r\n".encode()
        + body
    )


async def _copy(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    with contextlib.suppress(ConnectionError, OSError, ssl.SSLError):
        while True:
            data = await reader.read(CHUNK)
            if not data:
                return
            writer.write(data)
            await writer.drain()
