"""The only module of `bridge` that touches rospy: raw-bytes topics and services on a ROS 1 graph.

Messages cross the endpoint as the bytes they arrived in. A raw class carries the real type's name, md5sum and
definition (so rospy negotiates connections exactly as for the generated class) but serializes stored bytes and
deserializes by keeping them; `_has_header = False` keeps rospy from rewriting `header.seq`.
"""
from __future__ import annotations

import importlib
import io
import logging
import os
import socket
import struct
import sys
import threading
import time
import warnings
from typing import Any, Callable, Dict, List, Optional, Tuple

import genpy
import rosgraph
import rosgraph.network
import rospy
import rospy.impl.tcpros_pubsub
import xmlrpc.client
from rospy.exceptions import TransportTerminated

from bridge.definitions import (
    DefinitionError,
    RosPackages,
    message_class_from_files,
    message_class_from_text,
    service_class_from_files,
    split_type_name,
)
from bridge.diagnostics import Status
from bridge.framing import LARGE_PAYLOAD_BYTES
from bridge.layout import Layout, LayoutError
from bridge.master import MASTER_TIMEOUT_S, MasterError, MasterLink, MasterRefused, call_master, timed_proxy
from bridge.queues import OutgoingQueue
from bridge.sockets import send_to_all, takes_whole, unsent_bytes

__all__ = [
    "PUBLISH_WAIT_S", "SUBSCRIBER_STALL_S", "DIRECT_PUBLISH_MAX_BYTES", "RosError", "RawMessage", "TypeRegistry",
    "MessageCallback", "ServiceHandler", "RosGraph", "RawPublisher", "RawServiceProxy", "end_topic",
]

log = logging.getLogger(__name__)
_U32 = struct.Struct("<I")
# How long a client's reader waits for room in a full publisher queue before the ROS side counts as stalled.
PUBLISH_WAIT_S = 0.05
# A ROS subscriber connection that takes no bytes for this long while a batch waits for it has stopped reading (a
# frozen or wedged node): it is closed, so the topic's other subscribers, which already have the batch, get the next
# one too. A subscriber that reads slowly but steadily is waited for instead (flow control, see RawPublisher).
SUBSCRIBER_STALL_S = 1.0
# Messages up to this size take RawPublisher's direct path without asking for the send buffer's size: far below the
# smallest send buffer (16 KiB), so an empty, acknowledged send queue always takes them whole.
DIRECT_PUBLISH_MAX_BYTES = 8 * 1024
# rospy's read size for the endpoint's subscribers follows the traffic (next_read_size): its default to begin with and
# while large messages come, so little of one goes through rospy's read buffer (see read_raw_messages); larger once a
# read finds more waiting than it takes, a flood of small messages (measured: with 64 KiB reads, a JointState flood
# reached a client at 0.8 of the rate it did with 1 MiB reads).
SUBSCRIBER_READ_BYTES = 64 * 1024
FLOOD_READ_BYTES = 1024 * 1024
# A message from LARGE_PAYLOAD_BYTES up to this size is read straight into the buffer it is delivered in; a larger
# one (more than a client may be sent by default) takes rospy's way, which grows its buffer only as bytes come.
DIRECT_RECEIVE_MAX_BYTES = 64 * 1024 * 1024
# How long a client's new registration may wait for the master to hold it before its next command runs.
REGISTRATION_WAIT_S = 1.0
# A ROS service call looks this often whether its client has gone, and whether the service has been advertised.
SERVICE_POLL_S = 0.2


class RosError(RuntimeError):
    """A ROS-side failure the client should hear about (unknown type, service call failed, ...)."""


class RawMessage(genpy.Message):
    """Base of the per-type raw classes; `_buff` holds one serialized message."""

    __slots__ = ("_buff",)
    _type = "*"
    _md5sum = "*"
    _full_text = ""
    _has_header = False
    _slot_types: list[str] = []

    def __init__(self, buff: bytes = b"") -> None:  # noqa: D107 - genpy's positional-args init is not wanted
        self._buff = buff

    def serialize(self, buff: Any) -> None:
        buff.write(self._buff)

    def deserialize(self, data: bytes) -> RawMessage:
        self._buff = bytes(data)
        return self


def _split_name(message_name: str) -> tuple[str, str]:
    try:
        return split_type_name(message_name)
    except DefinitionError as error:
        raise RosError(str(error)) from None


def _import_generated(message_name: str, kind: str, packages: RosPackages) -> Any:
    """The generated class of a message (kind "msg") or service ("srv"): the package's Python module, else one built
    from the definition files on ROS_PACKAGE_PATH (bridge.definitions). Only a ROS package's own generated module is
    ever imported (see RosPackages). RosError says what to build or source."""
    package, type_name = _split_name(message_name)
    what = "message" if kind == "msg" else "service"
    if packages.has_generated(package, kind, type_name):
        try:
            return getattr(importlib.import_module(f"{package}.{kind}"), type_name)
        except (ImportError, AttributeError):
            pass
    elif not packages.exists(package):
        raise RosError(
            f"unknown {what} type {message_name!r}: {package!r} is not a ROS package (no generated Python "
            f"{package}/{kind}/_{type_name}.py, and not on ROS_PACKAGE_PATH: "
            f"{os.environ.get('ROS_PACKAGE_PATH') or 'not set'}); nothing was imported"
        )
    try:
        if kind == "msg":
            return message_class_from_files(message_name)
        return service_class_from_files(message_name)
    except DefinitionError as error:
        raise RosError(
            f"unknown {what} type {message_name!r}: no Python module {package}.{kind} has it (build the package, "
            f"and source its workspace's devel/setup.bash where the endpoint runs), and {error}"
        ) from None


class TypeRegistry:
    """Resolves 'pkg/Type' names to the generated classes and builds (cached) raw classes for them."""

    def __init__(self) -> None:
        self._lock = threading.Lock()  # held only to read and fill the caches, never while a type is looked up
        self._packages = RosPackages()
        self._raw_messages: dict[str, type[RawMessage]] = {}
        # service classes (genpy's and ours) are plain classes whose attributes genpy sets: typed Any
        self._raw_services: dict[str, Any] = {}
        self._generated: dict[str, type[genpy.Message]] = {}
        self._generated_services: dict[str, Any] = {}
        # 'pkg/Type' or 'pkg/Service request|response'; read without the lock: entries are only ever added
        self._layouts: dict[str, Layout] = {}

    def message_class(self, message_name: str) -> type[genpy.Message]:
        return self._imported(self._generated, message_name, "msg")

    def learn(self, message_name: str, full_text: str) -> None:
        """Take `message_name`'s class from its full definition (e.g. a publisher's connection header)."""
        try:
            cls = message_class_from_text(message_name, full_text)
        except DefinitionError as error:
            raise RosError(str(error)) from None
        with self._lock:
            self._generated.setdefault(message_name, cls)

    def raw_message_class(self, message_name: str) -> type[RawMessage]:
        generated = self.message_class(message_name)
        with self._lock:
            raw = self._raw_messages.get(message_name)
            if raw is None:
                raw = _raw_class_like(generated)
                self._raw_messages[message_name] = raw
            return raw

    def _generated_service(self, service_type: str) -> Any:
        return self._imported(self._generated_services, service_type, "srv")

    def _imported(self, cache: dict[str, Any], name: str, kind: str) -> Any:
        cls = cache.get(name)  # entries are only ever added
        if cls is not None:
            return cls
        # Looked up outside the lock: a look-up may take a while (files, genmsg), and other clients' types must
        # not wait for it. Two clients looking up one type at once both do; the first result is kept.
        cls = _import_generated(name, kind, self._packages)
        with self._lock:
            return cache.setdefault(name, cls)

    def raw_service_class(self, service_type: str) -> Any:
        generated = self._generated_service(service_type)
        with self._lock:
            raw = self._raw_services.get(service_type)
            if raw is not None:
                return raw
            raw = type(
                f"Raw{generated.__name__}",
                (),
                {
                    "_type": generated._type,
                    "_md5sum": generated._md5sum,
                    "_request_class": _raw_class_like(generated._request_class),
                    "_response_class": _raw_class_like(generated._response_class),
                },
            )
            self._raw_services[service_type] = raw
            return raw

    def validate(self, message_name: str, payload: bytes) -> None:
        """Prove the bytes are exactly one `message_name` (no truncation, no trailing bytes); RosError says why
        not. Walks the length prefixes only (bridge.layout), ~1 µs for a JointState instead of ~4 µs for a genpy
        deserialize, which would also need a bounds-checking wrapper (~11 µs) to catch truncated strings."""
        layout = self._layouts.get(message_name)
        if layout is None:
            layout = self._layout(message_name, lambda: self.message_class(message_name))
        self._check(layout, message_name, payload)

    def validate_service(self, service_type: str, part: str, payload: bytes) -> None:
        """`validate` for one part ("request" or "response") of a `service_type` call."""
        key = f"{service_type} {part}"
        layout = self._layouts.get(key)
        if layout is None:
            generated = self._generated_service(service_type)
            layout = self._layout(key, lambda: getattr(generated, f"_{part}_class"))
        self._check(layout, key, payload)

    @staticmethod
    def _check(layout: Layout, what: str, payload: bytes) -> None:
        try:
            layout.check(payload)
        except LayoutError as error:
            raise RosError(f"payload of {len(payload)} bytes is not a valid {what}: {error}") from None

    def _layout(self, key: str, message_class: Callable[[], type[genpy.Message]]) -> Layout:
        cls = message_class()
        try:
            layout = Layout(cls, self.message_class)
        except (LayoutError, ValueError) as error:
            raise RosError(f"cannot validate {key}: {error}") from None
        with self._lock:
            return self._layouts.setdefault(key, layout)


def end_topic(topic: Any) -> None:
    """Unregister a rospy publisher or subscriber and, once rospy has closed the topic, free its poller's
    descriptor: rospy leaves it to the garbage collector, which may not run for a long time (an endpoint whose
    clients come and go would run out of descriptors)."""
    impl = topic.impl
    topic.unregister()
    poller: Any = getattr(getattr(impl, "connection_poll", None), "poller", None)
    if impl is not None and impl.closed and hasattr(poller, "close"):
        poller.close()


def _raw_class_like(generated: type[genpy.Message]) -> type[RawMessage]:
    return type(
        f"Raw{generated.__name__}",
        (RawMessage,),
        {
            "__slots__": (),
            "_type": generated._type,
            "_md5sum": generated._md5sum,
            "_full_text": generated._full_text,
            "_has_header": False,
        },
    )


# (topic, message bytes, the TCPROS connection header it came with: "callerid" names the publishing node)
MessageCallback = Callable[[str, bytes, Dict[str, str]], None]
ServiceHandler = Callable[[bytes], bytes]


class RosGraph:
    """The endpoint's node on the ROS graph. Thread-safe; every rospy object is created and destroyed here."""

    def __init__(self, types: TypeRegistry | None = None) -> None:
        self.types = types or TypeRegistry()
        self.master = MasterLink()
        self._diagnostics: Any = None  # (publisher, message classes) once made; False without diagnostic_msgs

    # --- node lifecycle -----------------------------------------------------------------------------------------
    @staticmethod
    def strip_remappings(argv: list[str]) -> list[str]:
        """argv without ROS's `name:=value` remappings (roslaunch adds __name:= and __log:=)."""
        return rospy.myargv(argv)

    @staticmethod
    def wait_for_master(poll_s: float = 0.5) -> None:
        """Block until the ROS master answers (what roslaunch's --wait means), saying once what it waits for."""
        if rosgraph.is_master_online():
            return
        print(f"waiting for the ROS master at {rosgraph.get_master_uri()}", file=sys.stderr, flush=True)
        while not rosgraph.is_master_online():
            time.sleep(poll_s)

    def init_node(self, name: str) -> None:
        # disable_signals: the endpoint installs its own SIGINT/SIGTERM handling and shuts rospy down itself.
        rospy.init_node(name, anonymous=False, disable_signals=True)
        _install_raw_reader()
        self.master.install()  # from now on, registrations never wait for the master (bridge.master)

    @staticmethod
    def get_param(name: str, default: Any) -> Any:
        return rospy.get_param(name, default)

    @staticmethod
    def set_param(name: str, value: Any) -> None:
        rospy.set_param(name, value)

    @staticmethod
    def shutdown(reason: str) -> None:
        rospy.signal_shutdown(reason)  # the master link unregisters the node (see MasterLink._clean_up)

    @staticmethod
    def is_shutdown() -> bool:
        return rospy.is_shutdown()

    @staticmethod
    def node_name() -> str:
        return rospy.get_name()

    def publish_diagnostics(self, statuses: List[Status]) -> None:
        """The statuses as one diagnostic_msgs/DiagnosticArray on /diagnostics (skipped, with one warning, where
        diagnostic_msgs is not installed)."""
        if self._diagnostics is None:
            try:
                from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
            except ImportError:
                log.warning("diagnostic_msgs is not installed: no /diagnostics")
                self._diagnostics = False
                return
            publisher = rospy.Publisher("/diagnostics", DiagnosticArray, queue_size=1)
            self._diagnostics = (publisher, DiagnosticArray, DiagnosticStatus, KeyValue)
        if self._diagnostics is False:
            return
        publisher, array, status, key_value = self._diagnostics
        message = array(status=[
            status(level=entry.level, name=entry.name, message=entry.message, hardware_id=entry.hardware_id,
                   values=[key_value(key=key, value=value) for key, value in entry.values])
            for entry in statuses
        ])
        message.header.stamp = rospy.Time.now()
        publisher.publish(message)

    def wait_registered(self, kind: str, name: str) -> None:
        """Until the master holds a new registration (see MasterLink.wait_registered), REGISTRATION_WAIT_S at most:
        called on the registering client's reader, outside the endpoint's lock."""
        self.master.wait_registered(kind, name, REGISTRATION_WAIT_S)

    @staticmethod
    def now() -> float:
        """ROS time in seconds (simulated time when /use_sim_time is set)."""
        return rospy.get_rostime().to_sec()

    @staticmethod
    def resolve(name: str) -> str:
        return rospy.resolve_name(name)

    # --- topics -----------------------------------------------------------------------------------------------
    # Type look-ups (the first of a type reads files; a publisher's may ask the graph) are separate from making
    # the rospy objects, so the endpoint never holds its lock while one takes long.
    def publisher_type(self, topic: str, message_name: str) -> type[RawMessage]:
        """The raw class to publish `message_name` on `topic` with. Where no package has the type, the last place
        to look is a publisher of the topic already on the graph: it states the full definition."""
        try:
            return self.types.raw_message_class(message_name)
        except RosError as unknown:
            stated = self.definition_from_publishers(topic)
            if stated is None or stated[0] != message_name:
                raise RosError(f"{unknown}; and no publisher of {topic} on the graph states it") from None
            self.types.learn(message_name, stated[1])
            return self.types.raw_message_class(message_name)

    def subscriber_type(self, message_name: str) -> Tuple[Optional[type[RawMessage]], Optional[str]]:
        """The raw class to subscribe with, or None and why there is none (then only messages whose publisher says
        they are `message_name` are passed on, see make_subscriber)."""
        try:
            return self.types.raw_message_class(message_name), None
        except RosError as unknown:
            return None, str(unknown)

    def service_type(self, service_type: str) -> Any:
        return self.types.raw_service_class(service_type)

    @staticmethod
    def make_publisher(topic: str, raw: type[RawMessage], queue_size: int, latch: bool,
                       max_queue_bytes: int) -> RawPublisher:
        # queue_size=None: rospy's synchronous publisher; RawPublisher's own pump thread and queue (of the
        # client's queue_size, at least 1) keep client threads from ever waiting on ROS subscribers.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SyntaxWarning)  # rospy's "queue_size not specified" warning
            publisher = rospy.Publisher(topic, raw, queue_size=None, latch=latch, tcp_nodelay=True)
        return RawPublisher(publisher, raw, raw._type, queue_size, max_queue_bytes)

    def make_subscriber(self, topic: str, raw: Optional[type[RawMessage]], message_name: str,
                        callback: MessageCallback) -> Any:
        """A subscriber of `raw` (from subscriber_type); without one, of whatever publishers say is
        `message_name`."""
        if raw is None:
            return self._subscribe_untyped(topic, message_name, callback)
        # tcp_nodelay: a 1 kHz stream must not wait for Nagle; buff_size large enough for big messages.
        return rospy.Subscriber(
            topic, raw, lambda msg: callback(topic, msg._buff, msg._connection_header),
            tcp_nodelay=True, buff_size=SUBSCRIBER_READ_BYTES,
        )

    @staticmethod
    def _subscribe_untyped(topic: str, message_name: str, callback: MessageCallback) -> Any:
        """A type with no class anywhere: bytes need none. Subscribe like rospy.AnyMsg (type and md5sum "*"),
        and pass on only messages whose connection header says they are `message_name`."""
        mismatches: list = []

        def deliver(msg: Any) -> None:
            header = msg._connection_header
            if header.get("type") == message_name:
                callback(topic, msg._buff, header)
            elif not mismatches:
                mismatches.append(header.get("type"))
                log.warning("%s carries %s, not the %s a client subscribed to: not forwarded", topic,
                            header.get("type"), message_name)

        return rospy.Subscriber(topic, RawMessage, deliver, tcp_nodelay=True, buff_size=SUBSCRIBER_READ_BYTES)

    @staticmethod
    def definition_from_publishers(topic: str) -> Optional[Tuple[str, str]]:
        """(type, full definition) as a publisher of `topic` on the graph states them in its TCPROS connection
        header (rostopic's way to know a type); None when no publisher answers."""
        me = rospy.get_name()
        try:
            publishers, _, _ = call_master("getSystemState", me)
            nodes: List[str] = next((nodes for name, nodes in publishers if name == topic), [])
            apis = [call_master("lookupNode", me, node) for node in nodes if node != me]
        except MasterError:
            return None
        for api in apis:
            try:
                answer: Any = timed_proxy(api).requestTopic(me, topic, [["TCPROS"]])
                code, _, protocol = answer
                if code != 1 or not protocol or protocol[0] != "TCPROS":
                    continue
                with socket.create_connection((str(protocol[1]), int(protocol[2])), timeout=2.0) as sock:
                    sock.sendall(rosgraph.network.encode_ros_handshake_header(
                        {"callerid": me, "topic": topic, "md5sum": "*", "type": "*", "message_definition": ""}
                    ))
                    header = rosgraph.network.read_ros_handshake_header(sock, io.BytesIO(), 65536)
            except (OSError, xmlrpc.client.Error, rosgraph.network.ROSHandshakeException):
                continue
            if header.get("type") and header.get("message_definition"):
                return header["type"], header["message_definition"]
        return None

    def topic_types(self) -> tuple[list[str], list[str]]:
        """All topics the master knows (published or subscribed) and their types, as parallel lists; MasterError
        (an OSError) when the master does not answer in time."""
        pairs = sorted(call_master("getTopicTypes", rospy.get_name()))
        return [name for name, _ in pairs], [type_name for _, type_name in pairs]

    # --- services ---------------------------------------------------------------------------------------------
    @staticmethod
    def make_service_proxy(service: str, raw: Any, max_response_bytes: int) -> RawServiceProxy:
        return RawServiceProxy(raw, service, max_response_bytes)

    @staticmethod
    def make_service(service: str, raw: Any, handler: ServiceHandler) -> Any:
        response_class = raw._response_class

        def handle(request: RawMessage) -> RawMessage:
            return response_class(handler(request._buff))

        return rospy.Service(service, raw, handle)


def read_raw_messages(buffer: io.BytesIO, messages: List[RawMessage], sock: socket.socket,
                      raw: type[RawMessage]) -> bool:
    """What rospy's deserialize_messages does with its read buffer (every complete TCPROS message out of `buffer`
    into `messages`, the rest kept), for raw classes and with less copying: a large message whose first bytes are
    in the buffer is read from `sock` straight into a buffer of its size, which is what is delivered (a bytearray).
    rospy's way copies each message three times or more on the way (its read buffer grows by reallocation, the
    message is cut out of it, the buffer is shrunk again): for a 2.7 MB camera image, that was most of the
    endpoint's work. Returns whether a message was read straight from the socket. Raises TransportTerminated when
    the publisher goes, as rospy's reads do."""
    end = buffer.tell()
    position = 0
    read_large = False
    with buffer.getbuffer() as view:
        while end - position >= 4:
            (size,) = _U32.unpack_from(view, position)
            start, stop = position + 4, position + 4 + size
            if stop <= end:
                messages.append(raw(bytes(view[start:stop])))
                position = stop
                continue
            if LARGE_PAYLOAD_BYTES <= size <= DIRECT_RECEIVE_MAX_BYTES:
                payload = bytearray(size)
                payload[: end - start] = view[start:end]
                _receive_into(sock, memoryview(payload)[end - start :])
                messages.append(raw(payload))  # type: ignore[arg-type]  # bytes-like: framed and compared only
                position = end
                read_large = True
            break
        if not position:  # nothing taken (a message still coming): the buffer stays as it is, as rospy leaves it
            return read_large
        rest = bytes(view[position:end])
    buffer.seek(0)
    buffer.truncate()
    buffer.write(rest)
    return read_large


def next_read_size(read_size: int, buffered: int, read_large: bool) -> int:
    """rospy's next read size for a subscriber connection that read with `read_size`, after read_raw_messages took
    what `buffered` bytes held (`read_large`: a message came straight from the socket). See SUBSCRIBER_READ_BYTES."""
    if read_large:
        return SUBSCRIBER_READ_BYTES
    if buffered >= read_size:  # the last read came full: more is waiting than a read takes
        return FLOOD_READ_BYTES
    return read_size


def _receive_into(sock: socket.socket, view: memoryview) -> None:
    while view:
        try:
            received = sock.recv_into(view)
        except OSError as error:
            raise TransportTerminated(f"receiving from the publisher failed: {error}") from None
        if not received:
            raise TransportTerminated("the publisher closed the connection")
        view = view[received:]


def _install_raw_reader() -> None:
    """rospy's subscriber connections of raw classes read with read_raw_messages, with a read size that follows the
    traffic (next_read_size; the endpoint's own process: every other class keeps rospy's way). Messages read
    straight from the socket are not in rospy's byte statistics."""
    subscriber_protocol = rospy.impl.tcpros_pubsub.TCPROSSub
    rospy_read = subscriber_protocol.read_messages
    if getattr(rospy_read, "reads_raw", False):
        return

    def read_messages(protocol: Any, buffer: io.BytesIO, messages: list, sock: socket.socket) -> None:
        raw = protocol.recv_data_class
        if protocol.queue_size is None and isinstance(raw, type) and issubclass(raw, RawMessage):
            buffered = buffer.tell()
            read_large = read_raw_messages(buffer, messages, sock, raw)
            protocol.buff_size = next_read_size(protocol.buff_size, buffered, read_large)
        else:
            rospy_read(protocol, buffer, messages, sock)

    read_messages.reads_raw = True  # type: ignore[attr-defined]
    subscriber_protocol.read_messages = read_messages


class RawPublisher:
    """A ROS publisher fed by clients' reader threads, which must never block on ROS subscribers for long.

    Two ways to ROS, one writer at a time (`_write_lock`), so messages keep their order:
    - direct: a message that arrived alone (not in a burst), with nothing queued and every subscriber connection's
      sent bytes acknowledged, is written at once on the reader's thread, when each connection's send buffer takes
      it whole (bridge.sockets.takes_whole: any small message; a camera image once the kernel has grown the buffer
      for it). That saves the pump's wake-up, one thread hop of every 1 kHz round trip and ~0.15 ms of a 1 MiB one,
      and never blocks.
    - queued: everything else goes to a bounded drop-oldest queue of the client's `queue_size` (as rospy's queued
      publisher keeps per subscriber). One pump thread per topic drains it a batch at a time into rospy's
      *synchronous* publisher: one hand-off per batch instead of rospy's wake-up, sleep(0) and socket write per
      message. A batch goes to each subscriber connection as one write of back-to-back TCPROS frames
      (u32 length + bytes), see `_write_batch`.

    Flow control: when the queue is full, `publish` waits up to PUBLISH_WAIT_S for the pump to make room, so the
    client's reader (and, through TCP, the client) is slowed to the pace of the ROS subscribers instead of having
    its messages dropped, as a rospy node with a synchronous publisher would be. Measured: without it, a client
    flooding at 230k msg/s made the endpoint spend its GIL on frames it then dropped, and only 86k msg/s reached
    ROS. A ROS side that makes no room within that time is stalled: the queue then drops oldest at once (the
    client is told by __warn) until the pump completes a write again, so a stuck ROS subscriber costs the client
    one wait, never its other traffic. A ROS subscriber that stops reading altogether is cut off after
    SUBSCRIBER_STALL_S (rospy's synchronous publisher would wait for it forever, and the topic's other
    subscribers with it); the others get every batch at once meanwhile.
    """

    def __init__(self, publisher: Any, raw_class: type[RawMessage], message_name: str, queue_size: int,
                 max_queue_bytes: int) -> None:
        self._publisher = publisher
        self._raw_class = raw_class
        self._latch = bool(publisher.impl.is_latch)
        self.message_name = message_name
        self.queue = OutgoingQueue(max(queue_size, 1), max_queue_bytes)
        self._write_lock = threading.Lock()  # held while writing to the subscriber connections
        self._stalled = False  # set by publish when no room came in time; cleared by the pump's next write
        self.published = 0  # client messages handed over (for /diagnostics)
        self._pump = threading.Thread(target=self._pump_loop, name=f"pump {publisher.resolved_name}", daemon=True)
        self._pump.start()

    def publish(self, payloads: list[bytes], alone: bool = False) -> int:
        """Send messages to ROS, in order: those of one client read (one lock hand-off for all of them). A message
        that came `alone` goes directly if ROS keeps up; the rest through the queue, waiting for room unless the
        ROS side is stalled (see the class). Returns how many older queued messages were dropped to make room."""
        self.published += len(payloads)
        if alone and len(payloads) == 1 and not self._latch and self._write_lock.acquire(blocking=False):
            try:
                if not self.queue and self._subscribers_take_whole(len(payloads[0])):
                    self._write_batch(payloads)
                    return 0
            finally:
                self._write_lock.release()
        dropped = self.queue.put_many(payloads, wait_s=0.0 if self._stalled else PUBLISH_WAIT_S)
        if dropped:
            self._stalled = True
        return dropped

    def _subscribers_take_whole(self, size: int) -> bool:
        """Every subscriber connection takes a message of `size` bytes whole at once (see the class)."""
        impl = self._publisher.impl
        if impl is None:
            return False
        small = size + 4 <= DIRECT_PUBLISH_MAX_BYTES
        for connection in impl.connections:
            sock = getattr(connection, "socket", None)
            if sock is None or unsent_bytes(sock) or not (small or takes_whole(sock, size + 4)):
                return False
        return True

    def connections(self) -> int:
        """ROS subscribers connected."""
        return int(self._publisher.get_num_connections())

    def unregister(self) -> None:
        """The pump writes what is queued, then takes the topic off the graph (never waited for here: the caller
        holds the endpoint's lock, and a write to a stalled subscriber may take long)."""
        self.queue.close()

    def _pump_loop(self) -> None:
        while True:
            if not self.queue.wait():  # closed, and everything queued is written
                end_topic(self._publisher)
                return
            with self._write_lock:
                self._write_queued()

    def _write_queued(self) -> None:
        batch = self.queue.take_all(timeout=0)
        if batch:
            try:
                if self._latch:
                    # Latched topics take rospy's own path, which also records the latch for late subscribers.
                    for payload in batch:
                        self._publisher.publish(self._raw_class(payload))
                else:
                    self._write_batch(batch)
                self._stalled = False
            except Exception:  # rospy shutting down, topic closed: a lost batch, never a dead pump
                if not rospy.is_shutdown():
                    log.exception("publishing on %s failed", self._publisher.resolved_name)

    def _write_batch(self, payloads: list[bytes]) -> None:
        """What rospy's _PublisherImpl.publish does for one message (same lock, same stats; a connection whose write
        fails is closed, and rospy then removes it), done once for the whole batch, and without letting one ROS
        subscriber that stopped reading hold up the others: see bridge.sockets.send_to_all and SUBSCRIBER_STALL_S."""
        impl = self._publisher.impl
        if impl is None or impl.closed:
            return
        pieces = _tcpros_pieces(payloads)
        size = sum(len(piece) for piece in pieces)
        failed: Dict[Any, str] = {}
        impl.acquire()
        try:
            if impl.closed or not impl.has_connections() or rospy.is_shutdown():
                return
            # rospy replaces impl.connections on change, never mutates it
            connections = [c for c in impl.connections if not c.done and c.socket is not None]
            for piece in pieces:
                writing = [c for c in connections if c not in failed]
                for index, why in send_to_all([c.socket for c in writing], piece, SUBSCRIBER_STALL_S).items():
                    failed[writing[index]] = why
            for connection in connections:
                if connection not in failed:
                    connection.stat_bytes += size
                    connection.stat_num_msg += len(payloads)
            impl.seq += len(payloads)
            impl.message_data_sent += size
        finally:
            impl.release()
        for connection, why in failed.items():
            log.warning("ROS subscriber %s of %s: %s; connection closed (a rospy subscriber connects again)",
                        connection.endpoint_id, impl.resolved_name, why)
            try:
                connection.close()  # calls back into impl.remove_connection
            except Exception:
                pass


def _tcpros_pieces(payloads: List[bytes]) -> List[bytes]:
    """The TCPROS frames (u32 length + bytes) of `payloads`, back to back, as few pieces to write: small messages
    joined with their length prefixes, a large one (LARGE_PAYLOAD_BYTES or more) written as it is, after its prefix,
    so its bytes are not copied once more."""
    pieces: List[bytes] = []
    joined: List[bytes] = []
    for payload in payloads:
        joined.append(_U32.pack(len(payload)))
        if len(payload) < LARGE_PAYLOAD_BYTES:
            joined.append(payload)
        else:
            pieces += (b"".join(joined), payload)
            joined = []
    if joined:
        pieces.append(b"".join(joined))
    return pieces


class _Abandoned(Exception):
    """The call's client has gone: nobody waits for the answer any more."""


class RawServiceProxy:
    """Calls of one ROS service with request bytes, answered with response bytes; every call ends by its deadline.

    rospy's ServiceProxy waits for an answer with no limit (its timeout bounds only the wait for the service to
    appear), on a socket the caller cannot close: a service that never answers holds the calling thread forever.
    This speaks TCPROS itself (one connection per call, as rospy's non-persistent proxy does), with the deadline on
    every step, and gives up early when `abandoned` is set (the client left).
    """

    def __init__(self, raw_class: Any, service: str, max_response_bytes: int) -> None:
        self.service = service
        self.service_type: str = raw_class._type
        self._md5sum: str = raw_class._md5sum
        self._max_response_bytes = max_response_bytes

    def call(self, request: bytes, timeout: float, abandoned: threading.Event) -> bytes:
        """The response's bytes; RosError when the service is missing, fails, or does not answer within `timeout`
        seconds (the look-up included)."""
        deadline = time.monotonic() + timeout
        try:
            host, port = rospy.core.parse_rosrpc_uri(self._look_up(deadline, timeout, abandoned))
            with socket.create_connection((host, port), timeout=_remaining(deadline)) as sock:
                sock.sendall(rosgraph.network.encode_ros_handshake_header({
                    "callerid": rospy.get_caller_id(), "service": self.service, "md5sum": self._md5sum,
                    "type": self.service_type, "persistent": "0",
                }))
                size = _U32.unpack(_receive(sock, 4, deadline, abandoned))[0]
                if size > 65536:
                    raise RosError(f"service {self.service} sent a connection header of {size} bytes")
                header = rosgraph.network.decode_ros_handshake_header(
                    _U32.pack(size) + _receive(sock, size, deadline, abandoned))
                if "error" in header:
                    raise RosError(f"service {self.service} refused the call: {header['error']}")
                sock.sendall(_U32.pack(len(request)) + request)
                ok = _receive(sock, 1, deadline, abandoned)[0]
                size = _U32.unpack(_receive(sock, 4, deadline, abandoned))[0]
                if size > self._max_response_bytes:
                    raise RosError(f"service {self.service} answered with {size} bytes, more than the "
                                   f"{self._max_response_bytes} a frame may carry")
                body = _receive(sock, size, deadline, abandoned)
        except socket.timeout:
            raise RosError(f"service {self.service} did not answer within {timeout:g} s") from None
        except _Abandoned:
            raise RosError(f"service {self.service}: the call's client has gone") from None
        except (OSError, ValueError, rosgraph.network.ROSHandshakeException) as error:
            raise RosError(f"service {self.service} could not be called: {error}") from None
        if not ok:
            raise RosError(f"service {self.service} failed: {body.decode('utf-8', 'replace')}")
        return body

    def _look_up(self, deadline: float, timeout: float, abandoned: threading.Event) -> str:
        """The service's rosrpc URI, waiting for it to be advertised until the deadline."""
        while True:
            try:
                uri: str = call_master("lookupService", rospy.get_caller_id(), self.service,
                                       timeout_s=max(0.01, min(MASTER_TIMEOUT_S, _remaining(deadline))))
                return uri
            except MasterRefused:
                why = "is not available"  # not advertised (yet)
            except MasterError as error:
                why = f"could not be looked up: {error}"
            if abandoned.wait(min(SERVICE_POLL_S, _remaining(deadline))):
                raise _Abandoned()
            if time.monotonic() >= deadline:
                raise RosError(f"service {self.service} {why} (waited {timeout:g} s)")


def _remaining(deadline: float) -> float:
    remaining = deadline - time.monotonic()
    if remaining <= 0:
        raise socket.timeout()
    return remaining


def _receive(sock: socket.socket, size: int, deadline: float, abandoned: threading.Event) -> bytes:
    """Exactly `size` bytes; socket.timeout at the deadline, _Abandoned as soon as the client has gone (looked at
    every SERVICE_POLL_S)."""
    data = bytearray()
    while len(data) < size:
        if abandoned.is_set():
            raise _Abandoned()
        sock.settimeout(min(_remaining(deadline), SERVICE_POLL_S))
        try:
            chunk = sock.recv(min(size - len(data), 1 << 20))
        except socket.timeout:
            continue
        if not chunk:
            raise ConnectionResetError("the service closed the connection")
        data += chunk
    return bytes(data)
