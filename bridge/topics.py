"""The endpoint's topics: one rospy subscriber per topic fanned out to every subscribed client, one publisher per
topic fed by every publishing client, and the EchoFilter that keeps a client's own messages from coming back to it.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Iterable, Tuple

from bridge import protocol
from bridge.bridged import Bridged, ClientRegistrations, made_for_client
from bridge.connection.session import ClientSession
from bridge.errors import RequestRefused
from bridge.protocol import Publish, Subscribe, TopicMessage, Warn
from bridge.ros.publisher import RawPublisher, end_topic

__all__ = ["ECHO_RECORD_MAX", "EchoFilter", "SharedSubscriber", "SharedPublisher", "Topics"]

# Client messages remembered per topic until they come back from ROS (see EchoFilter)
ECHO_RECORD_MAX = 4096

# One client's subscription to a topic: (its session, the topic as it spells it, its queue depth for the topic: at
# most that many of the topic's frames wait for it; 0 = only the client's own bound). A plain tuple: the fan-out
# unpacks it for every message and client, where attribute lookups cost a tenth of the work.
_Subscription = Tuple[ClientSession, str, int]


class EchoFilter:
    """Which client a message that came back from ROS through the endpoint's own publisher was from, so that it
    skips that client (unless clients are configured to get their own messages back).

    Kept for the clients that both publish and subscribe on one topic: what each published, in its order. Each
    client's messages reach ROS in the order it sent them; different clients' messages interleave in any order.
    Client readers record, rospy's thread takes; `records` is replaced whole on change, so a reader may test it
    without the lock."""

    __slots__ = ("records", "_lock")

    def __init__(self) -> None:
        self.records: dict[Any, deque[bytes]] = {}
        self._lock = threading.Lock()

    def keep_for(self, clients: Iterable[Any]) -> None:
        """Keep records for exactly `clients` (their records so far kept, the others' dropped)."""
        with self._lock:
            self.records = {client: self.records.get(client) or deque(maxlen=ECHO_RECORD_MAX) for client in clients}

    def record(self, client: Any, payload: bytes) -> None:
        """`client` published `payload` (nothing when it has no record: it does not subscribe to the topic)."""
        own = self.records.get(client)
        if own is not None:
            with self._lock:
                own.append(payload)

    def take(self, payload: bytes) -> Any | None:
        """The client that published `payload`, now come back from ROS, and its record up to that message taken.
        A client's messages come back in its order, so its next one is at the front of its record; one found further
        in means those before it never came back (dropped before ROS): they go too. None when no client recorded it
        (another node of ours published it)."""
        with self._lock:
            for client, published in self.records.items():
                if published and published[0] == payload:
                    published.popleft()
                    return client
            for client, published in self.records.items():
                for index, earlier in enumerate(published):
                    if earlier == payload:
                        for _ in range(index + 1):
                            published.popleft()
                        return client
        return None


@dataclass
class SharedSubscriber:
    message_name: str
    handle: Any
    # replaced whole, never changed in place, so rospy callbacks read it without a lock
    clients: tuple[_Subscription, ...] = ()
    untyped: str | None = None  # why there is no class of the type, when there is none
    latest_only: bool = False  # a client behind gets only the newest message (EndpointConfig.latest_only)
    # messages from ROS fanned out (for /diagnostics), counted under its lock: rospy reads each publisher's
    # connection on a thread of its own, so two publishers of the topic count at once
    delivered: int = 0
    delivered_lock: threading.Lock = field(default_factory=threading.Lock)
    echoes: EchoFilter = field(default_factory=EchoFilter)


@dataclass
class SharedPublisher:
    message_name: str
    publisher: RawPublisher
    clients: set[ClientSession] = field(default_factory=set)
    unused_since: float | None = None  # monotonic time its last client left (see Topics.release)


class Topics:
    """Every bridged topic, both ways. Registrations run on the clients' reader threads under the shared lock; the
    data paths (publisher_for, fan_out) take no lock."""

    def __init__(self, bridged: Bridged) -> None:
        self._bridged = bridged
        self._ros = bridged.ros
        self._config = bridged.config
        self._lock = bridged.lock
        self._clients = bridged.clients
        self._node_name = bridged.ros.node_name()
        # messages at least this large go to a client that is behind only as the newest (0 in the settings: never)
        self._latest_only_bytes = bridged.config.latest_only_bytes or float("inf")
        self.subscribers: dict[str, SharedSubscriber] = {}
        self.publishers: dict[str, SharedPublisher] = {}

    def count(self) -> int:
        """ROS objects the topics hold: subscribers and publishers."""
        return len(self.subscribers) + len(self.publishers)

    # --- subscribing ------------------------------------------------------------------------------------------
    def subscribe(self, session: ClientSession, command: Subscribe) -> None:
        resolved = self._bridged.permitted(command.topic)
        raw, untyped = self._ros.subscriber_type(command.message_name)  # outside the lock: may read files
        with self._lock:
            shared = self.subscribers.get(resolved)
            if shared is not None and shared.message_name != command.message_name:
                raise RequestRefused(
                    f"__subscribe: topic {resolved} is already bridged as {shared.message_name}, "
                    f"not {command.message_name}"
                )
            self._bridged.room(
                session, "__subscribe", resolved, resolved in self._clients[session].subscriptions, shared is None
            )
            created = shared is None
            if shared is None:
                handle = made_for_client(
                    lambda: self._ros.make_subscriber(resolved, raw, command.message_name, self.fan_out)
                )
                shared = SharedSubscriber(
                    command.message_name, handle, untyped=untyped, latest_only=self._config.latest_only(resolved)
                )
                self.subscribers[resolved] = shared
            if shared.untyped is not None:
                session.send(
                    protocol.encode(
                        Warn(
                            f"__subscribe {resolved}: {shared.untyped}. Subscribed without it: messages are passed on "
                            "when "
                            f"their publisher says they are {command.message_name}"
                        )
                    )
                )
            others = tuple(entry for entry in shared.clients if entry[0] is not session)
            shared.clients = others + ((session, command.topic, command.queue_size or 0),)
            self._clients[session].subscriptions[resolved] = command.topic
            self._filter_echoes(resolved)
        if created:
            self._ros.wait_registered("subscriber", resolved)

    def unsubscribe(self, session: ClientSession, registrations: ClientRegistrations, resolved: str) -> None:
        with self._lock:
            registrations.subscriptions.pop(resolved, None)
            shared = self.subscribers.get(resolved)
            if shared is None:
                return
            shared.clients = tuple(entry for entry in shared.clients if entry[0] is not session)
            if not shared.clients:
                del self.subscribers[resolved]
                end_topic(shared.handle)
            else:
                self._filter_echoes(resolved)

    # --- publishing -------------------------------------------------------------------------------------------
    def register_publisher(self, session: ClientSession, command: Publish) -> None:
        resolved = self._bridged.permitted(command.topic)
        # Outside the lock: the first look-up of a type reads files, and may ask the topic's publishers.
        raw = made_for_client(lambda: self._ros.publisher_type(resolved, command.message_name))
        with self._lock:
            shared = self.publishers.get(resolved)
            if shared is not None and shared.message_name != command.message_name:
                if shared.clients:
                    raise RequestRefused(
                        f"__publish: topic {resolved} is already published as {shared.message_name}, "
                        f"not {command.message_name}"
                    )
                # Kept advertised after its clients left (see release), but nobody uses it: retype it.
                self._end_publisher(resolved)
                shared = None
            self._bridged.room(
                session, "__publish", resolved, command.topic in self._clients[session].publishers, shared is None
            )
            created = shared is None
            if shared is None:
                publisher = made_for_client(
                    lambda: self._ros.make_publisher(
                        resolved,
                        raw,
                        command.queue_size,
                        command.latch,
                        self._config.client_queue_bytes,
                    )
                )
                shared = SharedPublisher(command.message_name, publisher)
                self.publishers[resolved] = shared
            shared.clients.add(session)
            shared.unused_since = None
            self._clients[session].publishers[command.topic] = (resolved, shared.publisher)
            self._filter_echoes(resolved)
        if created:
            self._ros.wait_registered("publisher", resolved)

    def unregister_publisher(
        self,
        session: ClientSession,
        registrations: ClientRegistrations,
        client_topic: str,
        keep_advertised: bool = False,
    ) -> None:
        with self._lock:
            entry = registrations.publishers.pop(client_topic, None)
            if entry is None:
                return
            shared = self.publishers.get(entry[0])
            if shared is None:
                return
            shared.clients.discard(session)
            if not shared.clients:
                if keep_advertised:
                    shared.unused_since = time.monotonic()
                else:
                    self._end_publisher(entry[0])
            self._filter_echoes(entry[0])

    def end_unused_publishers(self) -> None:
        """Unadvertise the publishers no client has used for the grace period."""
        now = time.monotonic()
        with self._lock:
            for resolved, shared in list(self.publishers.items()):
                if (
                    not shared.clients
                    and shared.unused_since is not None
                    and now - shared.unused_since >= self._config.publisher_grace_s
                ):
                    self._end_publisher(resolved)

    def _end_publisher(self, resolved: str) -> None:
        """Take the topic's publisher off the bridge and the graph. Called with the lock held."""
        self.publishers.pop(resolved).publisher.unregister()

    def release(self, session: ClientSession, registrations: ClientRegistrations) -> None:
        """A departing client's subscriptions end. Its publishers stay advertised for config.publisher_grace_s after
        their last client left (rosbridge's unregister_timeout): a client that reconnects re-registers them, and
        re-advertising a topic from the same node races rospy's subscriber reconnect logic, so ROS subscribers
        would miss the first messages after every reconnect. Then they go (end_unused_publishers);
        __remove_publisher unadvertises at once."""
        with self._lock:
            for resolved in list(registrations.subscriptions):
                self.unsubscribe(session, registrations, resolved)
            for client_topic in list(registrations.publishers):
                self.unregister_publisher(session, registrations, client_topic, keep_advertised=True)

    def _filter_echoes(self, resolved: str) -> None:
        """Keep echo records for exactly the clients that both publish and subscribe on the topic (none when clients
        are configured to get their own messages back). Called with the lock held."""
        subscribed = self.subscribers.get(resolved)
        if subscribed is None or self._config.echo_own_publications:
            return
        published = self.publishers.get(resolved)
        publishing = published.clients if published is not None else set()
        subscribed.echoes.keep_for(session for session, _, _ in subscribed.clients if session in publishing)

    # --- data paths -------------------------------------------------------------------------------------------
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
        problem = self._bridged.payload_problem(publisher.message_name, message.payload)
        if problem is not None:
            raise RequestRefused(f"topic {resolved}: {problem}; message not published")
        subscribed = self.subscribers.get(resolved)
        if subscribed is not None and subscribed.echoes.records:
            subscribed.echoes.record(session, message.payload)
        return publisher

    def fan_out(self, resolved: str, payload: bytes, header: dict[str, str]) -> None:
        """rospy callback: one received message to every client subscribed to the topic, bytes untouched; a client's
        own message, come back through our publisher, skips that client (EchoFilter)."""
        shared = self.subscribers.get(resolved)
        if shared is None:
            return
        with shared.delivered_lock:
            shared.delivered += 1
        sender = None
        if shared.echoes.records and header.get("callerid") == self._node_name:
            sender = shared.echoes.take(payload)
        frames: dict[str, bytes] = {}
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
