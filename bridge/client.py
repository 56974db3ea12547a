"""A Python client of the ROS-TCP protocol v0.7.0, behaving like Unity's ROS-TCP-Connector. No rospy.

It connects, checks the handshake, sends a keepalive after each second without sending, registers topics and
services, and on a lost connection reconnects (fixed delay) and re-sends every registration. Payloads are plain
ROS 1 serialized bytes; (de)serialize them with rosbags or any ROS 1 serializer.
Callbacks run on the client's reader thread: keep them short.
"""
from __future__ import annotations

import itertools
import json
import logging
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from bridge import protocol
from bridge.protocol import BadFrame, Frame, FrameDecoder, ProtocolError

log = logging.getLogger(__name__)

MessageCallback = Callable[[bytes], None]
ServiceHandler = Callable[[bytes], bytes]


class ClientError(RuntimeError):
    """Connection, handshake or service-call failure of the TCP client."""


@dataclass
class _PendingCall:
    service: str
    done: threading.Event = field(default_factory=threading.Event)
    response: bytes | None = None
    failure: str | None = None


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
    ) -> None:
        self.host = host
        self.port = port
        self.reconnect = reconnect
        self.reconnect_delay_s = reconnect_delay_s
        self.keepalive_interval_s = keepalive_interval_s
        self.auth_token = auth_token
        self.on_error = on_error
        self.handshake: dict | None = None
        self.errors: list[str] = []  # __error texts received (newest last, at most 100 kept)
        self.warnings: list[str] = []
        self.connections = 0  # successful connects so far (reconnects included)
        self._sock: socket.socket | None = None
        self._write_lock = threading.Lock()
        self._state_lock = threading.Lock()
        self._connected = threading.Event()
        self._closing = threading.Event()
        self._last_send = 0.0
        # Registrations, re-sent on every (re)connect, in the order Unity sends them.
        self._subscriptions: dict[str, tuple[str, list[MessageCallback]]] = {}
        self._unity_services: dict[str, tuple[str, ServiceHandler]] = {}
        self._publishers: dict[str, tuple[str, int, bool]] = {}
        self._ros_services: dict[str, str] = {}
        self._srv_ids = itertools.count(101)
        self._pending: dict[int, _PendingCall] = {}
        self._topic_list_waiters: list[tuple[threading.Event, dict]] = []
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
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            sock.close()
        for thread in (self._reader, self._keepalive):
            if thread is not None and thread is not threading.current_thread():
                thread.join(timeout=2.0)
        self._fail_pending("client closed")

    def __enter__(self) -> TcpClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _open(self) -> None:
        sock = socket.create_connection((self.host, self.port), timeout=5.0)
        sock.settimeout(None)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock = sock
        # Like Unity: a keepalive first, then every registration, before reading anything.
        frames = [protocol.KEEPALIVE_FRAME]
        if self.auth_token is not None:
            frames.append(protocol.encode_syscommand("__auth", {"token": self.auth_token}))
        frames.extend(self._registration_frames())
        self._send_raw(b"".join(frames))

    def _registration_frames(self) -> list[bytes]:
        with self._state_lock:
            frames = [
                protocol.encode_syscommand("__subscribe", {"topic": topic, "message_name": name})
                for topic, (name, _) in self._subscriptions.items()
            ]
            frames += [
                protocol.encode_syscommand("__unity_service", {"topic": topic, "message_name": name})
                for topic, (name, _) in self._unity_services.items()
            ]
            frames += [
                protocol.encode_syscommand(
                    "__publish", {"topic": topic, "message_name": name, "queue_size": queue_size, "latch": latch}
                )
                for topic, (name, queue_size, latch) in self._publishers.items()
            ]
            frames += [
                protocol.encode_syscommand("__ros_service", {"topic": topic, "message_name": name})
                for topic, name in self._ros_services.items()
            ]
        return frames

    def _send_raw(self, data: bytes) -> None:
        sock = self._sock
        if sock is None:
            raise ClientError("not connected")
        with self._write_lock:
            sock.sendall(data)
            self._last_send = time.monotonic()

    def _send(self, data: bytes) -> None:
        """Send, or drop silently while disconnected (like Unity, the registration is re-sent on reconnect)."""
        try:
            self._send_raw(data)
        except (OSError, ClientError) as error:
            log.debug("send failed (%s); reconnecting", error)

    def _keepalive_loop(self) -> None:
        while not self._closing.wait(self.keepalive_interval_s / 4):
            if self._connected.is_set() and time.monotonic() - self._last_send >= self.keepalive_interval_s:
                self._send(protocol.KEEPALIVE_FRAME)

    # --- registrations and data ----------------------------------------------------------------------------
    def subscribe(self, topic: str, message_name: str, callback: MessageCallback) -> None:
        with self._state_lock:
            entry = self._subscriptions.setdefault(topic, (message_name, []))
            entry[1].append(callback)
        self._send(protocol.encode_syscommand("__subscribe", {"topic": topic, "message_name": message_name}))

    def register_publisher(self, topic: str, message_name: str, queue_size: int = 10, latch: bool = False) -> None:
        with self._state_lock:
            self._publishers[topic] = (message_name, queue_size, latch)
        self._send(
            protocol.encode_syscommand(
                "__publish", {"topic": topic, "message_name": message_name, "queue_size": queue_size, "latch": latch}
            )
        )

    def publish(self, topic: str, payload: bytes) -> None:
        self._send(protocol.encode_frame(topic, payload))

    def register_ros_service(self, service: str, service_name: str) -> None:
        with self._state_lock:
            self._ros_services[service] = service_name
        self._send(protocol.encode_syscommand("__ros_service", {"topic": service, "message_name": service_name}))

    def implement_service(self, service: str, service_name: str, handler: ServiceHandler) -> None:
        """Offer `service` to ROS; `handler` turns request bytes into response bytes."""
        with self._state_lock:
            self._unity_services[service] = (service_name, handler)
        self._send(protocol.encode_syscommand("__unity_service", {"topic": service, "message_name": service_name}))

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
        self._send(protocol.encode_syscommand(f"__remove_{kind}", {"topic": topic}))

    def call_service(self, service: str, request: bytes, timeout: float = 10.0) -> bytes:
        """Call a ROS service (registered with register_ros_service) and wait for its response bytes."""
        srv_id = next(self._srv_ids)
        call = _PendingCall(service)
        with self._state_lock:
            self._pending[srv_id] = call
        try:
            header = protocol.encode_syscommand("__request", {"srv_id": srv_id})
            self._send_raw(header + protocol.encode_frame(service, request))
            if not call.done.wait(timeout):
                raise ClientError(f"service {service}: no response within {timeout:g} s")
            if call.failure is not None:
                raise ClientError(f"service {service}: {call.failure}")
            assert call.response is not None
            return call.response
        except OSError as error:
            raise ClientError(f"service {service}: connection failed: {error}") from None
        finally:
            with self._state_lock:
                self._pending.pop(srv_id, None)

    def topic_list(self, timeout: float = 5.0) -> dict[str, str]:
        """The ROS graph's topics and their types, as the endpoint reports them."""
        done, result = threading.Event(), dict[str, str]()
        with self._state_lock:
            self._topic_list_waiters.append((done, result))
        self._send_raw(protocol.encode_syscommand("__topic_list", {}))
        if not done.wait(timeout):
            raise ClientError(f"no __topic_list answer within {timeout:g} s")
        return result

    def send_raw(self, data: bytes) -> None:
        """Write arbitrary bytes (tests and fault injection)."""
        self._send_raw(data)

    # --- reading ------------------------------------------------------------------------------------------
    def _read_loop(self) -> None:
        while not self._closing.is_set():
            sock = self._sock
            if sock is not None:
                self._read_connection(sock)
            self._connected.clear()
            self._fail_pending("connection lost")
            if self._closing.is_set() or not self.reconnect:
                return
            if self._closing.wait(self.reconnect_delay_s):
                return
            try:
                self._open()
            except OSError as error:
                self._sock = None
                log.debug("reconnect to %s:%d failed: %s", self.host, self.port, error)

    def _read_connection(self, sock: socket.socket) -> None:
        decoder = FrameDecoder()
        expect_body: int | None = None
        got_handshake = False
        try:
            while True:
                data = sock.recv(256 * 1024)
                if not data:
                    return
                for item in decoder.feed(data):
                    if isinstance(item, BadFrame):
                        continue
                    if not got_handshake:
                        got_handshake = self._check_handshake(item)
                        continue
                    if expect_body is not None:
                        self._handle_body(expect_body, item)
                        expect_body = None
                    else:
                        expect_body = self._handle_frame(item)
        except (OSError, ProtocolError) as error:
            if not self._closing.is_set():
                log.info("connection to %s:%d lost: %s", self.host, self.port, error)
        finally:
            try:
                sock.close()
            except OSError:
                pass

    def _check_handshake(self, frame: Frame) -> bool:
        if frame.destination != "__handshake":
            log.warning("first frame from the endpoint was %r, not __handshake", frame.destination)
            return False
        params = protocol.parse_json_params("__handshake", frame.payload)
        version = str(params.get("version", ""))
        try:
            metadata = json.loads(params.get("metadata", "{}"))
        except json.JSONDecodeError:
            metadata = {}
        if not version.startswith("v0.7.") or metadata.get("protocol") != "ROS1":
            log.warning("endpoint speaks %s / %s; this client expects v0.7.x / ROS1", version, metadata)
        self.handshake = {"version": version, "metadata": metadata}
        self.connections += 1
        self._connected.set()
        return True

    def _handle_frame(self, frame: Frame) -> int | None:
        """Handle one frame; returns a srv_id when the next frame is a service body."""
        if frame.is_keepalive:
            return None
        if not frame.is_syscommand:
            with self._state_lock:
                entry = self._subscriptions.get(frame.destination)
                callbacks = list(entry[1]) if entry else []
            for callback in callbacks:  # frames for undeclared topics are ignored, like Unity does
                try:
                    callback(frame.payload)
                except Exception:
                    log.exception("subscriber callback for %s failed", frame.destination)
            return None
        command = frame.destination
        if command in ("__request", "__response"):
            parsed = protocol.parse_syscommand(frame)  # the same srv_id checks as the endpoint's; ProtocolError
            assert isinstance(parsed, (protocol.Request, protocol.Response))
            return parsed.srv_id if command == "__request" else -parsed.srv_id
        params = protocol.parse_json_params(frame.destination, frame.payload)
        if command == "__topic_list":
            self._answer_topic_list(params)
        elif command == "__error":
            self._record_error(str(params.get("text", "")))
        elif command == "__warn":
            self.warnings = (self.warnings + [str(params.get("text", ""))])[-100:]
            log.warning("endpoint: %s", params.get("text"))
        elif command == "__log":
            log.info("endpoint: %s", params.get("text"))
        return None

    def _handle_body(self, signed_srv_id: int, frame: Frame) -> None:
        if signed_srv_id < 0:  # a __response to one of our calls
            with self._state_lock:
                call = self._pending.get(-signed_srv_id)
            if call is not None:
                call.response = frame.payload
                call.done.set()
            return
        # A __request from ROS for a service this client implements.
        with self._state_lock:
            entry = self._unity_services.get(frame.destination)
        if entry is None:
            log.warning("request for unknown service %s ignored", frame.destination)
            return
        try:
            response = entry[1](frame.payload)
        except Exception:
            log.exception("service handler for %s failed; no response sent", frame.destination)
            return
        header = protocol.encode_syscommand("__response", {"srv_id": signed_srv_id})
        self._send(header + protocol.encode_frame(frame.destination, response))

    def _answer_topic_list(self, params: dict) -> None:
        topics, types = params.get("topics", []), params.get("types", [])
        with self._state_lock:
            waiters, self._topic_list_waiters = self._topic_list_waiters, []
        for done, result in waiters:
            result.update(zip(topics, types))
            done.set()

    def _record_error(self, text: str) -> None:
        self.errors = (self.errors + [text])[-100:]
        log.warning("endpoint error: %s", text)
        # Our endpoint prefixes service failures with "__request <srv_id>:", so the waiting call fails at once.
        if text.startswith("__request "):
            srv_id_text = text[len("__request ") :].split(":", 1)[0]
            if srv_id_text.isdigit():
                with self._state_lock:
                    call = self._pending.get(int(srv_id_text))
                if call is not None:
                    call.failure = text
                    call.done.set()
        if self.on_error is not None:
            self.on_error(text)

    def _fail_pending(self, reason: str) -> None:
        with self._state_lock:
            calls = list(self._pending.values())
        for call in calls:
            call.failure = reason
            call.done.set()
