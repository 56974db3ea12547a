"""The endpoint's TCP server: one session per client, shared ROS topics and services, raw passthrough.

Threads: one accept thread; per client a reader (frames in), a writer (drains the client's bounded queue when a
direct send could not write everything, see ClientSession.send) and a few workers for its ROS service calls and
topic-list look-ups (so a slow service never stalls a reader, nor another client's calls); per published topic a
pump thread (bridge.ros.RawPublisher); rospy's own threads deliver ROS messages, which are fanned out to the
subscribed clients.
"""
from __future__ import annotations

import fcntl
import fnmatch
import hmac
import itertools
import logging
import socket
import struct
import termios
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from collections.abc import Callable
from typing import Any

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
from bridge.ros import RawPublisher, RawServiceProxy, RosError, RosGraph

log = logging.getLogger(__name__)

RECV_BYTES = 256 * 1024
# A client with more than this waiting unacknowledged in its socket is not keeping up: no direct sends to it.
DIRECT_SEND_MAX_UNSENT = 64 * 1024
DROP_WARNING_INTERVAL_S = 1.0
ERROR_LOG_INTERVAL_S = 1.0


@dataclass
class EndpointConfig:
    tcp_ip: str = "127.0.0.1"
    tcp_port: int = 10000
    max_payload_bytes: int = protocol.DEFAULT_MAX_PAYLOAD_BYTES
    max_destination_bytes: int = protocol.MAX_DESTINATION_BYTES
    client_queue_frames: int = 1024
    client_queue_bytes: int = 4 * 1024 * 1024
    auth_token: str | None = None  # off by default: Unity's client cannot send __auth
    allow_topics: tuple[str, ...] = ()  # fnmatch patterns on resolved names; empty = everything
    deny_topics: tuple[str, ...] = ()
    service_timeout_s: float = 10.0
    validate_payloads: bool = True
    # Per client: ROS service calls and topic-list look-ups in flight at once, and queued behind them. Each client
    # has its own workers, so one client calling missing services (each waiting service_timeout_s) delays only
    # its own later calls.
    client_call_workers: int = 4
    client_max_pending_calls: int = 64

    def permits(self, resolved_name: str) -> bool:
        if any(fnmatch.fnmatchcase(resolved_name, pattern) for pattern in self.deny_topics):
            return False
        return not self.allow_topics or any(
            fnmatch.fnmatchcase(resolved_name, pattern) for pattern in self.allow_topics
        )


class ClientError(Exception):
    """A request of one client that is refused; the text goes back to that client as __error."""


# ---------------------------------------------------------------------------------------------------------------


@dataclass
class _SharedSubscriber:
    message_name: str
    handle: Any
    # (session, topic as that client spells it); replaced whole so rospy callbacks read it without a lock
    clients: tuple[tuple[ClientSession, str], ...] = ()


@dataclass
class _SharedPublisher:
    message_name: str
    publisher: RawPublisher
    clients: set[ClientSession] = field(default_factory=set)


@dataclass
class _UnityService:
    message_name: str
    handle: Any
    owner: ClientSession
    client_name: str


@dataclass
class _PendingUnityCall:
    owner: ClientSession
    done: threading.Event = field(default_factory=threading.Event)
    response: bytes | None = None
    failure: str | None = None


class Endpoint:
    """The ROS-TCP endpoint: accepts clients and connects them to the ROS graph."""

    def __init__(self, ros: RosGraph, config: EndpointConfig) -> None:
        self.ros = ros
        self.config = config
        self._lock = threading.RLock()
        self._sessions: set[ClientSession] = set()
        self._subscribers: dict[str, _SharedSubscriber] = {}
        self._publishers: dict[str, _SharedPublisher] = {}
        self._unity_services: dict[str, _UnityService] = {}
        self._service_proxies: dict[tuple[str, str], RawServiceProxy] = {}
        self._pending_unity_calls: dict[int, _PendingUnityCall] = {}
        self._unity_srv_ids = itertools.count(1001)
        self._client_ids = itertools.count(1)
        self._listener: socket.socket | None = None
        self._accept_thread: threading.Thread | None = None
        self._stopping = threading.Event()
        self.frames_in = 0
        self.frames_out = 0

    # --- lifecycle ------------------------------------------------------------------------------------------
    def start(self) -> int:
        """Bind and start accepting; returns the actual port (useful with tcp_port 0)."""
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((self.config.tcp_ip, self.config.tcp_port))
        listener.listen(64)
        self._listener = listener
        self._accept_thread = threading.Thread(target=self._accept_loop, name="accept", daemon=True)
        self._accept_thread.start()
        port = listener.getsockname()[1]
        log.info("ROS-TCP endpoint listening on %s:%d", self.config.tcp_ip, port)
        return port

    def stop(self) -> None:
        self._stopping.set()
        if self._listener is not None:
            # shutdown() wakes the blocked accept(); close() alone does not on Linux.
            try:
                self._listener.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            self._listener.close()
        for session in list(self._sessions):
            session.close()
        if self._accept_thread is not None:
            self._accept_thread.join(timeout=2)
        log.info("endpoint stopped: %s", self.stats())

    def stats(self) -> dict[str, int]:
        with self._lock:
            sessions = list(self._sessions)
        return {
            "clients": len(sessions),
            "frames_in": self.frames_in + sum(s.frames_in for s in sessions),
            "frames_out": self.frames_out + sum(s.frames_out for s in sessions),
            "dropped": sum(s.queue.dropped for s in sessions),
        }

    def _accept_loop(self) -> None:
        assert self._listener is not None
        while not self._stopping.is_set():
            try:
                sock, address = self._listener.accept()
            except OSError:
                if self._stopping.is_set():
                    return
                log.exception("accept failed")
                time.sleep(0.1)
                continue
            _tune_socket(sock)
            session = ClientSession(self, sock, address, next(self._client_ids))
            with self._lock:
                self._sessions.add(session)
            session.start()

    # --- registrations (called from a session's reader thread) --------------------------------------------------
    def _checked_name(self, name: str) -> str:
        resolved = self.ros.resolve(name)
        if not self.config.permits(resolved):
            raise ClientError(f"topic {resolved} is not permitted by the endpoint's allow/deny lists")
        return resolved

    def subscribe(self, session: ClientSession, command: Subscribe) -> None:
        resolved = self._checked_name(command.topic)
        with self._lock:
            shared = self._subscribers.get(resolved)
            if shared is not None and shared.message_name != command.message_name:
                raise ClientError(
                    f"__subscribe: topic {resolved} is already bridged as {shared.message_name}, "
                    f"not {command.message_name}"
                )
            if shared is None:
                handle = self._ros_call(lambda: self.ros.make_subscriber(resolved, command.message_name, self._fan_out))
                shared = _SharedSubscriber(command.message_name, handle)
                self._subscribers[resolved] = shared
            others = tuple(entry for entry in shared.clients if entry[0] is not session)
            shared.clients = others + ((session, command.topic),)
            session.subscriptions[resolved] = command.topic

    def unsubscribe(self, session: ClientSession, resolved: str) -> None:
        with self._lock:
            session.subscriptions.pop(resolved, None)
            shared = self._subscribers.get(resolved)
            if shared is None:
                return
            shared.clients = tuple(entry for entry in shared.clients if entry[0] is not session)
            if not shared.clients:
                del self._subscribers[resolved]
                shared.handle.unregister()

    def register_publisher(self, session: ClientSession, command: Publish) -> None:
        resolved = self._checked_name(command.topic)
        with self._lock:
            shared = self._publishers.get(resolved)
            if shared is not None and shared.message_name != command.message_name:
                if shared.clients:
                    raise ClientError(
                        f"__publish: topic {resolved} is already published as {shared.message_name}, "
                        f"not {command.message_name}"
                    )
                # Kept advertised after its clients left (see release), but nobody uses it: retype it.
                del self._publishers[resolved]
                shared.publisher.unregister()
                shared = None
            if shared is None:
                publisher = self._ros_call(
                    lambda: self.ros.make_publisher(
                        resolved, command.message_name, command.queue_size, command.latch,
                        self.config.client_queue_bytes,
                    )
                )
                shared = _SharedPublisher(command.message_name, publisher)
                self._publishers[resolved] = shared
            shared.clients.add(session)
            session.publishers[command.topic] = (resolved, shared.publisher)

    def unregister_publisher(self, session: ClientSession, client_topic: str, keep_advertised: bool = False) -> None:
        with self._lock:
            entry = session.publishers.pop(client_topic, None)
            if entry is None:
                return
            resolved = entry[0]
            shared = self._publishers.get(resolved)
            if shared is None:
                return
            shared.clients.discard(session)
            if not shared.clients and not keep_advertised:
                del self._publishers[resolved]
                shared.publisher.unregister()

    def register_ros_service(self, session: ClientSession, command: RosService) -> None:
        resolved = self._checked_name(command.topic)
        with self._lock:
            key = (resolved, command.message_name)
            if key not in self._service_proxies:
                self._service_proxies[key] = self._ros_call(
                    lambda: self.ros.make_service_proxy(resolved, command.message_name)
                )
            session.ros_services[command.topic] = self._service_proxies[key]

    def register_unity_service(self, session: ClientSession, command: UnityService) -> None:
        resolved = self._checked_name(command.topic)
        with self._lock:
            existing = self._unity_services.get(resolved)
            if existing is not None and existing.message_name == command.message_name:
                # Re-registration (typically a reconnect): the newest client answers from now on.
                existing.owner.unity_services.discard(resolved)
                existing.owner = session
                existing.client_name = command.topic
                session.unity_services.add(resolved)
                return
            if existing is not None:
                raise ClientError(
                    f"__unity_service: service {resolved} is already provided as {existing.message_name}, "
                    f"not {command.message_name}"
                )
            handle = self._ros_call(
                lambda: self.ros.make_service(
                    resolved, command.message_name, lambda request: self._call_unity_service(resolved, request)
                )
            )
            self._unity_services[resolved] = _UnityService(command.message_name, handle, session, command.topic)
            session.unity_services.add(resolved)

    def unregister_unity_service(self, session: ClientSession, resolved: str) -> None:
        with self._lock:
            session.unity_services.discard(resolved)
            service = self._unity_services.get(resolved)
            if service is None or service.owner is not session:
                return
            del self._unity_services[resolved]
            service.handle.shutdown("client removed the service")

    def release(self, session: ClientSession) -> None:
        """Undo everything a departing client registered; fail its pending service calls."""
        with self._lock:
            self._sessions.discard(session)
            for resolved in list(session.subscriptions):
                self.unsubscribe(session, resolved)
            # Publishers stay advertised (as in the original endpoint): a client that reconnects re-registers
            # them, and re-advertising a topic from the same node races rospy's subscriber reconnect logic, so
            # ROS subscribers would miss the first messages after every reconnect. __remove_publisher unadvertises.
            for client_topic in list(session.publishers):
                self.unregister_publisher(session, client_topic, keep_advertised=True)
            for resolved in list(session.unity_services):
                self.unregister_unity_service(session, resolved)
            session.ros_services.clear()
            for call in self._pending_unity_calls.values():
                if call.owner is session:
                    call.failure = f"client {session.name} disconnected before answering"
                    call.done.set()
            self.frames_in += session.frames_in
            self.frames_out += session.frames_out

    @staticmethod
    def _ros_call(make: Any) -> Any:
        try:
            return make()
        except RosError as error:
            raise ClientError(str(error)) from None

    # --- data paths -------------------------------------------------------------------------------------------
    def _fan_out(self, resolved: str, payload: bytes) -> None:
        """rospy callback: one received message to every client subscribed to the topic, bytes untouched."""
        shared = self._subscribers.get(resolved)
        if shared is None:
            return
        frames: dict[str, bytes] = {}
        for session, client_topic in shared.clients:
            frame = frames.get(client_topic)
            if frame is None:
                frame = frames[client_topic] = protocol.encode_frame(client_topic, payload)
            session.send(frame)

    def publish(self, session: ClientSession, frame: Frame) -> None:
        entry = session.publishers.get(frame.destination)
        if entry is None:
            raise ClientError(
                f"message for topic {frame.destination!r}, which this client has not registered with __publish"
            )
        resolved, publisher = entry
        if self.config.validate_payloads:
            try:
                self.ros.types.validate(publisher.message_name, frame.payload)
            except RosError as error:
                raise ClientError(f"topic {resolved}: {error}; message not published") from None
        # Never blocks: the publisher's pump thread writes to ROS. Drops are reported by the writer (__warn).
        session.publish_drops += publisher.publish(frame.payload)

    def call_ros_service(self, session: ClientSession, srv_id: int, frame: Frame) -> None:
        proxy = session.ros_services.get(frame.destination)
        if proxy is None:
            raise ClientError(
                f"__request {srv_id}: service {frame.destination!r} was not registered with __ros_service; "
                "this call will not complete"
            )
        timeout = self.config.service_timeout_s

        def call() -> None:
            try:
                response = proxy.call(frame.payload, timeout)
            except RosError as error:
                session.send_error(f"__request {srv_id}: {error}; this call will not complete")
                return
            header = protocol.encode_syscommand("__response", {"srv_id": srv_id})
            # header and body back to back as one item: nothing can come between them on the wire.
            session.send(header + protocol.encode_frame(frame.destination, response), droppable=False)

        session.run_call(f"__request {srv_id} ({frame.destination})", call)

    def send_topic_list(self, session: ClientSession) -> None:
        def look_up() -> None:
            try:
                topics, types = self.ros.topic_types()
            except OSError as error:
                session.send_error(f"__topic_list: the ROS master did not answer: {error}")
                return
            session.send(protocol.encode_syscommand("__topic_list", {"topics": topics, "types": types}), False)

        session.run_call("__topic_list", look_up)

    def _call_unity_service(self, resolved: str, request: bytes) -> bytes:
        """rospy service thread: forward a ROS request to the owning client and wait for its __response."""
        with self._lock:
            service = self._unity_services.get(resolved)
            if service is None:
                raise RosError(f"service {resolved} has no client any more")
            srv_id = next(self._unity_srv_ids)
            call = _PendingUnityCall(service.owner)
            self._pending_unity_calls[srv_id] = call
            client_name = service.client_name
        header = protocol.encode_syscommand("__request", {"srv_id": srv_id})
        call.owner.send(header + protocol.encode_frame(client_name, request), droppable=False)
        try:
            if not call.done.wait(self.config.service_timeout_s):
                raise RosError(f"client did not answer {resolved} within {self.config.service_timeout_s:g} s")
            if call.failure is not None:
                raise RosError(call.failure)
            assert call.response is not None
            return call.response
        finally:
            with self._lock:
                self._pending_unity_calls.pop(srv_id, None)

    def accept_unity_response(self, session: ClientSession, srv_id: int) -> bool:
        with self._lock:
            call = self._pending_unity_calls.get(srv_id)
            return call is not None and call.owner is session

    def complete_unity_response(self, session: ClientSession, srv_id: int, frame: Frame) -> None:
        with self._lock:
            call = self._pending_unity_calls.get(srv_id)
        if call is None or call.owner is not session:
            raise ClientError(f"__response {srv_id}: the call timed out or is unknown; response discarded")
        call.response = frame.payload
        call.done.set()


# ---------------------------------------------------------------------------------------------------------------


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
        # Threads are started on demand, so a client that never calls a service costs none.
        self._calls = ThreadPoolExecutor(config.client_call_workers, thread_name_prefix=f"calls {self.name}")
        self._calls_lock = threading.Lock()
        self._calls_pending = 0
        self.publish_drops = 0  # this client's messages dropped before reaching ROS (publisher queue full)
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
        """
        if self._send_lock.acquire(blocking=False):
            try:
                if not self.queue and not self._closed.is_set() and _unsent_bytes(self.sock) < DIRECT_SEND_MAX_UNSENT:
                    try:
                        sent = self.sock.send(frame, socket.MSG_DONTWAIT)
                    except BlockingIOError:
                        sent = 0
                    except OSError:  # the connection is gone; the reader sees it too and cleans up
                        self.close()
                        return
                    if sent == len(frame):
                        self.frames_out += 1
                        return
                    if sent:
                        self.queue.put(frame[sent:], droppable=False)
                        return
            finally:
                self._send_lock.release()
        self.queue.put(frame, droppable)

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
            if self.expect_body is not None:
                self._handle_body(frame)
            elif frame.is_syscommand:
                self._handle_syscommand(frame)
            else:
                self.endpoint.publish(self, frame)
        except (ProtocolError, ClientError) as error:
            self.send_error(str(error))
        except Exception as error:  # a bug must cost one frame, never the connection or the endpoint
            log.exception("client %s: unexpected failure on %r", self.name, frame.destination)
            self.send_error(f"internal error handling {frame.destination!r}: {error}")
        return True

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
                        self.sock.sendall(b"".join(batch))
                        self.frames_out += len(batch)
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


def _unsent_bytes(sock: socket.socket) -> int:
    """Bytes in the socket's send queue not yet acknowledged by the peer (Linux SIOCOUTQ); 0 if unknown."""
    try:
        return _INT.unpack(fcntl.ioctl(sock.fileno(), termios.TIOCOUTQ, _INT_ZERO))[0]
    except OSError:
        return 0


_INT = struct.Struct("i")
_INT_ZERO = bytes(_INT.size)


def _tune_socket(sock: socket.socket) -> None:
    # TCP_NODELAY: at 1 kHz, Nagle + delayed ACK would add 40 ms spikes. Keepalive reaps vanished peers.
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
    for option, value in (("TCP_KEEPIDLE", 10), ("TCP_KEEPINTVL", 5), ("TCP_KEEPCNT", 3)):
        if hasattr(socket, option):
            sock.setsockopt(socket.IPPROTO_TCP, getattr(socket, option), value)
