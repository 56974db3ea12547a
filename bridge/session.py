"""One client connection of the endpoint: its framing state, registrations, service state and outgoing path.

A reader thread turns the client's bytes into frames and acts on them (through the Endpoint, which owns what
clients share); frames to the client go out directly when its socket keeps up, otherwise through a bounded queue
drained by a writer thread, so a slow reader loses its oldest topic frames, never the endpoint's memory.
"""
from __future__ import annotations

import hmac
import logging
import socket
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from collections.abc import Callable
from typing import TYPE_CHECKING

from bridge import protocol
from bridge.protocol import (
    Auth,
    BadFrame,
    Frame,
    FrameDecoder,
    FramingError,
    ProtocolError,
    Publish,
    Remove,
    Request,
    Response,
    RosService,
    Subscribe,
    TopicList,
    UnityService,
)
from bridge.queues import OutgoingQueue
from bridge.ros import RawPublisher, RawServiceProxy
from bridge.sockets import send_now, unsent_bytes

if TYPE_CHECKING:
    from bridge.server import Endpoint

log = logging.getLogger(__name__)

RECV_BYTES = 256 * 1024
# A client with more than this waiting unacknowledged in its socket is not keeping up: no direct sends to it.
DIRECT_SEND_MAX_UNSENT = 64 * 1024
DROP_WARNING_INTERVAL_S = 1.0
ERROR_LOG_INTERVAL_S = 1.0


class ClientError(Exception):
    """A request of one client that is refused; the text goes back to that client as __error."""


class ClientSession:
    """One connected client: its framing state, registrations, pending service state and outgoing queue."""

    def __init__(self, endpoint: Endpoint, sock: socket.socket, address: tuple[str, int], client_id: int) -> None:
        config = endpoint.config
        self.endpoint = endpoint
        self.sock = sock
        self.name = f"#{client_id} {address[0]}:{address[1]}"
        self.queue = OutgoingQueue(config.client_queue_frames, config.client_queue_bytes)
        self.decoder = FrameDecoder(config.max_payload_bytes, config.max_destination_bytes)
        self.authenticated = config.auth_token is None
        self.subscriptions: dict[str, str] = {}  # resolved topic -> topic as this client spells it
        self.publishers: dict[str, tuple[str, RawPublisher]] = {}  # client topic -> (resolved, publisher)
        self.ros_services: dict[str, RawServiceProxy] = {}
        self.unity_services: set[str] = set()
        # Per-connection "the next frame is a service body" state: ("request" | "response" | "discard", srv_id)
        self.expect_body: tuple[str, int] | None = None
        self.frames_in = 0
        self.frames_out = 0
        self._closed = threading.Event()
        self._send_lock = threading.Lock()  # one writer of the socket at a time: direct sends or the writer thread
        self._unsent_bound = 0  # at least the bytes waiting in the kernel's send queue (see _peer_keeps_up)
        # Threads are started on demand, so a client that never calls a service costs none.
        self._calls = ThreadPoolExecutor(config.client_call_workers, thread_name_prefix=f"calls {self.name}")
        self._calls_lock = threading.Lock()
        self._calls_pending = 0
        self.publish_drops = 0  # this client's messages dropped before reaching ROS (publisher queue full)
        # Topic messages of the current read that go to one publisher, handed over together (_publish_pending)
        self._pending_publisher: RawPublisher | None = None
        self._pending_payloads: list[bytes] = []
        self._reported_drops = 0
        self._reported_publish_drops = 0
        self._last_drop_warning_at = 0.0
        self._last_error_logged_at = -ERROR_LOG_INTERVAL_S
        self._errors_not_logged = 0
        self._reader = threading.Thread(target=self._read_loop, name=f"read {self.name}", daemon=True)
        self._writer = threading.Thread(target=self._write_loop, name=f"write {self.name}", daemon=True)

    def __hash__(self) -> int:
        return id(self)

    def start(self) -> None:
        log.info("client %s connected", self.name)
        # The handshake goes out at once, before the client says anything.
        self.queue.put(protocol.handshake_frame(), droppable=False)
        self._writer.start()
        self._reader.start()

    def send(self, frame: bytes, droppable: bool = True) -> None:
        """Send one frame (or a service header + body, as one item) without ever blocking the caller.

        Direct path: when nothing is queued, nobody is writing and the peer keeps up, write it at once with a non-blocking send on
        the calling thread (a rospy callback, a reader), which saves the writer thread's wake-up and keeps 1 kHz
        latency low. Whatever the socket does not take goes to the queue: the unsent rest of a frame as
        non-droppable (it must follow its first bytes), so frames stay whole and in order. The writer thread
        takes the same lock for each batch, so the two paths never interleave bytes. A peer that does not keep up
        (DIRECT_SEND_MAX_UNSENT bytes waiting in the kernel) is left to the writer thread: measured, sending to a
        never-reading client from rospy's receive thread slowed that thread to ~580 msg/s for every client.
        The kernel is asked (an ioctl, a fifth of a fan-out's cost) only when what was written since it last
        answered could have reached the limit.
        """
        if self._send_lock.acquire(blocking=False):
            try:
                if not self.queue and not self._closed.is_set() and self._peer_keeps_up(len(frame)):
                    try:
                        sent = send_now(self.sock, frame)
                    except OSError:  # the connection is gone; the reader sees it too and cleans up
                        self.close()
                        return
                    self._unsent_bound += sent
                    if sent == len(frame):
                        self.frames_out += 1
                        return
                    if sent:
                        self.queue.put(frame[sent:], droppable=False)
                        return
            finally:
                self._send_lock.release()
        self.queue.put(frame, droppable)

    def _peer_keeps_up(self, size: int) -> bool:
        """Fewer than DIRECT_SEND_MAX_UNSENT bytes would wait in the kernel after sending `size` more. Called with
        the send lock held; `_unsent_bound` is the last measured backlog plus everything written since."""
        if self._unsent_bound + size < DIRECT_SEND_MAX_UNSENT:
            return True
        self._unsent_bound = unsent_bytes(self.sock)
        return self._unsent_bound + size < DIRECT_SEND_MAX_UNSENT

    def run_call(self, what: str, call: Callable[[], None]) -> None:
        """Run a ROS call (service, topic list) on this client's own workers, so a slow ROS side holds up only this
        client's calls; refused with __error when too many are waiting already."""
        with self._calls_lock:
            if self._calls_pending >= self.endpoint.config.client_max_pending_calls:
                raise ClientError(
                    f"{what}: refused, this client already has {self._calls_pending} ROS calls in progress; "
                    "this call will not complete"
                )
            self._calls_pending += 1

        def run() -> None:
            try:
                call()
            finally:
                with self._calls_lock:
                    self._calls_pending -= 1

        try:
            self._calls.submit(run)
        except RuntimeError:  # the session is closing and its workers are shut down
            with self._calls_lock:
                self._calls_pending -= 1

    def send_error(self, text: str) -> None:
        # Errors are diagnostics (Unity only logs them): droppable, so a client that floods bad input and never
        # reads cannot grow the endpoint's memory; and logged at most once a second per client, so it cannot
        # flood the log either.
        self._log_error(text)
        self.send(protocol.error_frame(text), droppable=True)

    def _log_error(self, text: str) -> None:
        now = time.monotonic()
        if now - self._last_error_logged_at < ERROR_LOG_INTERVAL_S:
            self._errors_not_logged += 1
            return
        not_logged = f" ({self._errors_not_logged} more error(s) not logged)" if self._errors_not_logged else ""
        log.warning("client %s: %s%s", self.name, text, not_logged)
        self._last_error_logged_at = now
        self._errors_not_logged = 0

    def close(self) -> None:
        if self._closed.is_set():
            return
        self._closed.set()
        self.queue.close(discard=True)
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass

    # --- reader -----------------------------------------------------------------------------------------------
    def _read_loop(self) -> None:
        try:
            while not self._closed.is_set():
                data = self.sock.recv(RECV_BYTES)
                if not data:
                    break
                try:
                    frames = self.decoder.feed(data)
                except FramingError as error:
                    # The stream position is lost: say why, flush, and close this connection only.
                    self.send_error(f"framing lost, closing the connection: {error}")
                    break
                for frame in frames:
                    if not self._handle(frame):
                        return
                # frames that came together go to ROS together; one that came alone may go directly (RawPublisher)
                self._publish_pending(alone=len(frames) == 1)
        except OSError as error:
            if not self._closed.is_set():
                log.info("client %s: connection error: %s", self.name, error)
        finally:
            self._finish()

    def _finish(self) -> None:
        self.endpoint.release(self)
        self._calls.shutdown(wait=False, cancel_futures=True)  # running calls end by their timeout
        # Let the writer drain what is queued (e.g. the closing __error), then close the socket.
        self.queue.close()
        self._writer.join(timeout=2.0)
        self.close()
        self.sock.close()
        log.info(
            "client %s disconnected (frames in %d, out %d, dropped %d)",
            self.name, self.frames_in, self.frames_out, self.queue.dropped,
        )

    def _handle(self, item: Frame | BadFrame) -> bool:
        """Handle one frame; False when the connection must close."""
        self.frames_in += 1
        if isinstance(item, BadFrame):
            self.expect_body = None
            self.send_error(f"frame dropped: {item.reason}")
            return True
        frame = item
        if frame.is_keepalive:
            return True
        try:
            if not self.authenticated:
                return self._authenticate(frame)
            if self.expect_body is None and not frame.is_syscommand:
                self._collect_publication(frame)
                return True
            self._publish_pending()  # messages that came before a command go to ROS before it takes effect
            if self.expect_body is not None:
                self._handle_body(frame)
            else:
                self._handle_syscommand(frame)
        except (ProtocolError, ClientError) as error:
            self.send_error(str(error))
        except Exception as error:  # a bug must cost one frame, never the connection or the endpoint
            log.exception("client %s: unexpected failure on %r", self.name, frame.destination)
            self.send_error(f"internal error handling {frame.destination!r}: {error}")
        return True

    def _collect_publication(self, frame: Frame) -> None:
        publisher = self.endpoint.publisher_for(self, frame)  # ClientError: not registered, or invalid payload
        if publisher is not self._pending_publisher:
            self._publish_pending()
            self._pending_publisher = publisher
        self._pending_payloads.append(frame.payload)

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

    def _authenticate(self, frame: Frame) -> bool:
        token = self.endpoint.config.auth_token
        assert token is not None
        try:
            command = protocol.parse_syscommand(frame) if frame.destination == "__auth" else None
        except ProtocolError as error:
            command = None
            self.send_error(str(error))
        if isinstance(command, Auth) and hmac.compare_digest(command.token.encode(), token.encode()):
            self.authenticated = True
            return True
        self.send_error("authentication required: the first command must be __auth with the endpoint's token")
        return False

    def _handle_body(self, frame: Frame) -> None:
        assert self.expect_body is not None
        kind, srv_id = self.expect_body
        self.expect_body = None
        if kind == "request":
            self.endpoint.call_ros_service(self, srv_id, frame)
        elif kind == "response":
            self.endpoint.complete_unity_response(self, srv_id, frame)
        # kind == "discard": the body of a refused __response; consumed so framing state stays right.

    def _handle_syscommand(self, frame: Frame) -> None:
        command = protocol.parse_syscommand(frame)
        endpoint = self.endpoint
        match command:
            case Subscribe():
                endpoint.subscribe(self, command)
            case Publish():
                endpoint.register_publisher(self, command)
            case RosService():
                endpoint.register_ros_service(self, command)
            case UnityService():
                endpoint.register_unity_service(self, command)
            case Request(srv_id=srv_id):
                self.expect_body = ("request", srv_id)
            case Response(srv_id=srv_id):
                if endpoint.accept_unity_response(self, srv_id):
                    self.expect_body = ("response", srv_id)
                else:
                    self.expect_body = ("discard", srv_id)
                    raise ClientError(
                        f"__response: unknown srv_id {srv_id} (never requested from this client, or timed out); "
                        "the next frame is discarded"
                    )
            case TopicList():
                endpoint.send_topic_list(self)
            case Remove(kind="subscriber", topic=topic):
                endpoint.unsubscribe(self, endpoint.ros.resolve(topic))
            case Remove(kind="publisher", topic=topic):
                endpoint.unregister_publisher(self, topic)
            case Remove(kind="ros_service", topic=topic):
                self.ros_services.pop(topic, None)
            case Remove(kind="unity_service", topic=topic):
                endpoint.unregister_unity_service(self, endpoint.ros.resolve(topic))
            case Auth():
                pass  # already authenticated (or auth is off): harmless
            case _:
                raise ClientError(f"system command {frame.destination!r} is not accepted by the endpoint")

    # --- writer -----------------------------------------------------------------------------------------------
    def _write_loop(self) -> None:
        try:
            while self.queue.wait(timeout=DROP_WARNING_INTERVAL_S):
                # Take the batch under the send lock: a direct send (see send) can then never slip between
                # taking frames off the queue and writing them.
                with self._send_lock:
                    batch = self.queue.take_all(timeout=0) or []
                    warning = self._drop_warning()
                    if warning is not None:
                        batch.append(warning)
                    if batch:
                        data = b"".join(batch)
                        self.sock.sendall(data)
                        self.frames_out += len(batch)
                        self._unsent_bound += len(data)
        except OSError as error:
            if not self._closed.is_set():
                log.info("client %s: write failed: %s", self.name, error)
            self.close()

    def _drop_warning(self) -> bytes | None:
        """At most once per wake-up (>= 1 s apart when idle): how many frames were lost each way."""
        dropped, publish_dropped = self.queue.dropped, self.publish_drops
        if dropped == self._reported_drops and publish_dropped == self._reported_publish_drops:
            return None
        now = time.monotonic()
        if now - self._last_drop_warning_at < DROP_WARNING_INTERVAL_S:
            return None
        self._last_drop_warning_at = now
        parts = []
        if dropped != self._reported_drops:
            parts.append(
                f"client reads too slowly: {dropped - self._reported_drops} outgoing message(s) dropped "
                f"(oldest first), {dropped} in total"
            )
        if publish_dropped != self._reported_publish_drops:
            parts.append(
                f"ROS subscribers take this client's messages too slowly: {publish_dropped - self._reported_publish_drops} "
                f"published message(s) dropped (oldest first; raise queue_size in __publish), {publish_dropped} in total"
            )
        self._reported_drops, self._reported_publish_drops = dropped, publish_dropped
        return protocol.warn_frame("; ".join(parts))
