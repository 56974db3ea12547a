"""Helpers for the bridge integration tests: a raw-socket ROS-TCP client, ROS-side probes, endpoint fixtures.

Everything waits on conditions with a deadline (tests.rosenv.wait_for or socket timeouts), never on bare sleeps.
"""

from __future__ import annotations

import contextlib
import io
import itertools
import json
import os
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from bridge import protocol
from bridge.client import TcpClient
from bridge.protocol import FrameDecoder
from measuring.frames import BadFrame, Frame, feed
from sim.processes import subscribers_written, writes_to
from tests.rosenv import EndpointProcess, RosCore, wait_for

LOOPBACK = "127.0.0.1"
_names = itertools.count(1)


def unique(name: str) -> str:
    """A topic/service name no other test of the session uses (the ROS graph is shared by the whole session)."""
    return f"/bt_{name}_{os.getpid()}_{next(_names)}"


def serialize(message) -> bytes:
    buffer = io.BytesIO()
    message.serialize(buffer)
    return buffer.getvalue()


# --- endpoint processes -----------------------------------------------------------------------------------------


def start_endpoint(
    roscore: RosCore, log_dir: Path, *extra: str, name: str | None = None, env: dict[str, str] | None = None
) -> EndpointProcess:
    """The endpoint as a process of `roscore`'s, with `extra` options and, if given, more environment variables."""
    return EndpointProcess(
        {**roscore.env, **(env or {})},
        log_dir,
        name=name or f"bridge_test_{os.getpid()}_{next(_names)}",
        extra=extra,
    )


@pytest.fixture(scope="module")
def bridge(roscore: RosCore, ros_node, tmp_path_factory) -> Iterator[EndpointProcess]:
    """One endpoint shared by a test module (tests use unique names); short service timeout for failure tests."""
    process = start_endpoint(roscore, tmp_path_factory.mktemp("bridge"), "--service-timeout", "2")
    try:
        yield process
    finally:
        process.stop()
        assert process.process.poll() is not None


# --- a raw ROS-TCP connection ----------------------------------------------------------------------------------


class ConnectionClosed(ConnectionError):
    pass


class FrameReader:
    """What the raw clients share: waiting for frames (their `next_frame`) and reading what came (`received`)."""

    received: list[Frame]

    def next_frame(self, timeout: float = 10.0) -> Frame:
        raise NotImplementedError

    def command(self, name: str, **params) -> None:
        raise NotImplementedError

    def wait_frame(self, predicate: Callable[[Frame], bool], what: str, timeout: float = 10.0) -> Frame:
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"no {what} within {timeout} s; got {self.summary()}")
            frame = self.next_frame(remaining)
            if predicate(frame):
                return frame

    def wait_command(self, name: str, timeout: float = 10.0) -> dict:
        frame = self.wait_frame(lambda f: f.destination == name, name, timeout)
        return json.loads(frame.payload)

    def expect_error(self, *fragments: str, timeout: float = 10.0) -> str:
        """The next __error whose text contains every fragment (other frames are skipped but kept)."""

        def matches(frame: Frame) -> bool:
            if frame.destination != "__error":
                return False
            text = json.loads(frame.payload)["text"]
            return all(fragment in text for fragment in fragments)

        frame = self.wait_frame(matches, f"__error containing {fragments}", timeout)
        return json.loads(frame.payload)["text"]

    def topic_list(self, timeout: float = 10.0) -> dict[str, str]:
        """Round trip through the endpoint: every command sent before has been handled when this returns."""
        self.command("__topic_list")
        params = self.wait_command("__topic_list", timeout)
        assert len(params["topics"]) == len(params["types"])
        return dict(zip(params["topics"], params["types"]))

    def sync(self, timeout: float = 10.0) -> None:
        self.topic_list(timeout)

    def errors(self) -> list[str]:
        return [json.loads(f.payload)["text"] for f in self.received if f.destination == "__error"]

    def messages(self, topic: str) -> list[bytes]:
        return [f.payload for f in self.received if f.destination == topic]

    def summary(self) -> str:
        return ", ".join(
            f.destination + (f" {f.payload[:200].decode(errors='replace')}" if f.destination.startswith("__") else "")
            for f in self.received[-20:]
        )


class RawConnection(FrameReader):
    """A client socket that speaks the protocol by hand; every frame it reads is kept in `received`."""

    def __init__(self, port: int, *, handshake: bool = True, timeout: float = 10.0, rcvbuf: int | None = None) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        if rcvbuf is not None:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.settimeout(timeout)
        self.sock.connect((LOOPBACK, port))
        self.decoder = FrameDecoder(max_payload_bytes=1 << 30)
        self.received: list[Frame] = []
        self._unread: list[Frame] = []
        self.closed = False
        self.handshake: dict | None = None
        if handshake:
            first = self.next_frame()
            assert first.destination == "__handshake", f"first frame was {first.destination!r}"
            self.handshake = json.loads(first.payload)

    def __enter__(self) -> RawConnection:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self.sock.close()

    # sending
    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def send_frame(self, destination: str, payload: bytes) -> None:
        self.send(protocol.encode_frame(destination, payload))

    def command(self, name: str, **params) -> None:
        self.send(protocol.encode_syscommand(name, params))

    def subscribe(self, topic: str, message_name: str) -> None:
        self.command("__subscribe", topic=topic, message_name=message_name)

    def register_publisher(self, topic: str, message_name: str, queue_size: int = 10, latch: bool = False) -> None:
        self.command("__publish", topic=topic, message_name=message_name, queue_size=queue_size, latch=latch)

    # reading
    def offer_service(self, rospy, service: str, message_name: str) -> None:
        """__unity_service, then wait until the ROS master lists the service (advertised by the endpoint)."""
        self.command("__unity_service", topic=service, message_name=message_name)
        self.sync()
        wait_for(lambda: service_exists(rospy, service), 10, f"{service} advertised")

    def next_frame(self, timeout: float = 10.0) -> Frame:
        deadline = time.monotonic() + timeout
        while not self._unread:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"no frame within {timeout} s")
            self.sock.settimeout(remaining)
            try:
                data = self.sock.recv(1 << 20)
            except socket.timeout:
                raise TimeoutError(f"no frame within {timeout} s") from None
            except ConnectionResetError:
                data = b""
            if not data:
                self.closed = True
                raise ConnectionClosed("the endpoint closed the connection")
            for item in feed(self.decoder, data):
                assert not isinstance(item, BadFrame), item
                self.received.append(item)
                self._unread.append(item)
        return self._unread.pop(0)

    def wait_closed(self, timeout: float = 10.0) -> None:
        """Read (and keep) frames until the endpoint closes the connection."""
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"connection still open after {timeout} s; got {self.summary()}")
            try:
                self.next_frame(remaining)
            except ConnectionClosed:
                return


# --- TcpClient helpers -----------------------------------------------------------------------------------------


class Inbox:
    """Thread-safe list of payloads for a TcpClient subscription callback."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.items: list[bytes] = []

    def __call__(self, payload: bytes) -> None:
        with self._lock:
            self.items.append(payload)

    def __len__(self) -> int:
        with self._lock:
            return len(self.items)

    def snapshot(self) -> list[bytes]:
        with self._lock:
            return list(self.items)

    def wait_count(self, count: int, timeout: float = 10.0, what: str = "messages") -> list[bytes]:
        wait_for(lambda: len(self) >= count, timeout, f"{count} {what} (have {len(self)})")
        return self.snapshot()


def tcp_client(port: int, **kwargs) -> TcpClient:
    kwargs.setdefault("reconnect_delay_s", 0.2)
    return TcpClient(LOOPBACK, port, **kwargs).connect(timeout=10)


# --- ROS side --------------------------------------------------------------------------------------------------


class RosInbox(Inbox):
    """A rospy.AnyMsg subscriber in the test process: `items` are the exact bytes each message arrived in."""

    def __init__(self, rospy, topic: str) -> None:
        super().__init__()
        self.rospy, self.topic = rospy, topic
        self.subscriber = rospy.Subscriber(topic, rospy.AnyMsg, lambda message: self(bytes(message._buff)))

    def wait_count(self, count: int, timeout: float = 10.0, what: str = "ROS messages") -> list[bytes]:
        return super().wait_count(count, timeout, what)

    def wait_connected(self, timeout: float = 10.0) -> None:
        """Until the publishing node (the endpoint) has this connection in its own list, not just we in ours:
        rospy's subscriber side counts a connection a moment before the publisher side starts writing to it,
        and messages published in that window are lost."""
        wait_for(lambda: self.subscriber.get_num_connections() > 0, timeout, "subscriber connection to the endpoint")
        wait_for(lambda: publishers_connected(self.rospy, self.topic), timeout, "the publisher side of the connection")

    def close(self) -> None:
        self.subscriber.unregister()


def publishers_connected(rospy, topic: str) -> bool:
    """Every node publishing `topic` reports an outbound connection on it to this node (its getBusInfo)."""
    import rosgraph

    master = rosgraph.Master(rospy.get_name())
    publishers = next((nodes for name, nodes in master.getSystemState()[0] if name == topic), [])
    me = rospy.get_name()
    return bool(publishers) and all(writes_to(master.lookupNode(node), topic, me) for node in publishers)


def fully_connected(rospy, topic: str) -> bool:
    """Every node publishing `topic` writes to every node subscribed to it, itself included (each publisher's
    getBusInfo): until then, what is published may not reach every subscriber."""
    import rosgraph

    master = rosgraph.Master(rospy.get_name())
    publishers_, subscribers_, _ = master.getSystemState()
    publishers = next((nodes for name, nodes in publishers_ if name == topic), [])
    subscribers = set(next((nodes for name, nodes in subscribers_ if name == topic), []))
    if not publishers or not subscribers:
        return False
    me = rospy.get_name()
    return all(subscribers <= subscribers_written(master.lookupNode(node), topic, me) for node in publishers)


def wait_subscribers(publisher, count: int = 1, timeout: float = 10.0) -> None:
    wait_for(lambda: publisher.get_num_connections() >= count, timeout, f"{count} subscriber connection(s)")


def wait_new_subscriber(publisher, before: list, timeout: float = 10.0) -> None:
    """Until `publisher` has a connection that is not among `before` (its connections at some earlier time).

    A client that reconnects subscribes again, and the endpoint makes a new ROS subscriber for it; the old one's
    connection can still be counted by the publisher, which notices a closed peer only when it writes to it. A
    count of connections then passes before the new one is up, and a message goes only to the closed one."""
    wait_for(lambda: any(c not in before for c in publisher.impl.connections), timeout, "a new subscriber connection")


def wait_no_subscribers(publisher, timeout: float = 10.0) -> None:
    wait_for(lambda: publisher.get_num_connections() == 0, timeout, "the endpoint to drop its subscription")


def service_exists(rospy, service: str) -> bool:
    import rosgraph

    try:
        rosgraph.Master(rospy.get_name()).lookupService(service)
        return True
    except rosgraph.MasterError:
        return False


# --- /diagnostics ----------------------------------------------------------------------------------------------


class DiagnosticsInbox:
    """The newest /diagnostics statuses of one endpoint node, by name."""

    def __init__(self, rospy, node: str) -> None:
        self.node = node
        self._lock = threading.Lock()
        self.statuses: dict = {}
        from diagnostic_msgs.msg import DiagnosticArray

        self._subscriber = rospy.Subscriber("/diagnostics", DiagnosticArray, self._store)

    def _store(self, array) -> None:
        mine = {status.name: status for status in array.status if status.name.startswith(self.node + ":")}
        if mine:
            with self._lock:
                self.statuses = mine

    def find(self, fragment: str):
        with self._lock:
            return next((status for name, status in self.statuses.items() if fragment in name), None)

    def close(self) -> None:
        self._subscriber.unregister()


def status_values(status) -> dict:
    return {entry.key: entry.value for entry in status.values}


# --- a raw WebSocket connection ------------------------------------------------------------------------------------


class RawWebSocket(FrameReader):
    """A WebSocket client of the endpoint written with wsproto alone (not bridge.protocol.websocket, which is under
    test): it upgrades, sends what it is told (ROS-TCP frames as binary messages, or any WebSocket bytes), and keeps
    every frame it reads in `received`, checking that each binary message carries exactly one frame. `close_code` and
    `close_reason` say how the endpoint closed the WebSocket; `refusal` holds the body of an HTTP refusal."""

    def __init__(
        self,
        port: int,
        *,
        upgrade: bool = True,
        handshake: bool = True,
        timeout: float = 10.0,
        headers: tuple[tuple[str, str], ...] = (),
        answer_close: bool = True,
    ) -> None:
        import wsproto
        from wsproto.events import Request

        self.sock = socket.create_connection((LOOPBACK, port), timeout=timeout)
        self.ws = wsproto.WSConnection(wsproto.ConnectionType.CLIENT)
        self.received: list[Frame] = []
        self.messages = 0  # binary messages read
        self._unread: list[Frame] = []
        self._message = bytearray()
        self.upgraded = False
        self.refusal: str | None = None
        self.close_code: int | None = None
        self.close_reason: str | None = None
        self.closed = False
        self.answer_close = answer_close  # answer the endpoint's Close, as RFC 6455 says a client must
        self.after_close = 0  # WebSocket events that came after the endpoint's Close (there must be none)
        self.eof = False  # the endpoint closed the TCP connection
        self.pongs = 0  # answers to WebSocket pings
        self.handshake: dict | None = None
        if upgrade:
            extra = [(name.encode(), value.encode()) for name, value in headers]
            self.sock.sendall(self.ws.send(Request(host=f"{LOOPBACK}:{port}", target="/", extra_headers=extra)))
            deadline = time.monotonic() + timeout
            while not self.upgraded:
                if self.refusal is not None or self.closed or time.monotonic() > deadline:
                    raise ConnectionClosed(f"upgrade failed: {self.refusal}")
                self._read(deadline - time.monotonic())
            if handshake:
                first = self.next_frame()
                assert first.destination == "__handshake", f"first frame was {first.destination!r}"
                self.handshake = json.loads(first.payload)

    def __enter__(self) -> RawWebSocket:
        return self

    def __exit__(self, *exc: object) -> None:
        self.sock.close()

    # sending
    def send_bytes(self, data: bytes) -> None:
        """Raw bytes on the socket (WebSocket frames made by hand)."""
        self.sock.sendall(data)

    def send_event(self, event) -> None:
        self.sock.sendall(self.ws.send(event))

    def send_message(self, data: bytes, *, finished: bool = True) -> None:
        """`data` as one binary message (or, with finished=False, the first part of one)."""
        from wsproto.events import BytesMessage

        self.send_event(BytesMessage(data=data, message_finished=finished))

    def send_frame(self, destination: str, payload: bytes) -> None:
        self.send_message(protocol.encode_frame(destination, payload))

    def command(self, name: str, **params) -> None:
        self.send_message(protocol.encode_syscommand(name, params))

    # reading
    def _read(self, timeout: float) -> None:
        from wsproto.events import (
            AcceptConnection,
            BytesMessage,
            CloseConnection,
            Ping,
            Pong,
            RejectConnection,
            RejectData,
        )

        self.sock.settimeout(max(timeout, 0.001))
        try:
            data = self.sock.recv(1 << 20)
        except socket.timeout:
            raise TimeoutError(f"nothing read within {timeout:.1f} s") from None
        except ConnectionResetError:
            data = b""
        if not data:
            self.closed = self.eof = True
            return
        self.ws.receive_data(data)
        for event in self.ws.events():
            if self.close_code is not None:
                self.after_close += 1
            if isinstance(event, AcceptConnection):
                self.upgraded = True
            elif isinstance(event, RejectConnection):
                self.refusal = f"HTTP {event.status_code}"
            elif isinstance(event, RejectData):
                self.refusal = f"{self.refusal} {bytes(event.data).decode(errors='replace')}"
            elif isinstance(event, BytesMessage):
                self._message += event.data
                if event.message_finished:
                    self._take_message(bytes(self._message))
                    self._message = bytearray()
            elif isinstance(event, Ping):
                self.send_event(event.response())
            elif isinstance(event, Pong):
                self.pongs += 1
            elif isinstance(event, CloseConnection):
                self.close_code, self.close_reason = int(event.code), event.reason
                if self.answer_close:
                    with contextlib.suppress(Exception):
                        self.send_event(event.response())
                self.closed = True

    def _take_message(self, data: bytes) -> None:
        decoder = FrameDecoder(max_payload_bytes=1 << 30)
        frames = [item for item in feed(decoder, data) if not isinstance(item, BadFrame)]
        assert len(frames) == 1 and not decoder.buffered_bytes, f"a binary message held {len(frames)} frame(s)"
        self.messages += 1
        self.received.extend(frames)
        self._unread.extend(frames)

    def next_frame(self, timeout: float = 10.0) -> Frame:
        deadline = time.monotonic() + timeout
        while not self._unread:
            if self.closed:
                raise ConnectionClosed(f"the endpoint closed the WebSocket ({self.close_code} {self.close_reason})")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"no frame within {timeout} s")
            self._read(remaining)
        return self._unread.pop(0)

    def wait_eof(self, timeout: float = 10.0) -> None:
        """Read on until the endpoint closes the TCP connection."""
        self._read_until(lambda: self.eof, timeout, "the TCP connection")

    def wait_closed(self, timeout: float = 10.0) -> None:
        self._read_until(lambda: self.closed, timeout, "WebSocket")

    def _read_until(self, done: Callable[[], bool], timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while not done():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"{what} still open after {timeout} s")
            with contextlib.suppress(TimeoutError):
                self._read(remaining)
