"""The endpoint's TCP server: accepts clients as its gate lets them in (bridge.admission.gate), starts their sessions
(bridge.connection.session, bridge.connection.web_session) and dispatches what they ask to the topic and service
tables (bridge.topics, bridge.services), which it owns; housekeeping once a second. With a WebSocket port, a second
listener admits WebSocket clients (browsers, Unity WebGL builds) to the same tables, under the same rules.

Threads: one accept thread per listener; per client a reader (frames in), a writer (drains the client's bounded
queue when a direct send could not write everything, see SessionOutput.send) and a few workers for its ROS service
calls and topic-list look-ups (so a slow service never stalls a reader, nor another client's calls); per published
topic a pump thread (bridge.ros.publisher.RawPublisher); rospy's own threads deliver ROS messages, which are fanned
out to the subscribed clients (bridge.topics.Topics.fan_out); one housekeeping thread.

Long because the endpoint owns what its clients share: accepting, the sessions' registry, the dispatch and the
housekeeping all read the one set of tables under their one lock (bridge.bridged).
"""

from __future__ import annotations

import itertools
import logging
import socket
import threading
import time
from typing import TYPE_CHECKING, Any, Callable

from bridge import protocol
from bridge.admission.auth import AuthGuard
from bridge.admission.gate import Gate
from bridge.admission.throttle import LogThrottle
from bridge.bridged import Bridged, ClientRegistrations
from bridge.config import EndpointConfig
from bridge.connection.calls import CallRoom
from bridge.connection.queues import ByteBudget
from bridge.connection.session import CLOSE_TIMEOUT_S, ClientSession
from bridge.connection.sockets import send_now, tune_socket
from bridge.connection.web_session import WebSocketSession
from bridge.diagnostics import ClientSnapshot, TopicSnapshot, parse_client_time, report
from bridge.errors import RequestRefused
from bridge.memory import QuietTrim, give_back_free_memory
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
    UnityService,
)
from bridge.ros.graph import RosGraph
from bridge.ros.peer_links import PEER_CHECK_S, PEER_CHECK_SHARE, PeerWatch, problem_line, problem_statuses
from bridge.services import Services
from bridge.topics import Topics

if TYPE_CHECKING:  # wsproto is optional: bridge.protocol.websocket is imported only for WebSocket clients
    from bridge.protocol.websocket import UpgradeRequest

__all__ = ["Endpoint"]

log = logging.getLogger(__name__)
DIAGNOSTICS_PERIOD_S = 1.0  # /diagnostics at 1 Hz, as ROS's diagnostic tools expect
PEER_PROBES_PER_CHECK = 2  # links found down described per check (each may wait bridge.ros.peers.PROBE_S)


# Requests whose answer the client must read (it is never dropped), and how they are named in a refusal
_ANSWERED: dict[type, str] = {TopicListQuery: "__topic_list", Ping: "__ping", ServiceRequest: "__request"}


class Endpoint:
    """The ROS-TCP endpoint: accepts clients and connects them to the ROS graph (the owner of every session)."""

    def __init__(self, ros: RosGraph, config: EndpointConfig) -> None:
        self.ros = ros
        self.config = config
        self._bridged = Bridged(ros, config, self._check_room)
        self._lock = self._bridged.lock
        self._clients = self._bridged.clients
        self.topics = Topics(self._bridged)
        self.services = Services(self._bridged)
        # The session's fast path for topic messages goes straight to the topics.
        self.publisher_for = self.topics.publisher_for
        self._client_ids = itertools.count(1)
        self._listeners: list[socket.socket] = []
        self._accept_threads: list[threading.Thread] = []
        self.websocket_port: int | None = None  # where WebSocket clients are served, once started
        self._housekeeping_thread: threading.Thread | None = None
        self._address = ""
        self._stopping = threading.Event()
        self._auth = AuthGuard(config.auth_token) if config.auth_token is not None else None
        self._partial_frames = ByteBudget(config.max_partial_frame_bytes)
        # room to borrow (bridge.connection.calls)
        self.call_room = CallRoom(config.max_clients * config.client_call_workers)
        self._accept_failures = LogThrottle(log)
        self._gate = Gate(config, self._clients, self._lock)
        # Totals of the clients that have left (those still connected are summed in stats()).
        self.frames_in = 0
        self.frames_out = 0
        self.dropped = 0
        self.bytes_in_out = 0
        # What each client event does; topic messages take publisher_for, the session's fast path.
        self._handlers: dict[type, Callable[[ClientSession, Any], None]] = {
            Subscribe: self.topics.subscribe,
            Publish: self.topics.register_publisher,
            RosService: self.services.register_ros_service,
            UnityService: self.services.register_client_service,
            Remove: self._remove,
            ServiceRequest: self.services.call_ros_service,
            ServiceResponse: self.services.complete_client_call,
            TopicListQuery: self._send_topic_list,
            Ping: self._answer_ping,
            Auth: lambda session, event: None,  # already authenticated (or auth is off): harmless
        }

    # --- lifecycle ------------------------------------------------------------------------------------------
    def start(self) -> int:
        """Bind and start accepting; returns the actual TCP port (useful with tcp_port 0). With a websocket_port,
        WebSocket clients are accepted too (self.websocket_port says where). Both are bound before either accepts:
        an OSError (the port is taken) leaves nothing running."""
        listener = _listen(self.config.tcp_ip, self.config.tcp_port)
        websocket_listener = None
        if self.config.websocket_port is not None:
            try:
                websocket_listener = _listen(self.config.tcp_ip, self.config.websocket_port)
            except OSError:
                listener.close()
                raise
        self._listeners = [listener]
        self._start_accepting(listener, websocket=False)
        port: int = listener.getsockname()[1]
        self._address = f"{self.config.tcp_ip}:{port}"
        if websocket_listener is not None:
            self._listeners.append(websocket_listener)
            self._start_accepting(websocket_listener, websocket=True)
            self.websocket_port = websocket_listener.getsockname()[1]
        self._housekeeping_thread = threading.Thread(target=self._housekeeping_loop, name="housekeeping", daemon=True)
        self._housekeeping_thread.start()
        log.info("ROS-TCP endpoint listening on %s:%d", self.config.tcp_ip, port)
        if self.websocket_port is not None:
            log.info("WebSocket clients served on %s:%d", self.config.tcp_ip, self.websocket_port)
        return port

    def _start_accepting(self, listener: socket.socket, websocket: bool) -> None:
        name = "accept websocket" if websocket else "accept"
        thread = threading.Thread(target=self._accept_loop, args=(listener, websocket), name=name, daemon=True)
        self._accept_threads.append(thread)
        thread.start()

    def stop(self) -> None:
        self._stopping.set()
        for listener in self._listeners:
            # shutdown() wakes the blocked accept(); close() alone does not on Linux.
            try:
                listener.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            listener.close()
        with self._lock:
            sessions = list(self._clients)
        self.services.fail_waiting_calls("the endpoint is shutting down")  # their ROS callers hear at once
        for session in sessions:
            session.close("the endpoint is shutting down", tell_client=True)
        deadline = time.monotonic() + CLOSE_TIMEOUT_S  # WebSocket clients answer the close (the handshake)
        for session in sessions:
            session.wait_closed(max(0.0, deadline - time.monotonic()))
        for thread in self._accept_threads:
            thread.join(timeout=2)
        if self._housekeeping_thread is not None:
            self._housekeeping_thread.join(timeout=2)
        log.info("endpoint stopped: %s", self.stats())

    def bytes_moved(self) -> int:
        """Bytes received from and sent to clients since the start, all clients together."""
        with self._lock:
            sessions = list(self._clients)
        return self.bytes_in_out + sum(s.bytes_in + s.bytes_out for s in sessions)

    def stats(self) -> dict[str, int]:
        with self._lock:
            sessions = list(self._clients)
        return {
            "clients": len(sessions),
            "frames_in": self.frames_in + sum(s.frames_in for s in sessions),
            "frames_out": self.frames_out + sum(s.frames_out for s in sessions),
            "dropped": self.dropped + sum(s.dropped for s in sessions),
        }

    def _accept_loop(self, listener: socket.socket, websocket: bool) -> None:
        while not self._stopping.is_set():
            try:
                sock, address = listener.accept()
            except OSError as error:
                if self._stopping.is_set():
                    return
                self._accept_failures.warning("accepting a connection failed: %s", error)  # e.g. no descriptors left
                time.sleep(0.1)
                continue
            # A trusted proxy's clients are counted by their own address once their upgrade request says it
            behind_proxy = websocket and self._gate.behind_proxy(address[0])
            refusal = self._gate.refusal(address[0], per_address=not behind_proxy)
            if refusal is not None:
                _turn_away(sock, refusal, websocket)
                self._gate.turn_away(f"{address[0]}:{address[1]}", refusal)
                continue
            session: ClientSession | None = None
            try:
                tune_socket(sock, self.config.dead_peer_timeout_s)
                session = (WebSocketSession if websocket else ClientSession)(
                    self, self.config, sock, address, next(self._client_ids), self._auth, self._partial_frames
                )
                with self._lock:
                    self._clients[session] = ClientRegistrations()
                session.start()
            except Exception:  # e.g. no thread to be had: this client goes, the endpoint keeps accepting others
                log.exception("could not serve the client at %s:%d", *address[:2])
                if session is not None:
                    self.release(session)
                    session.close()
                sock.close()

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
                    f"{_ANSWERED[type(event)]}: refused, {unread} bytes of earlier answers wait unread by this client",
                    srv_id,
                )
        handler(session, event)

    def upgrade_refusal(self, session: WebSocketSession, request: UpgradeRequest) -> tuple[str, str] | None:
        """A WebSocket client's upgrade request, as the gate decides it (bridge.admission.gate)."""
        return self._gate.upgrade_refusal(session, request)

    def release(self, session: ClientSession) -> None:
        """Undo everything a departing client registered; fail its pending service calls."""
        with self._lock:
            registrations = self._clients.pop(session, None)
            if registrations is None:
                return
            if session.missed_deadline:
                self._gate.misused_slot(session.host)
            self.topics.release(session, registrations)
            self.services.release(session, registrations)
            self.frames_in += session.frames_in
            self.frames_out += session.frames_out
            self.dropped += session.dropped
            self.bytes_in_out += session.bytes_in + session.bytes_out

    # --- registrations: the room check the tables share, and removal ----------------------------------------
    def _check_room(
        self, session: ClientSession, command: str, resolved: str, registered: bool, new_on_ros: bool
    ) -> None:
        """Refuse a registration past the client's limit (unless it has this one already) or past the endpoint's
        (when it would make a new ROS object). Called with the lock held."""
        if not registered and self._clients[session].count() >= self.config.max_registrations_per_client:
            raise RequestRefused(
                f"{command} {resolved}: refused, this client has {self.config.max_registrations_per_client} "
                "registrations already, its limit (--max-registrations-per-client)"
            )
        if new_on_ros:
            bridged = self.topics.count() + self.services.count()
            if bridged >= self.config.max_registrations:
                raise RequestRefused(
                    f"{command} {resolved}: refused, the endpoint bridges {bridged} topics and services already, its "
                    "limit for all clients together (--max-registrations)"
                )

    def _remove(self, session: ClientSession, command: Remove) -> None:
        registrations = self._clients[session]
        if command.kind == "subscriber":
            self.topics.unsubscribe(session, registrations, self.ros.resolve(command.topic))
        elif command.kind == "publisher":
            self.topics.unregister_publisher(session, registrations, command.topic)
        elif command.kind == "ros_service":
            registrations.ros_services.pop(command.topic, None)
        else:
            self.services.unregister_client_service(session, registrations, self.ros.resolve(command.topic))

    # --- answers from the endpoint itself -----------------------------------------------------------------------
    def _answer_ping(self, session: ClientSession, ping: Ping) -> None:
        ros_time = self.ros.now()
        client_time = parse_client_time(ping.request_time)
        session.note_ping(ping.round_trip, None if client_time is None else ros_time - client_time)
        session.send(protocol.encode(PingResponse(ping.request_time, ros_time)), droppable=False)

    # --- housekeeping: unused publishers, links to ROS peers, /diagnostics, memory ---------------------------------
    def _housekeeping_loop(self) -> None:
        """Once a second: unused publishers end, /diagnostics goes out, and free memory is given back when traffic
        has gone quiet (bridge.memory); every PEER_CHECK_S (longer on a large graph), the links to ROS peers are
        checked."""
        counts: dict[str, tuple[int, int]] = {}
        trim = QuietTrim()
        peers, next_peer_check = PeerWatch(), time.monotonic() + PEER_CHECK_S
        while not self._stopping.wait(DIAGNOSTICS_PERIOD_S):
            try:
                self.topics.end_unused_publishers()
            except Exception:
                log.exception("ending unused publishers failed")
            if trim.due(self.bytes_moved()):
                give_back_free_memory()
            if time.monotonic() >= next_peer_check:
                started = time.monotonic()
                next_peer_check = started + PEER_CHECK_S
                try:
                    self._check_peer_links(peers)
                    took = time.monotonic() - started
                    next_peer_check = max(next_peer_check, started + took / PEER_CHECK_SHARE)
                except OSError as error:  # the master did not answer: its link says so (bridge.ros.master)
                    log.debug("links to ROS peers not checked: %s", error)
                except Exception:
                    log.exception("checking the links to ROS peers failed")
            try:
                clients, topics = self._snapshot()
                statuses, counts = report(
                    self.ros.node_name(),
                    self._address,
                    time.time(),
                    clients,
                    topics,
                    counts,
                    DIAGNOSTICS_PERIOD_S,
                    self._gate.refused_origins if self.config.websocket_port is not None else None,
                )
                self.ros.publish_diagnostics(statuses + problem_statuses(self.ros.node_name(), peers.problems))
            except Exception:  # diagnostics must never take the endpoint down
                log.exception("publishing /diagnostics failed")

    def _check_peer_links(self, peers: PeerWatch) -> None:
        """Links of bridged topics the master lists and rospy does not hold up (bridge.ros.peer_links): each client
        bridging the topic that way is told once, in an __error."""
        with self._lock:
            publishing = {topic: tuple(shared.clients) for topic, shared in self.topics.publishers.items()}
            subscribing = {
                topic: tuple(e[0] for e in shared.clients) for topic, shared in self.topics.subscribers.items()
            }
        listed, up = self.ros.peer_links(publishing, subscribing) if publishing or subscribing else (set(), set())
        for link, down_s in peers.observe(time.monotonic(), listed, up)[:PEER_PROBES_PER_CHECK]:
            problem = self.ros.describe_peer(link, down_s)
            peers.found(problem)
            log.warning("%s", problem_line(problem))
        for session, line in peers.to_tell(publishing, subscribing):
            session.send_error(line)

    def _snapshot(self) -> tuple[list[ClientSnapshot], list[TopicSnapshot]]:
        with self._lock:
            sessions = list(self._clients)
            subscribers = dict(self.topics.subscribers)
            publishers = dict(self.topics.publishers)
        clients = [
            ClientSnapshot(
                s.name,
                s.connected_at,
                s.authenticated,
                s.frames_in,
                s.frames_out,
                s.bytes_in,
                s.bytes_out,
                len(s.queue),
                s.queue.max_frames,
                s.queue.oldest_age(),
                s.dropped,
                s.publish_drops,
                s.pings,
                s.ping_clock_offset_s,
                s.ping_round_trip_s,
            )
            for s in sessions
        ]
        waits: dict[str, float] = {}
        for session in sessions:
            for topic, wait in session.queue.longest_waits().items():
                waits[topic] = max(wait, waits.get(topic, 0.0))
        topics = []
        for topic in sorted(set(subscribers) | set(publishers)):
            subscribed, published = subscribers.get(topic), publishers.get(topic)
            message_name = (
                subscribed.message_name
                if subscribed is not None
                else published.message_name
                if published is not None
                else ""
            )
            topics.append(
                TopicSnapshot(
                    topic,
                    message_name,
                    len(subscribed.clients) if subscribed else 0,
                    len(published.clients) if published else 0,
                    subscribed.delivered if subscribed else 0,
                    published.publisher.published if published else 0,
                    subscribed.handle.get_num_connections() if subscribed else 0,
                    published.publisher.connections() if published else 0,
                    waits.get(topic),
                )
            )
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


def _listen(host: str, port: int) -> socket.socket:
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        listener.bind((host, port))
        listener.listen(64)
    except OSError:
        listener.close()
        raise
    return listener


def _turn_away(sock: socket.socket, reason: str, websocket: bool) -> None:
    """Tell a client that cannot be served why (an __error in place of the handshake; a WebSocket client, an HTTP
    503 in place of the upgrade's answer, sent without waiting for its request), and close."""
    if websocket:
        from bridge.protocol.websocket import refusal_response

        refusal = refusal_response(f"connection refused: {reason}")
    else:
        refusal = protocol.encode(protocol.Error(f"connection refused: {reason}"))
    try:
        send_now(sock, refusal)
    except OSError:
        pass
    sock.close()
