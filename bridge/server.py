"""The endpoint's TCP server: accepts clients (bridge.session) and owns what they share on the ROS graph.

One rospy subscriber per topic fans out to every subscribed client; one publisher per topic takes every
publishing client's bytes; ROS services both ways; raw passthrough throughout.

Threads: one accept thread; per client a reader (frames in), a writer (drains the client's bounded queue when a
direct send could not write everything, see ClientSession.send) and a few workers for its ROS service calls and
topic-list look-ups (so a slow service never stalls a reader, nor another client's calls); per published topic a
pump thread (bridge.ros.RawPublisher); rospy's own threads deliver ROS messages, which are fanned out to the
subscribed clients.
"""
from __future__ import annotations

import fnmatch
import itertools
import logging
import math
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from bridge import protocol
from bridge.protocol import Frame, Publish, RosService, Subscribe, UnityService
from bridge.ros import RawPublisher, RawServiceProxy, RosError, RosGraph
from bridge.session import ClientError, ClientSession
from bridge.sockets import tune_socket

log = logging.getLogger(__name__)


class ConfigError(ValueError):
    """A setting the endpoint cannot serve clients with; `setting` is the EndpointConfig field concerned."""

    def __init__(self, setting: str, problem: str) -> None:
        super().__init__(f"{setting}: {problem}")
        self.setting = setting
        self.problem = problem


# Unity's client reads frame lengths as signed 32-bit integers: nothing longer can be framed.
MAX_FRAME_LENGTH = 2**31 - 1


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

    def __post_init__(self) -> None:
        """Refuse, before anything starts, settings that would fail later: at bind, or at every client's connect."""
        if not isinstance(self.tcp_ip, str) or not self.tcp_ip:
            raise ConfigError("tcp_ip", f"must be an address or host name, got {self.tcp_ip!r}")
        _check_whole("tcp_port", self.tcp_port, 0, 65535)
        _check_whole("max_payload_bytes", self.max_payload_bytes, 1, MAX_FRAME_LENGTH)
        _check_whole("max_destination_bytes", self.max_destination_bytes, 1, MAX_FRAME_LENGTH)
        _check_whole("client_queue_frames", self.client_queue_frames, 1)
        _check_whole("client_queue_bytes", self.client_queue_bytes, 1)
        _check_whole("client_call_workers", self.client_call_workers, 1)
        _check_whole("client_max_pending_calls", self.client_max_pending_calls, 1)
        timeout = self.service_timeout_s
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not (0 < timeout < math.inf):
            raise ConfigError("service_timeout_s", f"must be a positive number of seconds, got {timeout!r}")

    def permits(self, resolved_name: str) -> bool:
        if any(fnmatch.fnmatchcase(resolved_name, pattern) for pattern in self.deny_topics):
            return False
        return not self.allow_topics or any(
            fnmatch.fnmatchcase(resolved_name, pattern) for pattern in self.allow_topics
        )


def _check_whole(setting: str, value: object, lowest: int, highest: int | None = None) -> None:
    in_range = value >= lowest and (highest is None or value <= highest) if isinstance(value, int) else False
    if isinstance(value, bool) or not in_range:
        allowed = f"from {lowest} to {highest}" if highest is not None else f"of at least {lowest}"
        raise ConfigError(setting, f"must be a whole number {allowed}, got {value!r}")


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
    service_name: str  # 'pkg/Service', to check the client's response
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
        # Totals of the clients that have left (those still connected are summed in stats()).
        self.frames_in = 0
        self.frames_out = 0
        self.dropped = 0

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
            "dropped": self.dropped + sum(s.queue.dropped for s in sessions),
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
            session: ClientSession | None = None
            try:
                tune_socket(sock)
                session = ClientSession(self, sock, address, next(self._client_ids))
                with self._lock:
                    self._sessions.add(session)
                session.start()
            except Exception:  # e.g. no thread to be had: this client goes, the endpoint keeps accepting others
                log.exception("could not serve the client at %s:%d", *address[:2])
                if session is not None:
                    self.release(session)
                    session.close()
                sock.close()

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
            self.dropped += session.queue.dropped

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

    def publisher_for(self, session: ClientSession, frame: Frame) -> RawPublisher:
        """The ROS publisher a client's topic frame goes to, once the client may publish there and the payload is
        exactly one message of the topic's type; ClientError says why not. The session batches what one read
        brought for the same publisher (RawPublisher.publish)."""
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
        return publisher

    def call_ros_service(self, session: ClientSession, srv_id: int, frame: Frame) -> None:
        proxy = session.ros_services.get(frame.destination)
        if proxy is None:
            raise ClientError(
                f"__request {srv_id}: service {frame.destination!r} was not registered with __ros_service; "
                "this call will not complete"
            )
        if self.config.validate_payloads:
            try:
                self.ros.types.validate_service(proxy.service_name, "request", frame.payload)
            except RosError as error:
                # The "__request <srv_id>:" prefix lets a client fail that call at once (bridge.client does).
                raise ClientError(
                    f"__request {srv_id}: service {frame.destination}: {error}; not sent to ROS, this call will not "
                    "complete"
                ) from None
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
            call = _PendingUnityCall(service.owner, service.message_name)
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
        if self.config.validate_payloads:
            try:
                self.ros.types.validate_service(call.service_name, "response", frame.payload)
            except RosError as error:
                # The ROS caller hears at once instead of getting bytes it cannot read (or waiting for a timeout).
                call.failure = f"client {session.name} answered with an invalid response: {error}"
                call.done.set()
                raise ClientError(
                    f"__response {srv_id}: service {frame.destination}: {error}; the ROS call fails"
                ) from None
        call.response = frame.payload
        call.done.set()
