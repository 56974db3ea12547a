"""A Python client of the ROS-TCP protocol v0.7.0, behaving like Unity's ROS-TCP-Connector. No rospy.

It connects, checks the handshake, sends a keepalive after each second without sending, registers topics and
services, and on a lost connection reconnects (fixed delay) and re-sends every registration. Payloads are plain
ROS 1 serialized bytes; (de)serialize them with rosbags or any ROS 1 serializer. With `websocket=True` it speaks
the same protocol over a WebSocket (bridge.protocol.websocket; needs wsproto), as a browser or a Unity WebGL build
would. Callbacks run on the client's reader thread: keep them short. The answers it waits for are
bridge.protocol.client_answers'. One concern, and a long one: every command of the protocol, and the reconnection.
"""

from __future__ import annotations

import itertools
import logging
import socket
import threading
import time
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any, Callable

from bridge.connection.sockets import UnsentLimit, unpaced_on_loopback
from bridge.errors import BridgeError
from bridge.protocol import (
    Auth,
    Conversation,
    Error,
    Event,
    Handshake,
    IgnoredFields,
    InvalidInput,
    Keepalive,
    Log,
    Ping,
    Publish,
    Remove,
    Role,
    RosService,
    ServiceRequest,
    ServiceResponse,
    Subscribe,
    TopicListQuery,
    TopicMessage,
    UnityService,
    Warn,
)
from bridge.protocol.client_answers import Answers, PingResult
from bridge.protocol.framing import LARGE_PAYLOAD_BYTES

if TYPE_CHECKING:  # wsproto is optional: bridge.protocol.websocket is imported only by WebSocket clients
    from bridge.protocol.websocket import WebSocketLink

__all__ = ["ClientError", "PingResult", "TcpClient"]

log = logging.getLogger(__name__)

MessageCallback = Callable[[bytes], None]
ServiceHandler = Callable[[bytes], bytes]


class ClientError(BridgeError, RuntimeError):
    """Connection, handshake or service-call failure of the TCP client."""


class TcpClient:
    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 10000,
        *,
        reconnect: bool = True,
        reconnect_delay_s: float = 1.0,
        keepalive_interval_s: float = 1.0,
        auth_token: str | None = None,
        on_error: Callable[[str], None] | None = None,
        websocket: bool = False,
        websocket_path: str = "/",
    ) -> None:
        self.host = host
        self.port = port
        self.reconnect = reconnect
        self.reconnect_delay_s = reconnect_delay_s
        self.keepalive_interval_s = keepalive_interval_s
        self.auth_token = auth_token
        self.on_error = on_error
        self.websocket = websocket
        self.websocket_path = websocket_path
        self.handshake: Handshake | None = None
        self.errors: list[str] = []  # __error texts received (newest last, at most 100 kept)
        self.warnings: list[str] = []
        self.connections = 0  # successful connects so far (reconnects included)
        self._sock: socket.socket | None = None
        self._unsent_limit: UnsentLimit | None = None  # of the current connection
        self._conversation = Conversation(Role.CLIENT)  # a new one for every connection
        self._link: WebSocketLink | None = None  # the current connection's WebSocket layer, when websocket
        self._write_lock = threading.Lock()
        self._state_lock = threading.Lock()
        self._connected = threading.Event()
        self._closing = threading.Event()
        self._last_send = 0.0
        # Registrations, re-sent on every (re)connect, in the order Unity sends them.
        self._subscriptions: dict[str, tuple[Subscribe, list[MessageCallback]]] = {}
        self._unity_services: dict[str, tuple[UnityService, ServiceHandler]] = {}
        self._publishers: dict[str, Publish] = {}
        self._ros_services: dict[str, RosService] = {}
        self._srv_ids = itertools.count(101)
        self._answers = Answers()  # service responses, topic lists and ping answers awaited
        self._last_round_trip: float | None = None  # told to the endpoint with the next ping, for its diagnostics
        self._reader: threading.Thread | None = None
        self._keepalive: threading.Thread | None = None

    # --- connection ---------------------------------------------------------------------------------------
    def connect(self, timeout: float = 10.0) -> TcpClient:
        """Connect (retrying until `timeout`) and wait for the handshake; then keep the connection alive."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                self._open()
                break
            except OSError as error:
                if time.monotonic() > deadline:
                    raise ClientError(f"cannot connect to {self.host}:{self.port}: {error}") from None
                time.sleep(min(0.2, self.reconnect_delay_s))
        self._reader = threading.Thread(target=self._read_loop, name="tcp-client-read", daemon=True)
        self._reader.start()
        self._keepalive = threading.Thread(target=self._keepalive_loop, name="tcp-client-keepalive", daemon=True)
        self._keepalive.start()
        self.wait_connected(max(0.1, deadline - time.monotonic()))
        return self

    def wait_connected(self, timeout: float) -> None:
        if not self._connected.wait(timeout):
            raise ClientError(f"no handshake from {self.host}:{self.port} within {timeout:.1f} s")

    @property
    def is_connected(self) -> bool:
        return self._connected.is_set()

    def close(self) -> None:
        self._closing.set()
        self._connected.clear()
        sock = self._sock
        if sock is not None:
            try:
                if self._link is not None:
                    sock.sendall(self._link.close())
            except OSError:
                pass
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            sock.close()
        for thread in (self._reader, self._keepalive):
            if thread is not None and thread is not threading.current_thread():
                thread.join(timeout=2.0)
        self._answers.fail_calls("client closed")

    def __enter__(self) -> TcpClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _open(self) -> None:
        sock = socket.create_connection((self.host, self.port), timeout=5.0)
        sock.settimeout(None)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        unpaced_on_loopback(sock)
        self._unsent_limit = UnsentLimit(sock)
        self._conversation = Conversation(Role.CLIENT)
        early: list[Event] = []
        if self.websocket:
            early = self._upgrade(sock)
        self._sock = sock
        # Like Unity: a keepalive first, then every registration, before reading anything.
        events: list[Event] = [Keepalive()]
        if self.auth_token is not None:
            events.append(Auth(self.auth_token))
        events.extend(self._registrations())
        self._send_raw(self._wrap(b"".join(self._conversation.send(event) for event in events)))
        self._deliver_all(early)

    def _upgrade(self, sock: socket.socket) -> list[Event]:
        """The WebSocket upgrade (the first messages may come with its answer: their events are returned); OSError
        when the endpoint refuses it or does not answer in time."""
        from bridge.protocol.websocket import WebSocketLink

        link = WebSocketLink(Role.CLIENT, self._conversation)
        sock.settimeout(5.0)
        try:
            sock.sendall(link.upgrade_request(f"{self.host}:{self.port}", self.websocket_path))
            events: list[Event] = []
            while not link.upgraded:
                data = sock.recv(64 * 1024)
                events.extend(link.receive_data(data) if data else [])
                if link.closed is not None or not data:
                    raise ConnectionRefusedError(link.closed or "the endpoint closed the connection during the upgrade")
        except OSError:
            sock.close()
            raise
        finally:
            if sock.fileno() >= 0:
                sock.settimeout(None)
        self._link = link
        return events

    def _wrap(self, frames: bytes) -> bytes:
        return frames if self._link is None else self._link.wrap(frames)

    def _registrations(self) -> list[Event]:
        with self._state_lock:
            return [
                *(subscribe for subscribe, _ in self._subscriptions.values()),
                *(offer for offer, _ in self._unity_services.values()),
                *self._publishers.values(),
                *self._ros_services.values(),
            ]

    def _send_raw(self, data: bytes) -> None:
        sock = self._sock
        if sock is None:
            raise ClientError("not connected")
        with self._write_lock:
            if len(data) >= LARGE_PAYLOAD_BYTES and self._unsent_limit is not None:
                # As the endpoint does: on a slow link a large publish waits until it is nearly on the wire, instead
                # of piling seconds of messages into the kernel's send buffer (bridge.connection.sockets.UnsentLimit).
                self._unsent_limit.before_large_write()
            sock.sendall(data)
            self._last_send = time.monotonic()

    def _say(self, event: Event, *, or_raise: bool = False) -> None:
        """Send an event. Unless `or_raise`, a failure while disconnected is silent: like Unity, registrations are
        re-sent on reconnect."""
        data = self._wrap(self._conversation.send(event))
        try:
            self._send_raw(data)
        except (OSError, ClientError) as error:
            if or_raise:
                raise
            log.debug("send failed (%s); reconnecting", error)

    def _keepalive_loop(self) -> None:
        while not self._closing.wait(self.keepalive_interval_s / 4):
            if self._connected.is_set() and time.monotonic() - self._last_send >= self.keepalive_interval_s:
                self._say(Keepalive())

    # --- registrations and data ----------------------------------------------------------------------------
    def subscribe(
        self, topic: str, message_name: str, callback: MessageCallback, queue_size: int | None = None
    ) -> None:
        subscribe = Subscribe(topic, message_name, queue_size)
        with self._state_lock:
            callbacks = self._subscriptions[topic][1] if topic in self._subscriptions else []
            callbacks.append(callback)
            self._subscriptions[topic] = (subscribe, callbacks)
        self._say(subscribe)

    def register_publisher(self, topic: str, message_name: str, queue_size: int = 10, latch: bool = False) -> None:
        publish = Publish(topic, message_name, queue_size, latch)
        with self._state_lock:
            self._publishers[topic] = publish
        self._say(publish)

    def publish(self, topic: str, payload: bytes) -> None:
        self._say(TopicMessage(topic, payload))

    def register_ros_service(self, service: str, service_type: str) -> None:
        registration = RosService(service, service_type)
        with self._state_lock:
            self._ros_services[service] = registration
        self._say(registration)

    def implement_service(self, service: str, service_type: str, handler: ServiceHandler) -> None:
        """Offer `service` to ROS; `handler` turns request bytes into response bytes."""
        offer = UnityService(service, service_type)
        with self._state_lock:
            self._unity_services[service] = (offer, handler)
        self._say(offer)

    def remove(self, kind: str, topic: str) -> None:
        """Undo a registration; kind is subscriber | publisher | ros_service | unity_service."""
        registries: dict[str, dict[str, Any]] = {
            "subscriber": self._subscriptions,
            "publisher": self._publishers,
            "ros_service": self._ros_services,
            "unity_service": self._unity_services,
        }
        registry = registries[kind]
        with self._state_lock:
            registry.pop(topic, None)
        self._say(Remove(kind, topic))

    def call_service(self, service: str, request: bytes, timeout: float = 10.0) -> bytes:
        """Call a ROS service (registered with register_ros_service) and wait for its response bytes."""
        srv_id = next(self._srv_ids)
        call = self._answers.call(srv_id, service)
        try:
            self._say(ServiceRequest(srv_id, service, request), or_raise=True)
            if not call.done.wait(timeout):
                raise ClientError(f"service {service}: no response within {timeout:g} s")
            if call.failure is not None:
                raise ClientError(f"service {service}: {call.failure}")
            assert call.response is not None
            return call.response
        except OSError as error:
            raise ClientError(f"service {service}: connection failed: {error}") from None
        finally:
            self._answers.forget_call(srv_id)

    def topic_list(self, timeout: float = 5.0) -> dict[str, str]:
        """The ROS graph's topics and their types, as the endpoint reports them."""
        done, result = self._answers.topic_list()
        self._say(TopicListQuery(), or_raise=True)
        if not done.wait(timeout):
            raise ClientError(f"no __topic_list answer within {timeout:g} s")
        return result

    def ping(self, timeout: float = 5.0) -> PingResult:
        """A __ping (newer connectors' ROSConnection.Ping) and its answer: round trip and ROS clock offset."""
        request_time = datetime.now(timezone.utc).isoformat()
        done, answer = self._answers.ping(request_time)
        try:
            sent_at, started = time.time(), time.monotonic()
            self._say(Ping(request_time, self._last_round_trip), or_raise=True)
            if not done.wait(timeout):
                raise ClientError(f"no __ping_response within {timeout:g} s")
            round_trip = time.monotonic() - started
            self._last_round_trip = round_trip
            ros_time = answer[0].ros_time
            offset = None if ros_time is None else ros_time - (sent_at + round_trip / 2)
            return PingResult(round_trip, offset)
        finally:
            self._answers.forget_ping(request_time)

    def send_raw(self, data: bytes, *, as_is: bool = False) -> None:
        """Write arbitrary bytes (tests and fault injection); over a WebSocket, as one binary message, unless
        `as_is`: then exactly these bytes (made by `wire`, or a fault in the WebSocket's own framing)."""
        self._send_raw(data if self._link is None or as_is else self._link.message(data))

    def wire(self, frames: bytes) -> bytes:
        """Whole frames as this connection carries them (over a WebSocket, a binary message each), to be written
        with send_raw(..., as_is=True): a flood then frames its message once, not at every write."""
        return self._wrap(frames)

    # --- reading ------------------------------------------------------------------------------------------
    def _read_loop(self) -> None:
        while not self._closing.is_set():
            sock = self._sock
            if sock is not None:
                self._read_connection(sock, self._conversation if self._link is None else self._link)
            self._connected.clear()
            self._answers.fail_calls("connection lost")
            if self._closing.is_set() or not self.reconnect:
                return
            if self._closing.wait(self.reconnect_delay_s):
                return
            try:
                self._open()
            except OSError as error:
                self._sock = None
                log.debug("reconnect to %s:%d failed: %s", self.host, self.port, error)

    def _read_connection(self, sock: socket.socket, incoming: Conversation | WebSocketLink) -> None:
        try:
            while True:
                data = sock.recv(256 * 1024)
                if not data:
                    return
                if not self._deliver_all(incoming.receive_data(data)):
                    return
                link = self._link
                if link is not None:
                    reply = link.data_to_send()  # pongs, the answer to a close
                    if reply:
                        self._send_raw(reply)
                    if link.closed is not None:
                        log.info("endpoint %s:%d: %s", self.host, self.port, link.closed)
                        return
        except OSError as error:
            if not self._closing.is_set():
                log.info("connection to %s:%d lost: %s", self.host, self.port, error)
        finally:
            try:
                sock.close()
            except OSError:
                pass

    def _deliver_all(self, events: list[Event]) -> bool:
        """Act on the endpoint's events; False after one that ends the connection."""
        for event in events:
            if type(event) is TopicMessage:
                self._deliver(event)
            elif isinstance(event, InvalidInput):
                log.warning("endpoint %s:%d: %s", self.host, self.port, event.error)
                if event.error.fatal:
                    return False
            elif not self._answers.take(event):  # a service response, a topic list, a ping's answer: taken
                self._handle(event)
        return True

    def _deliver(self, message: TopicMessage) -> None:
        with self._state_lock:
            entry = self._subscriptions.get(message.topic)
            callbacks = list(entry[1]) if entry else []
        for callback in callbacks:  # messages for undeclared topics are ignored, like Unity does
            try:
                callback(message.payload)
            except Exception:
                log.exception("subscriber callback for %s failed", message.topic)

    def _handle(self, event: Event) -> None:
        if isinstance(event, Handshake):
            if not event.is_compatible:
                log.warning("endpoint speaks %s / %s; this client expects v0.7.x / ROS1", event.version, event.metadata)
            self.handshake = event
            self.connections += 1
            self._connected.set()
        elif isinstance(event, ServiceRequest):
            self._answer(event)
        elif isinstance(event, Error):
            self._record_error(event)
        elif isinstance(event, Warn):
            self.warnings = (self.warnings + [event.text])[-100:]
            log.warning("endpoint: %s", event.text)
        elif isinstance(event, Log):
            log.info("endpoint: %s", event.text)
        elif isinstance(event, IgnoredFields):
            log.info("endpoint's %s has field(s) %s this client does not know", event.command, event.fields)

    def _answer(self, request: ServiceRequest) -> None:
        """A request from ROS for a service this client implements."""
        with self._state_lock:
            entry = self._unity_services.get(request.service)
        if entry is None:
            log.warning("request for unknown service %s ignored", request.service)
            return
        try:
            response = entry[1](request.payload)
        except Exception:
            log.exception("service handler for %s failed; no response sent", request.service)
            return
        self._say(ServiceResponse(request.srv_id, request.service, response))

    def _record_error(self, error: Error) -> None:
        self.errors = (self.errors + [error.text])[-100:]
        log.warning("endpoint error: %s", error.text)
        if error.srv_id is not None:  # the endpoint says which of our calls will not complete: fail it at once
            self._answers.fail_call(error.srv_id, error.text)
        if self.on_error is not None:
            self.on_error(error.text)
