"""One client connection of the endpoint: the socket, the conversation on it, and the connection's life.

The connection carries ROS-TCP frames directly (TCP), or one frame per binary message of a WebSocket
(bridge.protocol.websocket, for browsers and Unity WebGL builds); everything above the frames is the same.

A reader thread feeds the client's bytes to its Conversation and hands the events to the session's owner (the
Endpoint, which owns every registration and everything clients share): topic messages go to their ROS publisher,
a read's worth at a time; commands and service bodies to `owner.handle`. The way out to the client (direct sends,
the queue and its writer) is bridge.connection.output's, the threads of its ROS calls bridge.connection.calls', and
a WebSocket client's session bridge.connection.web_session's (which builds on this module, never the other way).
What is left is long because a connection's life is: its reader, with the deadlines, authentication and close.
"""

from __future__ import annotations

import logging
import math
import select
import socket
import threading
import time
from typing import TYPE_CHECKING, Callable, Protocol

from bridge import protocol
from bridge.admission.auth import AuthGuard
from bridge.admission.room import SlotUse
from bridge.admission.throttle import LogThrottle
from bridge.config import EndpointConfig
from bridge.connection.calls import CallRoom, ClientCalls
from bridge.connection.output import SessionOutput
from bridge.connection.queues import ByteBudget
from bridge.connection.sockets import send_now, unread_bytes
from bridge.errors import RequestRefused
from bridge.protocol import Auth, Conversation, Event, IgnoredFields, InvalidInput, Role, TopicMessage, Warn
from bridge.ros.publisher import RawPublisher

if TYPE_CHECKING:  # wsproto is optional: bridge.protocol.websocket is imported only for WebSocket clients
    from bridge.protocol.websocket import UpgradeRequest, WebSocketLink

__all__ = ["ClientSession", "SessionOwner", "CLOSE_TIMEOUT_S"]

log = logging.getLogger(__name__)

RECV_BYTES = 256 * 1024
# A client may hold this much of a frame not yet complete without counting against the endpoint's budget for them.
PARTIAL_FRAME_FREE_BYTES = 1024 * 1024
# A WebSocket's reader looks up at least this often (s), so that a close made on another thread starts its handshake
CLOSE_CHECK_INTERVAL_S = 0.2
# How long a closing WebSocket waits for the peer's Close (RFC 6455 7.1.1: the server closes the TCP connection
# once the close handshake is done); a peer that does not answer in time is cut off.
CLOSE_TIMEOUT_S = 2.0
_AUTH_FAILURES_LOG = LogThrottle(log)  # wrong tokens may come thousands a second: logged once a second


class SessionOwner(Protocol):
    """What a session needs from the endpoint that accepted it."""

    call_room: CallRoom  # where the ROS calls of every client find their threads

    def publisher_for(self, session: ClientSession, message: TopicMessage) -> RawPublisher:
        """The ROS publisher for a client's message; RequestRefused when it may not be published."""

    def handle(self, session: ClientSession, event: Event) -> None:
        """Act on a command or service event of the client; RequestRefused says why not."""

    def release(self, session: ClientSession) -> None:
        """The client has gone: undo its registrations."""


class ClientSession(SessionOutput):
    """One connected client: its conversation and reader, its outgoing queue and writer (SessionOutput), its calls."""

    websocket = False  # the transport: ROS-TCP frames directly; WebSocketSession's are WebSocket messages

    def __init__(
        self,
        owner: SessionOwner,
        config: EndpointConfig,
        sock: socket.socket,
        address: tuple,
        client_id: int,
        auth: AuthGuard | None = None,
        partial_frames: ByteBudget | None = None,
    ) -> None:
        self.owner = owner
        self.client_id = client_id
        self.name = f"#{client_id} {address[0]}:{address[1]}"
        # The client's address for per-address limits and back-off: the peer's, or (behind a trusted proxy) the one
        # the proxy says the client has (WebSocketSession.use_forwarded_address)
        self.host: str = address[0]
        self.peer_host: str = address[0]
        self.conversation = Conversation(Role.ENDPOINT, config.max_payload_bytes, config.max_destination_bytes)
        # What the client's bytes are fed to: the conversation itself, or the WebSocket link around it.
        self._link: WebSocketLink | None = None
        self._incoming: Conversation | WebSocketLink = self.conversation
        if self.websocket:
            from bridge.protocol.websocket import WebSocketLink

            self._link = self._incoming = WebSocketLink(Role.ENDPOINT, self.conversation, protocol.handshake())
        self._auth = auth
        self.authenticated = auth is None
        self._auth_deadline = time.monotonic() + config.auth_timeout_s
        self._frame_timeout_s = config.frame_timeout_s
        # Bytes of answers (never dropped) that may wait unread before more are refused (Endpoint.handle) or dropped
        self._answers_budget = config.client_queue_bytes
        # Monotonic time the frame now partly received began. A WebSocket client's upgrade request counts as a frame
        # begun at connect: it must be complete within --frame-timeout.
        self._frame_started: float | None = time.monotonic() if self.websocket else None
        # Partly received frames above PARTIAL_FRAME_FREE_BYTES count against the endpoint's budget for all clients
        self._partial_frames = partial_frames
        self._partial_held = 0
        self.bytes_in = 0
        self.connected_at = time.time()
        self._connected_monotonic = time.monotonic()
        self.pings = 0
        self.ping_clock_offset_s: float | None = None  # see bridge.diagnostics.ClientSnapshot
        self.ping_round_trip_s: float | None = None
        self._end_reason: str | None = None  # why the connection ended, first cause only
        self.missed_deadline = False  # closed for a frame or __auth not in time: its address is a suspect (gate)
        self.publish_drops = 0  # this client's messages dropped before reaching ROS (publisher queue full)
        self.pongs_refused = 0  # WebSocket pongs not sent: the client left its budget of answers unread
        self._closed = threading.Event()
        # Set once the reader has ended: the client will read no more answers, so its ROS calls may give up.
        self.gone = threading.Event()
        self._calls = ClientCalls(self.name, config, owner.call_room)
        # Topic messages of the current read that go to one publisher, handed over together (_publish_pending)
        self._pending_publisher: RawPublisher | None = None
        self._pending_payloads: list[bytes] = []
        SessionOutput.__init__(self, config, sock)
        self._reader = threading.Thread(target=self._read_loop, name=f"read {self.name}", daemon=True)

    @property
    def frames_in(self) -> int:
        return self._incoming.frames_received

    @property
    def closing(self) -> bool:
        """The connection is ending (its threads may still be finishing)."""
        return self._closed.is_set()

    def slot_use(self, now: float) -> SlotUse:
        """What this connection has done with its slot so far (for bridge.admission.room); `now` is monotonic time."""
        frame_started = self._frame_started
        return SlotUse(
            now - self._connected_monotonic,
            None if frame_started is None else now - frame_started,
            self._incoming.buffered_bytes,
            self.frames_in,
            self.authenticated,
            unread_bytes(self.sock),
        )

    def start(self) -> None:
        auth = "" if self.authenticated else ", waiting for __auth"
        if self._link is None:
            log.info("client %s connected; handshake sent%s", self.name, auth)
            # The handshake goes out at once, before the client says anything.
            self.queue.put(protocol.handshake(), droppable=False)
        else:  # the handshake follows the answer to the client's WebSocket upgrade
            log.info("client %s connected by WebSocket; waiting for its upgrade request%s", self.name, auth)
        self._writer.start()
        self._reader.start()

    def run_call(self, what: str, call: Callable[[], None], srv_id: int | None = None) -> None:
        """Start a ROS service call when there is room (bridge.connection.calls); RequestRefused when there cannot
        be."""
        self._calls.run_call(what, call, srv_id)

    def run_lookup(self, what: str, look_up: Callable[[], None]) -> None:
        """Run a look-up at the ROS master (a topic list) on this client's look-up worker."""
        self._calls.run_lookup(what, look_up)

    def close(self, reason: str | None = None, tell_client: bool = False) -> None:
        """End the connection (from any thread); with `tell_client`, the reason goes to the client first as a __warn,
        if its socket takes it at once (nothing waits for a client that does not read)."""
        if self._closed.is_set():
            return
        if reason is not None:
            self._ended(reason)
        self._say_goodbye(reason if tell_client else None)

    def _say_goodbye(self, text: str | None) -> None:
        """Over TCP: the __warn with `text` if the socket takes it now, then the connection is shut at once."""
        if text is not None and self._send_lock.acquire(blocking=False):
            try:
                send_now(self.sock, protocol.encode(Warn(f"closing the connection: {text}")))
            except OSError:
                pass
            finally:
                self._send_lock.release()
        self._closed.set()
        self.queue.close(discard=True)
        self._shut()

    def _shut(self) -> None:
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass

    # --- reader -----------------------------------------------------------------------------------------------
    def _read_loop(self) -> None:
        readable = select.poll()
        readable.register(self.sock, select.POLLIN)
        try:
            while not self._closed.is_set():
                if not self._readable_in_time(readable):
                    break
                data = self.sock.recv(RECV_BYTES)
                if not data:
                    self._ended("closed by the client")
                    break
                self.bytes_in += len(data)
                incoming = self._incoming
                frames_before = incoming.frames_received
                events = incoming.receive_data(data)
                if self._link is not None:
                    if self._link.pending_request is not None:
                        self._decide_upgrade(self._link.pending_request)
                    self._answer_link()  # before the events' answers: the upgrade's must go first
                    if self._closed.is_set() and self._link.closed is None:  # closed on another thread meanwhile
                        break
                if not self._account_partial_frame(incoming.frames_received > frames_before):
                    break
                for event in events:
                    if type(event) is TopicMessage and self.authenticated:
                        self._collect_publication(event)
                    elif not self._handle(event):
                        return
                # messages that came together go to ROS together; one that came alone may go directly (RawPublisher)
                self._publish_pending(alone=len(events) == 1)
                if self._link is not None and self._link.closed is not None:
                    self._ended(self._link.closed)
                    break
        except OSError as error:
            self._ended(f"connection error: {error}")
        finally:
            self._finish()

    def _answer_link(self) -> None:
        """Send what the WebSocket link says of its own accord: the upgrade's answer and the handshake, pongs, the
        answer to the peer's Close. Pongs are answers too: while more than the budget of earlier answers waits unread
        (Endpoint.handle), they are dropped, and the client is told."""
        link = self._link
        assert link is not None
        pongs = link.pongs_waiting()
        over_budget = pongs and self.queue.kept_bytes + pongs > self._answers_budget
        reply = link.data_to_send(pongs=not over_budget)
        if over_budget:
            self._pongs_refused()
        if not reply:
            return
        if link.close_sent:  # the answer to the peer's Close: the last thing sent, nothing is queued after it
            self._ended(link.closed or "WebSocket closed by the peer")
            self._closed.set()  # first: direct sends stop (see WebSocketSession._say_goodbye)
            self.queue.put(reply, droppable=False)
            self.queue.close()
            return
        self._send_bytes(reply, droppable=False)
        if link.upgraded and reply.startswith(b"HTTP/"):
            log.info("client %s: WebSocket upgraded; handshake sent", self.name)

    def _pongs_refused(self) -> None:
        """A pong dropped for the budget: logged, and said in the writer's next warning (_drop_warning), which goes
        with the next batch the client reads (a frame queued now would be dropped at once: the queue is over its
        bytes with answers)."""
        self.pongs_refused += 1
        self._error_log.warning(
            "client %s: WebSocket pong not sent: %d bytes of earlier answers wait unread (%d pongs not sent)",
            self.name,
            self.queue.kept_bytes,
            self.pongs_refused,
        )

    def _decide_upgrade(self, request: UpgradeRequest) -> None:
        """Accept or refuse a WebSocket client's upgrade request: WebSocketSession's (bridge.connection.web_session),
        whose owner judges it; only a session with a WebSocket link has one to decide, so a TCP session never does."""
        raise NotImplementedError("a TCP session has no upgrade request to decide")

    def _readable_in_time(self, readable: select.poll) -> bool:
        """Wait for bytes while a deadline runs (a frame begun, __auth due); False when it passed (the client was
        told), or when the connection was closed meanwhile. Without a deadline, a TCP client's recv simply waits:
        keepalives and TCP keepalive tell a live peer from a dead one (a close on another thread shuts the socket,
        which wakes it). A WebSocket's reader looks up every CLOSE_CHECK_INTERVAL_S: its close must be handshaken
        from here, so its socket is not shut."""
        while True:
            deadlines = []
            if not self.authenticated:
                deadlines.append((self._auth_deadline, "no __auth within the endpoint's --auth-timeout"))
            if self._frame_started is not None:
                deadlines.append(
                    (
                        self._frame_started + self._frame_timeout_s,
                        f"a frame begun was not completed within {self._frame_timeout_s:g} s (--frame-timeout)",
                    )
                )
            if not deadlines and not self.websocket:
                return True
            deadline, why = min(deadlines) if deadlines else (math.inf, "")
            now = time.monotonic()
            wait_s = min(deadline - now, CLOSE_CHECK_INTERVAL_S) if self.websocket else deadline - now
            if readable.poll(max(0.0, wait_s) * 1000):
                return True
            if self._closed.is_set():
                return False
            if time.monotonic() >= deadline:
                self.send_error(f"closing the connection: {why}")
                self._ended(why)
                self.missed_deadline = True
                return False

    def _account_partial_frame(self, frames_completed: bool) -> bool:
        """After a read: when the frame now partly received began, and its bytes against the endpoint's budget;
        False when the budget cannot take them (the client was told)."""
        buffered = self._incoming.buffered_bytes
        if not buffered:
            self._frame_started = None
        elif self._frame_started is None or frames_completed:
            self._frame_started = time.monotonic()
        wanted = buffered if buffered > PARTIAL_FRAME_FREE_BYTES else 0
        if self._partial_frames is None or wanted == self._partial_held:
            return True
        granted = self._partial_frames.resize(self._partial_held, wanted)
        self._partial_held = wanted if granted else 0  # refused: nothing held any more (ByteBudget)
        if granted:
            return True
        why = (
            f"the endpoint holds {self._partial_frames.used} bytes of frames not yet complete from all clients, "
            f"its limit (--max-partial-frame-bytes): the frame begun here ({buffered} bytes so far) cannot be "
            "taken"
        )
        self.send_error(f"closing the connection: {why}")
        self._ended(why)
        return False

    def _finish(self) -> None:
        self.gone.set()
        if self._partial_frames is not None:
            self._partial_frames.resize(self._partial_held, 0)
            self._partial_held = 0
        self.owner.release(self)
        self._calls.stop()  # calls not started yet are dropped; running ones see `gone` and end
        self._end_transport()
        log.info(
            "client %s disconnected: %s (frames in %d, out %d, dropped %d)",
            self.name,
            self._end_reason or "closed by the endpoint",
            self.frames_in,
            self.frames_out,
            self.dropped,
        )

    def _end_transport(self) -> None:
        """Over TCP: let the writer drain what is queued (the closing __error), then close the socket."""
        self.queue.close()
        self._writer.join(timeout=CLOSE_TIMEOUT_S)
        self.close()
        self.sock.close()

    def wait_closed(self, timeout_s: float) -> None:
        """Until the connection has ended (its reader finished, the socket closed), at most `timeout_s`."""
        if self._reader.is_alive():
            self._reader.join(timeout_s)

    def _ended(self, reason: str) -> None:
        if self._end_reason is None and not self._closed.is_set():
            self._end_reason = reason

    def note_ping(self, round_trip: float | None, clock_offset: float | None) -> None:
        """A __ping came: what it tells of the client's clock and (if it says) of its last round trip."""
        self.pings += 1
        if clock_offset is not None:
            self.ping_clock_offset_s = clock_offset
        if round_trip is not None:
            self.ping_round_trip_s = round_trip

    def _collect_publication(self, message: TopicMessage) -> None:
        try:
            publisher = self.owner.publisher_for(self, message)
        except RequestRefused as refusal:
            self.send_error(str(refusal), refusal.srv_id)
            return
        if publisher is not self._pending_publisher:
            self._publish_pending()
            self._pending_publisher = publisher
        self._pending_payloads.append(message.payload)

    def _publish_pending(self, alone: bool = False) -> None:
        """Hand the collected messages to their publisher: one queue hand-off for a whole read's worth instead of
        one per message. Never blocks for long (see RawPublisher); drops are reported by the writer (__warn)."""
        publisher, payloads = self._pending_publisher, self._pending_payloads
        if publisher is None:
            return
        self._pending_publisher, self._pending_payloads = None, []
        try:
            self.publish_drops += publisher.publish(payloads, alone)
        except Exception as error:  # a bug must cost these messages, never the connection or the endpoint
            log.exception("client %s: publishing %d message(s) failed", self.name, len(payloads))
            self.send_error(f"internal error publishing {len(payloads)} message(s): {error}")

    def _handle(self, event: Event) -> bool:
        """Act on one event other than an authenticated topic message; False when the connection must close."""
        self._publish_pending()  # messages that came before a command go to ROS before it takes effect
        if isinstance(event, InvalidInput):
            error = event.error
            self.send_error(
                f"framing lost, closing the connection: {error}" if error.fatal else str(error), error.srv_id
            )
            if error.fatal:
                self._ended(f"framing lost: {error}")
                return False
            if self.authenticated:
                return True
        elif isinstance(event, IgnoredFields):
            names = ", ".join(map(repr, event.fields))
            self.send(protocol.encode(Warn(f"{event.command}: field(s) {names} not known to this endpoint, ignored")))
            return True
        if not self.authenticated:
            return self._authenticate(event)
        try:
            self.owner.handle(self, event)
        except RequestRefused as refusal:
            self.send_error(str(refusal), refusal.srv_id)
        except Exception as error:  # a bug must cost one event, never the connection or the endpoint
            log.exception("client %s: unexpected failure on %r", self.name, event)
            self.send_error(f"internal error handling {type(event).__name__}: {error}")
        return True

    def _authenticate(self, event: Event) -> bool:
        assert self._auth is not None
        if isinstance(event, Auth):
            hold_back = self._auth.check(self.host, event.token)
            if not hold_back:
                self.authenticated = True
                log.info("client %s authenticated", self.name)
                return True
            reason = f"a wrong token, {self._auth.failures(self.host)} in a row from {self.host}"
            self._closed.wait(hold_back)  # the verdict on a wrong token is held back: guessing is slow
        else:
            reason = f"{type(event).__name__} before __auth"
        _AUTH_FAILURES_LOG.warning("client %s: authentication failed (%s)", self.name, reason)
        self._ended(f"authentication failed ({reason})")
        self.send_error("authentication required: the first command must be __auth with the endpoint's token")
        return False
