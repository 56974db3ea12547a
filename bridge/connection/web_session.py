"""A client of the endpoint over WebSocket (browsers, Unity WebGL builds): a ClientSession
(bridge.connection.session) whose frames go out as binary messages of their own, whose upgrade request its owner
judges, and whose close is the WebSocket's handshake."""

from __future__ import annotations

import logging
import select
import time
from typing import TYPE_CHECKING, Protocol

from bridge import protocol
from bridge.connection.session import CLOSE_TIMEOUT_S, RECV_BYTES, ClientSession, SessionOwner
from bridge.protocol import Warn

if TYPE_CHECKING:  # wsproto is optional: bridge.protocol.websocket is imported only for WebSocket clients
    from bridge.protocol.websocket import UpgradeRequest

__all__ = ["WebSocketOwner", "WebSocketSession"]

log = logging.getLogger(__name__)


class WebSocketOwner(SessionOwner, Protocol):
    """What a WebSocket session needs from the endpoint that accepted it: a session's needs, and a judge of its
    upgrade request."""

    def upgrade_refusal(self, session: WebSocketSession, request: UpgradeRequest) -> tuple[str, str] | None:
        """Why a WebSocket client's upgrade request is refused, as (HTTP status, reason); None to accept it."""


class WebSocketSession(ClientSession):
    """A client of the WebSocket transport: each frame it is sent goes out as a binary message of its own. (Its own
    class, so that sending to a TCP client, the endpoint's hot path, checks nothing more per frame.)

    Its close is a handshake (RFC 6455 7.1): the Close goes out after the frame on the wire, never inside it, and
    nothing after it; then the reader waits up to CLOSE_TIMEOUT_S for the peer's Close before the socket closes.
    Only the reader touches the socket's reading side, so a close made on another thread never races it."""

    websocket = True
    owner: WebSocketOwner

    def send(self, frame: bytes, droppable: bool = True, key: str | None = None, key_limit: int = 0) -> None:
        link = self._link
        assert link is not None
        if not link.upgraded:  # nothing can be said in frames before the upgrade (link.close answers in HTTP)
            return
        super().send(link.wrap(frame), droppable, key, key_limit)

    def use_forwarded_address(self, host: str) -> None:
        """The client's own address, as a trusted proxy in front of the endpoint says it: per-address limits,
        back-off and /diagnostics go by it from now on."""
        self.name = f"#{self.client_id} {host} via {self.name.split(' ', 1)[1]}"
        self.host = host

    def _decide_upgrade(self, request: UpgradeRequest) -> None:
        """Accept or refuse the client's upgrade request, as the owner says."""
        assert self._link is not None
        refusal = self.owner.upgrade_refusal(self, request)
        if refusal is None:
            self._link.accept()
        else:
            self._link.refuse(*refusal)

    def _say_goodbye(self, text: str | None) -> None:
        """The __warn with `text` and the Close (1001, going away), after the frame on the wire; what is queued and
        not begun is dropped. Before the upgrade, an HTTP 503 instead. The reader sees the close within
        CLOSE_CHECK_INTERVAL_S and waits for the peer's answer (_end_transport)."""
        link = self._link
        assert link is not None
        self._closed.set()  # first: a direct send that checks it under the send lock from now on queues instead
        goodbye = link.wrap(protocol.encode(Warn(f"closing the connection: {text}"))) if text and link.upgraded else b""
        goodbye += link.close(text or self._end_reason or "", going_away=True)
        self.queue.finish_with(goodbye)

    def _end_transport(self) -> None:
        link = self._link
        assert link is not None
        if not self._closed.is_set():  # the reader ended it: what it said last (an __error) goes before the Close
            self._closed.set()
            closing = link.close(self._end_reason or "")
            if closing:
                self.queue.put(closing, droppable=False)
        self.queue.close()
        deadline = time.monotonic() + CLOSE_TIMEOUT_S
        if link.close_sent and not link.peer_closed:
            self._await_peer_close(deadline)
        self._writer.join(timeout=max(0.0, deadline - time.monotonic()))
        self._shut()
        self.sock.close()

    def _await_peer_close(self, deadline: float) -> None:
        """Read until the peer answers this end's Close, hangs up, or `deadline` passes; what else it sends is not
        acted on any more."""
        assert self._link is not None
        readable = select.poll()
        readable.register(self.sock, select.POLLIN)
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not readable.poll(remaining * 1000):
                log.info("client %s: no answer to the WebSocket close within %g s", self.name, CLOSE_TIMEOUT_S)
                return
            try:
                data = self.sock.recv(RECV_BYTES)
            except OSError:
                return
            if not data or self._link.await_close(data):
                return
