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

import itertools
import logging
import socket
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Deque, Dict, List, Optional, Set, Tuple, TypeVar

from bridge import protocol
from bridge.config import EndpointConfig
from bridge.diagnostics import ClientSnapshot, TopicSnapshot, parse_client_time, report
from bridge.protocol import (
    Auth,
    Event,
    Ping,
    PingResponse,
    Publish,
    Remove,
    RosService,
    ServiceRequest,
    ServiceResponse,
    Subscribe,
    TopicList,
    TopicListQuery,
    TopicMessage,
    UnityService,
    Warn,
)
from bridge.ros import RawPublisher, RawServiceProxy, RosError, RosGraph, end_topic
from bridge.session import ClientSession, RequestRefused
from bridge.admission import to_evict
from bridge.auth import AuthGuard
from bridge.memory import QuietTrim, give_back_free_memory
from bridge.queues import ByteBudget
from bridge.sockets import send_now, tune_socket
from bridge.throttle import LogThrottle

__all__ = ["Endpoint"]

log = logging.getLogger(__name__)
_Made = TypeVar("_Made")
# Client messages remembered per topic until they come back from ROS (see _SharedSubscriber.echoes)
ECHO_RECORD_MAX = 4096
DIAGNOSTICS_PERIOD_S = 1.0  # /diagnostics at 1 Hz, as ROS's diagnostic tools expect


# Requests whose answer the client must read (it is never dropped), and how they are named in a refusal
_ANSWERED: Dict[type, str] = {TopicListQuery: "__topic_list", Ping: "__ping", ServiceRequest: "__request"}


@dataclass
class _Registrations:
    """What one client registered, as the endpoint keeps it (the session knows none of it)."""

    subscriptions: Dict[str, str] = field(default_factory=dict)  # resolved topic -> topic as the client spells it
    publishers: Dict[str, Tuple[str, RawPublisher]] = field(default_factory=dict)  # client topic -> (resolved, ...)
    ros_services: Dict[str, RawServiceProxy] = field(default_factory=dict)  # client's service name -> proxy
    unity_services: Set[str] = field(default_factory=set)  # resolved names

    def count(self) -> int:
        return len(self.subscriptions) + len(self.publishers) + len(self.ros_services) + len(self.unity_services)


# One client's subscription to a topic: (its session, the topic as it spells it, its queue depth for the topic: at
# most that many of the topic's frames wait for it; 0 = only the client's own bound). A plain tuple: the fan-out
# unpacks it for every message and client, where attribute lookups cost a tenth of the work.
_Subscription = Tuple[ClientSession, str, int]


@dataclass
class _SharedSubscriber:
    message_name: str
    handle: Any
    # replaced whole, never changed in place, so rospy callbacks read it without a lock
    clients: Tuple[_Subscription, ...] = ()
    untyped: Optional[str] = None  # why there is no class of the type, when there is none
    latest_only: bool = False  # a client behind gets only the newest message (EndpointConfig.latest_only)
    delivered: int = 0  # messages from ROS fanned out (for /diagnostics; rospy's threads count, roughly)
    # Per client that publishes on the topic and subscribes to it: what it published, in its order, so the copy that
    # comes back from ROS (through our own publisher) skips it. Each client's messages reach ROS in the order it sent
    # them; different clients' messages interleave in any order.
    echoes: Dict[ClientSession, Deque[bytes]] = field(default_factory=dict)
    echoes_lock: threading.Lock = field(default_factory=threading.Lock)  # readers append, rospy's thread takes


@dataclass
class _SharedPublisher:
    message_name: str
    publisher: RawPublisher
    clients: Set[ClientSession] = field(default_factory=set)
    unused_since: Optional[float] = None  # monotonic time its last client left (see Endpoint.release)


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
    response: Optional[bytes] = None
    failure: Optional[str] = None


class Endpoint:
    """The ROS-TCP endpoint: accepts clients and connects them to the ROS graph (the owner of every session)."""

    def __init__(self, ros: RosGraph, config: EndpointConfig) -> None:
        self.ros = ros
        self.config = config
        self._lock = threading.RLock()
        self._node_name = ros.node_name()
        self._clients: Dict[ClientSession, _Registrations] = {}
        self._subscribers: Dict[str, _SharedSubscriber] = {}
        self._publishers: Dict[str, _SharedPublisher] = {}
        self._unity_services: Dict[str, _UnityService] = {}
        self._pending_unity_calls: Dict[int, _PendingUnityCall] = {}
        self._unity_srv_ids = itertools.count(1001)
        self._client_ids = itertools.count(1)
        self._listener: Optional[socket.socket] = None
        self._accept_thread: Optional[threading.Thread] = None
        self._housekeeping_thread: Optional[threading.Thread] = None
        self._address = ""
        self._stopping = threading.Event()
        self._turned_away = LogThrottle(log)
        self._auth = AuthGuard(config.auth_token) if config.auth_token is not None else None
        self._partial_frames = ByteBudget(config.max_partial_frame_bytes)
        # messages at least this large go to a client that is behind only as the newest (0 in the settings: never)
        self._latest_only_bytes = config.latest_only_bytes or float("inf")
        self._accept_failures = LogThrottle(log)
        # Totals of the clients that have left (those still connected are summed in stats()).
        self.frames_in = 0
        self.frames_out = 0
        self.dropped = 0
        self.bytes_in_out = 0
        # What each client event does; topic messages take publisher_for, the session's fast path.
        self._handlers: Dict[type, Callable[[ClientSession, Any], None]] = {
            Subscribe: self._subscribe,
            Publish: self._register_publisher,
            RosService: self._register_ros_service,
            UnityService: self._register_unity_service,
            Remove: self._remove,
            ServiceRequest: self._call_ros_service,
            ServiceResponse: self._complete_unity_call,
            TopicListQuery: self._send_topic_list,
            Ping: self._answer_ping,
            Auth: lambda session, event: None,  # already authenticated (or auth is off): harmless
        }

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
        port: int = listener.getsockname()[1]
        self._address = f"{self.config.tcp_ip}:{port}"
        self._housekeeping_thread = threading.Thread(target=self._housekeeping_loop, name="housekeeping",
                                                     daemon=True)
        self._housekeeping_thread.start()
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
        with self._lock:
            sessions = list(self._clients)
            for call in self._pending_unity_calls.values():  # ROS callers of clients' services hear at once
                call.failure = "the endpoint is shutting down"
                call.done.set()
        self._wait_for_ros_callers_answered()
        for session in sessions:
            session.close("the endpoint is shutting down", tell_client=True)
        if self._accept_thread is not None:
            self._accept_thread.join(timeout=2)
        if self._housekeeping_thread is not None:
            self._housekeeping_thread.join(timeout=2)
        log.info("endpoint stopped: %s", self.stats())

    def _wait_for_ros_callers_answered(self, timeout_s: float = 1.0) -> None:
        """Until the ROS calls waiting for clients (just failed) have left for rospy to send their callers the error,
        before rospy's shutdown closes the connections (else a caller hears only that the connection broke)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with self._lock:
                if not self._pending_unity_calls:
                    return
            time.sleep(0.01)

    def bytes_moved(self) -> int:
        """Bytes received from and sent to clients since the start, all clients together."""
        with self._lock:
            sessions = list(self._clients)
        return self.bytes_in_out + sum(s.bytes_in + s.bytes_out for s in sessions)

    def stats(self) -> Dict[str, int]:
        with self._lock:
            sessions = list(self._clients)
        return {
            "clients": len(sessions),
            "frames_in": self.frames_in + sum(s.frames_in for s in sessions),
            "frames_out": self.frames_out + sum(s.frames_out for s in sessions),
            "dropped": self.dropped + sum(s.dropped for s in sessions),
        }

    def _accept_loop(self) -> None:
        assert self._listener is not None
        while not self._stopping.is_set():
            try:
                sock, address = self._listener.accept()
            except OSError as error:
                if self._stopping.is_set():
                    return
                self._accept_failures.warning("accepting a connection failed: %s", error)  # e.g. no descriptors left
                time.sleep(0.1)
                continue
            refusal = self._admission_refusal(address[0])
            if refusal is not None:
                _turn_away(sock, refusal)
                self._turned_away.warning("turned away a client at %s:%d: %s", address[0], address[1], refusal)
                continue
            session: Optional[ClientSession] = None
            try:
                tune_socket(sock, self.config.dead_peer_timeout_s)
                session = ClientSession(self, self.config, sock, address, next(self._client_ids), self._auth,
                                        self._partial_frames)
                with self._lock:
                    self._clients[session] = _Registrations()
                session.start()
            except Exception:  # e.g. no thread to be had: this client goes, the endpoint keeps accepting others
                log.exception("could not serve the client at %s:%d", *address[:2])
                if session is not None:
                    self.release(session)
                    session.close()
                sock.close()

    def _admission_refusal(self, host: str) -> Optional[str]:
        """Why a new client from `host` cannot be served now (a limit reached, and no connection there not using its
        slot: bridge.admission); None when it can, room having been made if needed."""
        now = time.monotonic()
        with self._lock:
            sessions = [session for session in self._clients if not session.closing]  # those leaving hold no slot
        from_host = [session for session in sessions if session.host == host]
        if len(sessions) >= self.config.max_clients:
            limit, among = f"the endpoint serves {len(sessions)} clients already, its limit (--max-clients)", sessions
        elif len(from_host) >= self.config.max_clients_per_address:
            limit = (f"the endpoint serves {len(from_host)} clients from {host} already, its limit per address "
                     "(--max-clients-per-address)")
            among = from_host
        else:
            return None
        uses = [session.slot_use(now) for session in among]
        victim = to_evict(uses)
        if victim is None:
            return limit
        use = uses[victim]
        doing = (f"{use.frame_bytes} bytes of a frame in {use.frame_for_s:.1f} s" if use.frame_for_s is not None
                 else f"no {'__auth' if not use.authenticated else 'frame'} in {use.connected_for_s:.1f} s")
        log.warning("client %s closed to make room for a new client from %s (%s): %s", among[victim].name, host,
                    limit, doing)
        among[victim].close(f"closed to make room for a new client: {limit}, and this connection sent {doing}",
                            tell_client=True)
        return None

    # --- the session's owner: every client event lands here ------------------------------------------------------
    def handle(self, session: ClientSession, event: Event) -> None:
        """Act on a client's command or service event (on its reader thread); RequestRefused says why not."""
        handler = self._handlers.get(type(event))
        if handler is None:
            raise RequestRefused(f"{type(event).__name__} is not accepted by the endpoint")
        if type(event) in _ANSWERED:
            unread = session.queue.kept_bytes
            if unread > self.config.client_queue_bytes:  # answers are never dropped: stop making them
                srv_id = event.srv_id if isinstance(event, ServiceRequest) else None
                raise RequestRefused(
                    f"{_ANSWERED[type(event)]}: refused, {unread} bytes of earlier answers wait unread by this "
                    "client", srv_id,
                )
        handler(session, event)

    def publisher_for(self, session: ClientSession, message: TopicMessage) -> RawPublisher:
        """The ROS publisher a client's topic message goes to, once the client may publish there and the payload is
        exactly one message of the topic's type. The session batches what one read brought for the same publisher
        (RawPublisher.publish)."""
        entry = self._clients[session].publishers.get(message.topic)
        if entry is None:
            raise RequestRefused(
                f"message for topic {message.topic!r}, which this client has not registered with __publish"
            )
        resolved, publisher = entry
        if self.config.validate_payloads:
            try:
                self.ros.types.validate(publisher.message_name, message.payload)
            except RosError as error:
                raise RequestRefused(f"topic {resolved}: {error}; message not published") from None
        subscribed = self._subscribers.get(resolved)
        if subscribed is not None and subscribed.echoes:
            own = subscribed.echoes.get(session)
            if own is not None:
                with subscribed.echoes_lock:
                    own.append(message.payload)
        return publisher

    def release(self, session: ClientSession) -> None:
        """Undo everything a departing client registered; fail its pending service calls."""
        with self._lock:
            registrations = self._clients.pop(session, None)
            if registrations is None:
                return
            for resolved in list(registrations.subscriptions):
                self._unsubscribe(session, registrations, resolved)
            # Publishers stay advertised for config.publisher_grace_s after their last client left (rosbridge's
            # unregister_timeout): a client that reconnects re-registers them, and re-advertising a topic from the
            # same node races rospy's subscriber reconnect logic, so ROS subscribers would miss the first messages
            # after every reconnect. Then they go (_end_unused_publishers). __remove_publisher unadvertises at once.
            for client_topic in list(registrations.publishers):
                self._unregister_publisher(session, registrations, client_topic, keep_advertised=True)
            for resolved in list(registrations.unity_services):
                self._unregister_unity_service(session, registrations, resolved)
            for call in self._pending_unity_calls.values():
                if call.owner is session:
                    call.failure = f"client {session.name} disconnected before answering"
                    call.done.set()
            self.frames_in += session.frames_in
            self.frames_out += session.frames_out
            self.dropped += session.dropped
            self.bytes_in_out += session.bytes_in + session.bytes_out

    # --- registrations ----------------------------------------------------------------------------------------
    def _checked_name(self, name: str) -> str:
        resolved = self.ros.resolve(name)
        if not self.config.permits(resolved):
            raise RequestRefused(f"topic {resolved} is not permitted by the endpoint's allow/deny lists")
        return resolved

    def _subscribe(self, session: ClientSession, command: Subscribe) -> None:
        resolved = self._checked_name(command.topic)
        raw, untyped = self.ros.subscriber_type(command.message_name)  # outside the lock: may read files
        with self._lock:
            shared = self._subscribers.get(resolved)
            if shared is not None and shared.message_name != command.message_name:
                raise RequestRefused(
                    f"__subscribe: topic {resolved} is already bridged as {shared.message_name}, "
                    f"not {command.message_name}"
                )
            self._check_room(session, "__subscribe", resolved, resolved in self._clients[session].subscriptions,
                             shared is None)
            created = shared is None
            if shared is None:
                handle = _made_for_client(
                    lambda: self.ros.make_subscriber(resolved, raw, command.message_name, self._fan_out)
                )
                shared = _SharedSubscriber(command.message_name, handle, untyped=untyped,
                                           latest_only=self.config.latest_only(resolved))
                self._subscribers[resolved] = shared
            if shared.untyped is not None:
                session.send(protocol.encode(Warn(
                    f"__subscribe {resolved}: {shared.untyped}. Subscribed without it: messages are passed on when "
                    f"their publisher says they are {command.message_name}"
                )))
            others = tuple(entry for entry in shared.clients if entry[0] is not session)
            shared.clients = others + ((session, command.topic, command.queue_size or 0),)
            self._clients[session].subscriptions[resolved] = command.topic
            self._guard_echoes(resolved)
        if created:
            self.ros.wait_registered("subscriber", resolved)

    def _check_room(self, session: ClientSession, command: str, resolved: str, registered: bool,
                    new_on_ros: bool) -> None:
        """Refuse a registration past the client's limit (unless it has this one already) or past the endpoint's
        (when it would make a new ROS object). Called with the lock held."""
        if not registered and self._clients[session].count() >= self.config.max_registrations_per_client:
            raise RequestRefused(
                f"{command} {resolved}: refused, this client has {self.config.max_registrations_per_client} "
                "registrations already, its limit (--max-registrations-per-client)"
            )
        if new_on_ros:
            bridged = len(self._subscribers) + len(self._publishers) + len(self._unity_services)
            if bridged >= self.config.max_registrations:
                raise RequestRefused(
                    f"{command} {resolved}: refused, the endpoint bridges {bridged} topics and services already, its "
                    "limit for all clients together (--max-registrations)"
                )

    def _unsubscribe(self, session: ClientSession, registrations: _Registrations, resolved: str) -> None:
        with self._lock:
            registrations.subscriptions.pop(resolved, None)
            shared = self._subscribers.get(resolved)
            if shared is None:
                return
            shared.clients = tuple(entry for entry in shared.clients if entry[0] is not session)
            if not shared.clients:
                del self._subscribers[resolved]
                end_topic(shared.handle)
            else:
                self._guard_echoes(resolved)

    def _register_publisher(self, session: ClientSession, command: Publish) -> None:
        resolved = self._checked_name(command.topic)
        # Outside the lock: the first look-up of a type reads files, and may ask the topic's publishers.
        raw = _made_for_client(lambda: self.ros.publisher_type(resolved, command.message_name))
        with self._lock:
            shared = self._publishers.get(resolved)
            if shared is not None and shared.message_name != command.message_name:
                if shared.clients:
                    raise RequestRefused(
                        f"__publish: topic {resolved} is already published as {shared.message_name}, "
                        f"not {command.message_name}"
                    )
                # Kept advertised after its clients left (see release), but nobody uses it: retype it.
                self._end_publisher(resolved)
                shared = None
            self._check_room(session, "__publish", resolved, command.topic in self._clients[session].publishers,
                             shared is None)
            created = shared is None
            if shared is None:
                publisher = _made_for_client(
                    lambda: self.ros.make_publisher(
                        resolved, raw, command.queue_size, command.latch,
                        self.config.client_queue_bytes,
                    )
                )
                shared = _SharedPublisher(command.message_name, publisher)
                self._publishers[resolved] = shared
            shared.clients.add(session)
            shared.unused_since = None
            self._clients[session].publishers[command.topic] = (resolved, shared.publisher)
            self._guard_echoes(resolved)
        if created:
            self.ros.wait_registered("publisher", resolved)

    def _unregister_publisher(self, session: ClientSession, registrations: _Registrations, client_topic: str,
                              keep_advertised: bool = False) -> None:
        with self._lock:
            entry = registrations.publishers.pop(client_topic, None)
            if entry is None:
                return
            shared = self._publishers.get(entry[0])
            if shared is None:
                return
            shared.clients.discard(session)
            if not shared.clients:
                if keep_advertised:
                    shared.unused_since = time.monotonic()
                else:
                    self._end_publisher(entry[0])
            self._guard_echoes(entry[0])

    def _end_unused_publishers(self) -> None:
        """Unadvertise the publishers no client has used for the grace period."""
        now = time.monotonic()
        with self._lock:
            for resolved, shared in list(self._publishers.items()):
                if not shared.clients and shared.unused_since is not None \
                        and now - shared.unused_since >= self.config.publisher_grace_s:
                    self._end_publisher(resolved)

    def _end_publisher(self, resolved: str) -> None:
        """Take the topic's publisher off the bridge and the graph. Called with the lock held."""
        self._publishers.pop(resolved).publisher.unregister()

    def _register_ros_service(self, session: ClientSession, command: RosService) -> None:
        resolved = self._checked_name(command.topic)
        raw = _made_for_client(lambda: self.ros.service_type(command.message_name))
        proxy = self.ros.make_service_proxy(resolved, raw, self.config.max_payload_bytes)
        with self._lock:
            registrations = self._clients[session]
            # A proxy holds no ROS object: it counts for the client only.
            self._check_room(session, "__ros_service", resolved, command.topic in registrations.ros_services, False)
            registrations.ros_services[command.topic] = proxy

    def _register_unity_service(self, session: ClientSession, command: UnityService) -> None:
        resolved = self._checked_name(command.topic)
        raw = _made_for_client(lambda: self.ros.service_type(command.message_name))
        with self._lock:
            existing = self._unity_services.get(resolved)
            if existing is not None and existing.message_name == command.message_name:
                # Re-registration (typically a reconnect): the newest client answers from now on.
                self._check_room(session, "__unity_service", resolved,
                                 resolved in self._clients[session].unity_services, False)
                previous = self._clients.get(existing.owner)
                if previous is not None:
                    previous.unity_services.discard(resolved)
                existing.owner = session
                existing.client_name = command.topic
                self._clients[session].unity_services.add(resolved)
                return
            if existing is not None:
                raise RequestRefused(
                    f"__unity_service: service {resolved} is already provided as {existing.message_name}, "
                    f"not {command.message_name}"
                )
            self._check_room(session, "__unity_service", resolved, False, True)
            handle = _made_for_client(
                lambda: self.ros.make_service(
                    resolved, raw, lambda request: self._call_unity_service(resolved, request)
                )
            )
            self._unity_services[resolved] = _UnityService(command.message_name, handle, session, command.topic)
            self._clients[session].unity_services.add(resolved)
        self.ros.wait_registered("service", resolved)

    def _unregister_unity_service(self, session: ClientSession, registrations: _Registrations,
                                  resolved: str) -> None:
        with self._lock:
            registrations.unity_services.discard(resolved)
            service = self._unity_services.get(resolved)
            if service is None or service.owner is not session:
                return
            del self._unity_services[resolved]
            service.handle.shutdown("client removed the service")

    def _guard_echoes(self, resolved: str) -> None:
        """Keep an echo record for exactly the clients that both publish and subscribe on the topic (none when clients
        are configured to get their own messages back). Called with the lock held."""
        subscribed = self._subscribers.get(resolved)
        if subscribed is None or self.config.echo_own_publications:
            return
        published = self._publishers.get(resolved)
        publishing = published.clients if published is not None else set()
        with subscribed.echoes_lock:
            subscribed.echoes = {
                session: subscribed.echoes.get(session) or deque(maxlen=ECHO_RECORD_MAX)
                for session, _, _ in subscribed.clients if session in publishing
            }

    def _remove(self, session: ClientSession, command: Remove) -> None:
        registrations = self._clients[session]
        if command.kind == "subscriber":
            self._unsubscribe(session, registrations, self.ros.resolve(command.topic))
        elif command.kind == "publisher":
            self._unregister_publisher(session, registrations, command.topic)
        elif command.kind == "ros_service":
            registrations.ros_services.pop(command.topic, None)
        else:
            self._unregister_unity_service(session, registrations, self.ros.resolve(command.topic))

    # --- data paths -------------------------------------------------------------------------------------------
    def _fan_out(self, resolved: str, payload: bytes, header: Dict[str, str]) -> None:
        """rospy callback: one received message to every client subscribed to the topic, bytes untouched; a client's
        own message, come back through our publisher, skips that client (see _SharedSubscriber.echoes)."""
        shared = self._subscribers.get(resolved)
        if shared is None:
            return
        shared.delivered += 1
        sender = None
        if shared.echoes and header.get("callerid") == self._node_name:
            with shared.echoes_lock:
                sender = _take_echo(shared.echoes, payload)
        frames: Dict[str, bytes] = {}
        # A client behind on the topic gets its newest message only, not a backlog of stale ones, where the settings
        # say so (EndpointConfig.latest_only_*); its own queue_size for the topic, if it gave one, wins.
        default_limit = 1 if len(payload) >= self._latest_only_bytes or shared.latest_only else 0
        for session, client_topic, queue_size in shared.clients:
            if session is sender:
                continue
            frame = frames.get(client_topic)
            if frame is None:
                frame = frames[client_topic] = protocol.encode_frame(client_topic, payload)
            # droppable; at most queue_size of the topic wait
            session.send(frame, True, resolved, queue_size or default_limit)

    def _call_ros_service(self, session: ClientSession, request: ServiceRequest) -> None:
        srv_id = request.srv_id
        proxy = self._clients[session].ros_services.get(request.service)
        if proxy is None:
            raise RequestRefused(
                f"__request {srv_id}: service {request.service!r} was not registered with __ros_service; "
                "this call will not complete", srv_id,
            )
        if self.config.validate_payloads:
            try:
                self.ros.types.validate_service(proxy.service_name, "request", request.payload)
            except RosError as error:
                raise RequestRefused(
                    f"__request {srv_id}: service {request.service}: {error}; not sent to ROS, this call will not "
                    "complete", srv_id,
                ) from None
        timeout = self.config.service_timeout_s

        def call() -> None:
            try:
                response = proxy.call(request.payload, timeout, session.gone)
            except RosError as error:
                session.send_error(f"__request {srv_id}: {error}; this call will not complete", srv_id)
                return
            session.send(protocol.encode(ServiceResponse(srv_id, request.service, response)), droppable=False)

        session.run_call(f"__request {srv_id} ({request.service})", call, srv_id)

    def _answer_ping(self, session: ClientSession, ping: Ping) -> None:
        ros_time = self.ros.now()
        client_time = parse_client_time(ping.request_time)
        session.note_ping(ping.round_trip, None if client_time is None else ros_time - client_time)
        session.send(protocol.encode(PingResponse(ping.request_time, ros_time)), droppable=False)

    # --- housekeeping: unused publishers, /diagnostics, memory ---------------------------------------------------
    def _housekeeping_loop(self) -> None:
        """Once a second: unused publishers end, /diagnostics goes out, and free memory is given back when traffic
        has gone quiet (bridge.memory)."""
        counts: Dict[str, Tuple[int, int]] = {}
        trim = QuietTrim()
        while not self._stopping.wait(DIAGNOSTICS_PERIOD_S):
            try:
                self._end_unused_publishers()
            except Exception:
                log.exception("ending unused publishers failed")
            if trim.due(self.bytes_moved()):
                give_back_free_memory()
            try:
                clients, topics = self._snapshot()
                statuses, counts = report(self.ros.node_name(), self._address, time.time(), clients, topics,
                                          counts, DIAGNOSTICS_PERIOD_S)
                self.ros.publish_diagnostics(statuses)
            except Exception:  # diagnostics must never take the endpoint down
                log.exception("publishing /diagnostics failed")

    def _snapshot(self) -> Tuple[List[ClientSnapshot], List[TopicSnapshot]]:
        with self._lock:
            sessions = list(self._clients)
            subscribers = dict(self._subscribers)
            publishers = dict(self._publishers)
        clients = [
            ClientSnapshot(
                s.name, s.connected_at, s.authenticated, s.frames_in, s.frames_out, s.bytes_in, s.bytes_out,
                len(s.queue), s.queue.max_frames, s.queue.oldest_age(), s.dropped, s.publish_drops, s.pings,
                s.ping_clock_offset_s, s.ping_round_trip_s,
            )
            for s in sessions
        ]
        waits: Dict[str, float] = {}
        for session in sessions:
            for topic, wait in session.queue.longest_waits().items():
                waits[topic] = max(wait, waits.get(topic, 0.0))
        topics = []
        for topic in sorted(set(subscribers) | set(publishers)):
            subscribed, published = subscribers.get(topic), publishers.get(topic)
            message_name = subscribed.message_name if subscribed is not None else published.message_name \
                if published is not None else ""
            topics.append(TopicSnapshot(
                topic, message_name,
                len(subscribed.clients) if subscribed else 0, len(published.clients) if published else 0,
                subscribed.delivered if subscribed else 0, published.publisher.published if published else 0,
                subscribed.handle.get_num_connections() if subscribed else 0,
                published.publisher.connections() if published else 0,
                waits.get(topic),
            ))
        return clients, topics

    def _send_topic_list(self, session: ClientSession, query: TopicListQuery) -> None:
        def look_up() -> None:
            try:
                topics, types = self.ros.topic_types()
            except OSError as error:
                session.send_error(f"__topic_list: the ROS master did not answer: {error}")
                return
            session.send(protocol.encode(TopicList(tuple(topics), tuple(types))), droppable=False)

        session.run_lookup("__topic_list", look_up)

    def _call_unity_service(self, resolved: str, request: bytes) -> bytes:
        """rospy service thread: forward a ROS request to the owning client and wait for its __response."""
        with self._lock:
            service = self._unity_services.get(resolved)
            if service is None:
                raise RosError(f"service {resolved} has no client any more")
            if service.owner.queue.kept_bytes > self.config.client_queue_bytes:
                raise RosError(f"the client providing {resolved} does not read what it is sent")
            srv_id = next(self._unity_srv_ids)
            call = _PendingUnityCall(service.owner, service.message_name)
            self._pending_unity_calls[srv_id] = call
            client_name = service.client_name
        call.owner.send(protocol.encode(ServiceRequest(srv_id, client_name, request)), droppable=False)
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

    def _complete_unity_call(self, session: ClientSession, response: ServiceResponse) -> None:
        srv_id = response.srv_id
        with self._lock:
            call = self._pending_unity_calls.get(srv_id)
        if call is None or call.owner is not session:
            raise RequestRefused(
                f"__response: unknown srv_id {srv_id} (never requested from this client, or timed out); "
                "response discarded", srv_id,
            )
        if self.config.validate_payloads:
            try:
                self.ros.types.validate_service(call.service_name, "response", response.payload)
            except RosError as error:
                # The ROS caller hears at once instead of getting bytes it cannot read (or waiting for a timeout).
                call.failure = f"client {session.name} answered with an invalid response: {error}"
                call.done.set()
                raise RequestRefused(
                    f"__response {srv_id}: service {response.service}: {error}; the ROS call fails", srv_id
                ) from None
        call.response = response.payload
        call.done.set()


def _turn_away(sock: socket.socket, reason: str) -> None:
    """Tell a client that cannot be served why (an __error, in place of the handshake), and close."""
    try:
        send_now(sock, protocol.encode(protocol.Error(f"connection refused: {reason}")))
    except OSError:
        pass
    sock.close()


def _take_echo(echoes: Dict[ClientSession, Deque[bytes]], payload: bytes) -> Optional[ClientSession]:
    """The client that published `payload`, now come back from ROS through our own publisher, and its record up to
    that message taken. A client's messages come back in its order, so its next one is at the front of its record;
    one found further in means those before it never came back (dropped before ROS): they go too."""
    for session, published in echoes.items():
        if published and published[0] == payload:
            published.popleft()
            return session
    for session, published in echoes.items():
        for index, earlier in enumerate(published):
            if earlier == payload:
                for _ in range(index + 1):
                    published.popleft()
                return session
    return None


def _made_for_client(make: Callable[[], _Made]) -> _Made:
    """A ROS object made for a client's request; a ROS-side failure is that request's refusal."""
    try:
        return make()
    except RosError as error:
        raise RequestRefused(str(error)) from None
