"""The ROS-TCP protocol over WebSocket (RFC 6455), sans I/O: each ROS-TCP frame travels as one binary message.

For clients that cannot open a raw TCP socket: web pages (a WebXR headset's browser) and Unity WebGL builds. The
frames, commands and rules are those of TCP; only their envelope differs. wsproto (Debian's and Ubuntu's
python3-wsproto, by h11's authors) does the HTTP upgrade and reads the peer's WebSocket frames; this module adds
what the ROS-TCP protocol needs on top: a message must end where a ROS-TCP frame ends, text messages are refused,
and the endpoint's handshake frame follows the upgrade. Like bridge.protocol, it never reads a socket.

wsproto is optional: the endpoint imports this module only when it is asked to serve WebSocket clients.
"""

from __future__ import annotations

import struct
import threading
from dataclasses import dataclass

import wsproto
from wsproto.connection import ConnectionState
from wsproto.events import (
    AcceptConnection,
    BytesMessage,
    CloseConnection,
    Message,
    Ping,
    RejectConnection,
    RejectData,
    Request,
    TextMessage,
)
from wsproto.events import (
    Event as WsEvent,
)
from wsproto.frame_protocol import CloseReason
from wsproto.utilities import RemoteProtocolError as WsRemoteProtocolError

from bridge.protocol import Conversation, Role
from bridge.protocol.events import Event, FramingError, InvalidInput, RemoteProtocolError

__all__ = [
    "WebSocketLink",
    "UpgradeRequest",
    "refusal_response",
    "split_frames",
    "CLOSE_NORMAL",
    "CLOSE_GOING_AWAY",
    "CLOSE_POLICY",
]

# Close codes the endpoint sends (RFC 6455 7.4.1): done; the endpoint is stopping; the client broke a rule.
CLOSE_NORMAL = int(CloseReason.NORMAL_CLOSURE)
CLOSE_GOING_AWAY = int(CloseReason.GOING_AWAY)
CLOSE_POLICY = int(CloseReason.POLICY_VIOLATION)

_U32 = struct.Struct("<I")
_SHORT_HEADER = struct.Struct("!BBH")
_LONG_HEADER = struct.Struct("!BBQ")
_FIN_BINARY = 0x82  # FIN bit + opcode 2 (binary)


def split_frames(data: bytes) -> list[bytes | memoryview]:
    """The ROS-TCP frames `data` holds back to back (a service header and its body are sent as one item). Each is
    a view into `data`, or `data` itself when it is a single frame (the usual case: no copy)."""
    frames: list[bytes | memoryview] = []
    view = memoryview(data)
    offset = 0
    while offset < len(data):
        destination_length = _U32.unpack_from(data, offset)[0]
        payload_at = offset + 4 + destination_length
        end = payload_at + 4 + _U32.unpack_from(data, payload_at)[0]
        if offset == 0 and end == len(data):
            return [data]
        frames.append(view[offset:end])
        offset = end
    return frames


def _message_header(length: int) -> bytes:
    """The header of one unmasked, unfragmented binary message of `length` bytes (what a server sends)."""
    if length < 126:
        return bytes((_FIN_BINARY, length))
    if length < 1 << 16:
        return _SHORT_HEADER.pack(_FIN_BINARY, 126, length)
    return _LONG_HEADER.pack(_FIN_BINARY, 127, length)


@dataclass(frozen=True)
class UpgradeRequest:
    """What the endpoint decides a WebSocket upgrade on: the page's Origin (None from clients that are not
    browsers), the client's address as a proxy in front says it (X-Forwarded-For, all its values in order), and the
    secret by which that proxy proves itself (X-Proxy-Secret)."""

    target: str
    origin: str | None
    forwarded_for: str | None
    proxy_secret: str | None = None


def refusal_response(reason: str, status: str = "503 Service Unavailable") -> bytes:
    """An HTTP answer in place of the upgrade's, saying why in the body: by default the 503 that turns a client away
    when the endpoint is full, sent at once, so that the endpoint's accept thread never waits for a request."""
    body = f"{reason}\n".encode()
    head = (
        f"HTTP/1.1 {status}\r\ncontent-type: text/plain; charset=utf-8\r\n"
        f"content-length: {len(body)}\r\nconnection: close\r\n\r\n"
    )
    return head.encode("ascii") + body


class WebSocketLink:
    """One connection's WebSocket layer around its Conversation: bytes from the socket in, ROS-TCP events out.

    For the endpoint: the client's upgrade request waits in `pending_request` until the endpoint decides on it with
    `accept()` (then `first_frames`, the handshake, follow the answer) or `refuse()`. For a client:
    `upgrade_request()` starts the connection. What the link must send of its own accord (the upgrade's answer,
    pongs, a close's reply) waits in `data_to_send()`; what the conversation sends goes through `wrap()`. `closed`
    says why the WebSocket ended, once it has; `close_sent` says a Close has been made (nothing may follow it).

    Pongs: the peer may ping faster than it reads. Only the newest ping of a read is answered (RFC 6455 5.5.3
    allows it), and `pongs_waiting()` tells the owner how many bytes of pongs wait, so that it can drop them
    (`data_to_send(pongs=False)`) when the peer leaves its answers unread.

    Thread safety: `wrap()` may be called from any thread at the endpoint (each message header is made here, from
    the frame's length alone); everything that touches wsproto holds one lock, so a close made on another thread
    never meets the reading thread inside wsproto.
    """

    def __init__(self, role: Role, conversation: Conversation, first_frames: bytes = b"") -> None:
        self.role = role
        self.conversation = conversation
        self._ws = wsproto.WSConnection(
            wsproto.ConnectionType.SERVER if role is Role.ENDPOINT else wsproto.ConnectionType.CLIENT
        )
        self._first_frames = first_frames
        self._outgoing = bytearray()
        self._pong = b""  # the answer to the newest ping not yet taken (data_to_send)
        self.pongs_dropped = 0
        self._lock = threading.RLock()  # wsproto is for one thread at a time
        self.pending_request: UpgradeRequest | None = None  # an upgrade request the owner has not decided on
        self._in_message = False  # a data message has begun and not ended
        self._failure: tuple[int, str] | None = None  # the close code and reason a fatal problem calls for
        self._http_answered = False  # the upgrade request has had its answer (accepted, or refused)
        self.upgraded = False
        self.close_sent = False
        self.peer_closed = False  # the peer's Close came (an answer to this end's, or its own)
        self.closed: str | None = None

    # --- what the session reads of the conversation -----------------------------------------------------------
    @property
    def frames_received(self) -> int:
        return self.conversation.frames_received

    @property
    def buffered_bytes(self) -> int:
        """Bytes of ROS-TCP frames not yet complete; at least 1 while the upgrade or a message is under way, so that
        the endpoint's deadline for a frame begun (--frame-timeout) covers them too."""
        pending = not self.upgraded or self._in_message
        return max(self.conversation.buffered_bytes, int(pending))

    # --- bytes in ----------------------------------------------------------------------------------------------
    def receive_data(self, data: bytes) -> list[Event]:
        """The ROS-TCP events in `data`, with an InvalidInput for each WebSocket-level problem (fatal when the
        stream cannot go on). Nothing more is read once the WebSocket has closed or failed."""
        with self._lock:
            if self.closed is not None:
                return []
            try:
                self._ws.receive_data(data)
                return self._events()
            except WsRemoteProtocolError as error:  # a malformed upgrade request
                if self.role is Role.ENDPOINT and error.event_hint is not None:
                    self._outgoing += self._send(error.event_hint)
                    self._http_answered = True
                return [self._failed(f"WebSocket upgrade failed: {error}")]

    def _events(self) -> list[Event]:
        events: list[Event] = []
        if self.pending_request is not None:  # nothing is read past the request until it is decided on
            return events
        for ws_event in self._ws.events():
            if isinstance(ws_event, BytesMessage):
                events.extend(self._binary(bytes(ws_event.data), ws_event.message_finished))
                if self.closed is not None:
                    break
            elif isinstance(ws_event, TextMessage):
                self._in_message = not ws_event.message_finished
                if ws_event.message_finished:
                    events.append(
                        InvalidInput(
                            RemoteProtocolError(
                                "a text WebSocket message was ignored: send each ROS-TCP frame as one binary message"
                            )
                        )
                    )
            elif isinstance(ws_event, Ping):
                if self._ws.state is ConnectionState.OPEN:  # after a Close, nothing but its answer may be sent
                    if self._pong:
                        self.pongs_dropped += 1  # superseded by this newer ping's answer
                    self._pong = self._send(ws_event.response())
            elif isinstance(ws_event, CloseConnection):
                events.extend(self._close_received(ws_event))
                break
            elif isinstance(ws_event, Request):
                headers: dict[bytes, list[bytes]] = {}
                for name, value in ws_event.extra_headers:
                    headers.setdefault(bytes(name).lower(), []).append(bytes(value))
                origin = headers.get(b"origin")
                forwarded = headers.get(b"x-forwarded-for")
                secret = headers.get(b"x-proxy-secret")
                self.pending_request = UpgradeRequest(
                    ws_event.target,
                    origin[-1].decode("latin-1") if origin else None,
                    b", ".join(forwarded).decode("latin-1") if forwarded else None,
                    secret[-1].decode("latin-1") if secret else None,
                )
                break
            elif isinstance(ws_event, AcceptConnection):
                self.upgraded = True
            elif isinstance(ws_event, RejectConnection):
                self.closed = f"the WebSocket upgrade was refused with HTTP {ws_event.status_code}"
            elif isinstance(ws_event, RejectData):
                body = bytes(ws_event.data).decode("utf-8", "replace").strip()
                if body and self.closed is not None:
                    self.closed += f": {body}"
            # Pongs need no answer.
        return events

    def _binary(self, data: bytes, message_finished: bool) -> list[Event]:
        self._in_message = not message_finished
        events = self.conversation.receive_data(data) if data else []
        if events and isinstance(events[-1], InvalidInput) and events[-1].error.fatal:
            self._failed(str(events[-1].error))  # the ROS-TCP stream is lost (a length over its limit)
        elif message_finished and self.conversation.buffered_bytes:
            events.append(
                self._failed(
                    f"a binary WebSocket message ended inside a ROS-TCP frame ({self.conversation.buffered_bytes} "
                    "bytes of it so far): each message must carry whole frames"
                )
            )
        return events

    def _close_received(self, close: CloseConnection) -> list[Event]:
        if self._ws.state is ConnectionState.REMOTE_CLOSING:  # the peer closed: answer, and end
            self._outgoing += self._send(close.response())
            self.close_sent = self.peer_closed = True
            mid_frame = self._in_message or self.conversation.buffered_bytes
            reason = f": {close.reason}" if close.reason else ""
            self.closed = f"WebSocket closed by the peer (code {int(close.code)}{reason})" + (
                ", in the middle of a frame" if mid_frame else ""
            )
            return []
        if self._ws.state is ConnectionState.CLOSED:  # the peer's answer to the close this end sent
            self.peer_closed = True
            self.closed = f"WebSocket closed (code {int(close.code)}), the peer answering this end's close"
            return []
        # wsproto reports WebSocket frames it cannot parse (unmasked, a bad opcode, ...) as a close of its own
        return [self._failed(f"broken WebSocket framing: {close.reason}", int(close.code))]

    def _failed(self, why: str, code: int = CLOSE_POLICY) -> InvalidInput:
        """A fatal problem: nothing more is read, and `close()` gives the close that tells the peer (to be sent after
        the __error the session sends for the InvalidInput)."""
        self._failure = (code, why)
        self.closed = why
        return InvalidInput(FramingError(why))

    # --- the endpoint's decision on an upgrade request -----------------------------------------------------------
    def accept(self) -> None:
        """Accept the pending upgrade request: its answer and the first frames wait in data_to_send(). (A client
        must wait for the answer before it sends anything, RFC 6455 4.1; wsproto drops what one sent earlier.)"""
        with self._lock:
            self.pending_request = None
            self._outgoing += self._send(AcceptConnection())
            self._http_answered = True
            self._outgoing += self.wrap(self._first_frames) if self._first_frames else b""
            self.upgraded = True

    def refuse(self, status: str, reason: str) -> None:
        """Refuse the pending upgrade request with an HTTP answer (e.g. "403 Forbidden") that says why; the link is
        closed."""
        with self._lock:
            self.pending_request = None
            self._outgoing += refusal_response(reason, status)
            self._http_answered = True
            self.closed = f"WebSocket upgrade refused ({status}): {reason}"

    def await_close(self, data: bytes) -> bool:
        """After this end's Close: read `data` for the peer's answer (nothing else in it is acted on); True once it
        came, or once the peer's bytes cannot be read for it any more."""
        with self._lock:
            try:
                self._ws.receive_data(data)
                for event in self._ws.events():
                    if isinstance(event, CloseConnection):  # the answer, or wsproto's word that the stream broke
                        self.peer_closed = True
            except WsRemoteProtocolError:
                self.peer_closed = True
            return self.peer_closed

    def pongs_waiting(self) -> int:
        """Bytes of pongs that data_to_send() would send."""
        return len(self._pong)

    def data_to_send(self, pongs: bool = True) -> bytes:
        """Bytes the link itself must send (the upgrade's answer, pongs, close replies), taken once; with
        `pongs=False` the waiting pong is dropped (counted in pongs_dropped)."""
        with self._lock:
            data = bytes(self._outgoing)
            self._outgoing = bytearray()
            if self._pong and pongs:
                # A pong goes before a Close that follows it (nothing may follow a Close)
                data = self._pong + data
            elif self._pong:
                self.pongs_dropped += 1
            self._pong = b""
            return data

    # --- bytes out ---------------------------------------------------------------------------------------------
    def wrap(self, frames: bytes) -> bytes:
        """`frames` (one or more whole ROS-TCP frames, as the conversation makes them) as binary messages, one
        each."""
        if self.role is Role.ENDPOINT:
            parts = split_frames(frames)
            if len(parts) == 1:
                return _message_header(len(frames)) + frames
            return b"".join(_message_header(len(part)) + part for part in parts)
        return b"".join(self._send(Message(data=bytes(part))) for part in split_frames(frames))

    def upgrade_request(self, host: str, path: str = "/") -> bytes:
        """A client's opening: the HTTP upgrade request."""
        return self._send(Request(host=host, target=path))

    def message(self, data: bytes) -> bytes:
        """Any bytes as one binary message, whole frames or not (for tests that send broken frames)."""
        if self.role is Role.ENDPOINT:
            return _message_header(len(data)) + data
        return self._send(Message(data=data))

    def close(self, reason: str = "", going_away: bool = False) -> bytes:
        """The WebSocket close to send as this end closes the connection: "going away" (the endpoint stops, or makes
        room), else with the code and reason of the fatal problem that ended it, else "policy violation" (the
        client missed a deadline or its authentication) with `reason`, else "normal". Nothing once a close has been
        sent. At the endpoint before the upgrade, an HTTP answer instead: 503 when going away, else 408 (the only
        other way to end there is the upgrade request's deadline)."""
        with self._lock:
            if self.role is Role.ENDPOINT and not self.upgraded:
                if self._http_answered:
                    return b""
                self._http_answered = True
                self.pending_request = None
                return refusal_response(reason, "503 Service Unavailable" if going_away else "408 Request Timeout")
            code = CLOSE_GOING_AWAY if going_away else CLOSE_POLICY if reason else CLOSE_NORMAL
            if self._failure is not None and not going_away:
                code, reason = self._failure
            if self._ws.state not in (ConnectionState.OPEN, ConnectionState.REMOTE_CLOSING):
                return b""
            self.close_sent = True
            self._pong = b""  # a pong not yet taken can no longer be sent (nothing follows a Close)
            # wsproto cuts the reason to the 123 bytes a close has room for
            return self._ws.send(CloseConnection(code, reason or None))

    def _send(self, event: WsEvent) -> bytes:
        with self._lock:
            return self._ws.send(event)
