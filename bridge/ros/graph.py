"""The endpoint's node on the ROS graph: node lifecycle, parameters, names, and every rospy publisher, subscriber,
service and proxy the endpoint makes, raw throughout (bridge.ros.raw_types). With the other modules of bridge.ros, the
only code of the endpoint that touches rospy.
"""

from __future__ import annotations

import io
import logging
import socket
import sys
import time
import warnings
import xmlrpc.client
from typing import Any, Callable, Dict

import rosgraph
import rosgraph.network
import rospy
import rospy.impl.tcpros_pubsub

from bridge.diagnostics import Status
from bridge.ros.master import MasterError, MasterLink, call_master, timed_proxy
from bridge.ros.peers import describe_peer, peer_links
from bridge.ros.publisher import RawPublisher
from bridge.ros.raw_types import RawMessage, RosError, TypeRegistry
from bridge.ros.reader import SUBSCRIBER_READ_BYTES, install_raw_reader
from bridge.ros.service_proxy import RawServiceProxy

log = logging.getLogger(__name__)

__all__ = ["REGISTRATION_WAIT_S", "MessageCallback", "ServiceHandler", "RosGraph"]

# How long a client's new registration may wait for the master to hold it before its next command runs.
REGISTRATION_WAIT_S = 1.0

# (topic, message bytes, the TCPROS connection header it came with: "callerid" names the publishing node)
MessageCallback = Callable[[str, bytes, Dict[str, str]], None]
ServiceHandler = Callable[[bytes], bytes]


def _serialized(msg: Any) -> bytes:
    """A decoded message's bytes. rospy hands one over in place of our raw class's when it subscribes to the topic
    itself in this process, with its own class: under /use_sim_time it takes /clock as rosgraph_msgs/Clock, and one
    subscription of a process has one class. (genpy serializes canonically: the bytes are those sent.)"""
    out = io.BytesIO()
    msg.serialize(out)
    return out.getvalue()


def _message_bytes(msg: Any) -> bytes:
    """A received message's bytes: as they came (our raw classes keep them), or serialized again (_serialized)."""
    try:
        return msg._buff  # type: ignore[no-any-return]
    except AttributeError:
        return _serialized(msg)


def _passing_bytes(topic: str, callback: MessageCallback) -> Callable[[Any], None]:
    """rospy's callback for `topic`: the message's bytes to `callback`. rospy hands over messages of the class the
    process's first subscription to the topic asked for: ours keep their bytes; another (rospy's own /clock under
    /use_sim_time) is serialized again. Decided once here: this runs for every message from ROS, and passing
    `msg._buff` on is all the usual case needs."""
    impl = rospy.topics.get_topic_manager().get_subscriber_impl(rospy.names.resolve_name(topic))
    if impl is None or issubclass(impl.data_class, RawMessage):
        return lambda msg: callback(topic, msg._buff, msg._connection_header)
    return lambda msg: callback(topic, _serialized(msg), msg._connection_header)


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
        install_raw_reader()
        self.master.install()  # from now on, registrations never wait for the master (bridge.ros.master)

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

    def publish_diagnostics(self, statuses: list[Status]) -> None:
        """The statuses as one diagnostic_msgs/DiagnosticArray on /diagnostics (skipped, with one warning, where
        diagnostic_msgs is not installed)."""
        if self._diagnostics is None:
            try:
                from diagnostic_msgs.msg import (
                    DiagnosticArray,
                    DiagnosticStatus,
                    KeyValue,
                )
            except ImportError:
                log.warning("diagnostic_msgs is not installed: no /diagnostics")
                self._diagnostics = False
                return
            publisher = rospy.Publisher("/diagnostics", DiagnosticArray, queue_size=1)
            self._diagnostics = (publisher, DiagnosticArray, DiagnosticStatus, KeyValue)
        if self._diagnostics is False:
            return
        publisher, array, status, key_value = self._diagnostics
        message = array(
            status=[
                status(
                    level=entry.level,
                    name=entry.name,
                    message=entry.message,
                    hardware_id=entry.hardware_id,
                    values=[key_value(key=key, value=value) for key, value in entry.values],
                )
                for entry in statuses
            ]
        )
        message.header.stamp = rospy.Time.now()
        publisher.publish(message)

    def wait_registered(self, kind: str, name: str) -> None:
        """Until the master holds a new registration (see MasterLink.wait_registered), REGISTRATION_WAIT_S at most:
        called on the registering client's reader, outside the endpoint's lock."""
        self.master.wait_registered(kind, name, REGISTRATION_WAIT_S)

    # The links of bridged topics to their ROS peers (bridge.ros.peers, judged by bridge.ros.peer_links)
    peer_links = staticmethod(peer_links)
    describe_peer = staticmethod(describe_peer)

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

    def subscriber_type(self, message_name: str) -> tuple[type[RawMessage] | None, str | None]:
        """The raw class to subscribe with, or None and why there is none (then only messages whose publisher says
        they are `message_name` are passed on, see make_subscriber)."""
        try:
            return self.types.raw_message_class(message_name), None
        except RosError as unknown:
            return None, str(unknown)

    def service_type(self, service_type: str) -> Any:
        return self.types.raw_service_class(service_type)

    @staticmethod
    def make_publisher(
        topic: str, raw: type[RawMessage], queue_size: int, latch: bool, max_queue_bytes: int
    ) -> RawPublisher:
        # queue_size=None: rospy's synchronous publisher; RawPublisher's own pump thread and queue (of the
        # client's queue_size, at least 1) keep client threads from ever waiting on ROS subscribers.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SyntaxWarning)  # rospy's "queue_size not specified" warning
            publisher = rospy.Publisher(topic, raw, queue_size=None, latch=latch, tcp_nodelay=True)
        return RawPublisher(publisher, raw, raw._type, queue_size, max_queue_bytes)

    def make_subscriber(
        self, topic: str, raw: type[RawMessage] | None, message_name: str, callback: MessageCallback
    ) -> Any:
        """A subscriber of `raw` (from subscriber_type); without one, of whatever publishers say is
        `message_name`."""
        if raw is None:
            return self._subscribe_untyped(topic, message_name, callback)
        # tcp_nodelay: a 1 kHz stream must not wait for Nagle; buff_size large enough for big messages.
        return rospy.Subscriber(
            topic, raw, _passing_bytes(topic, callback), tcp_nodelay=True, buff_size=SUBSCRIBER_READ_BYTES
        )

    @staticmethod
    def _subscribe_untyped(topic: str, message_name: str, callback: MessageCallback) -> Any:
        """A type with no class anywhere: bytes need none. Subscribe like rospy.AnyMsg (type and md5sum "*"),
        and pass on only messages whose connection header says they are `message_name`."""
        mismatches: list = []

        def deliver(msg: Any) -> None:
            header = msg._connection_header
            if header.get("type") == message_name:
                callback(topic, _message_bytes(msg), header)
            elif not mismatches:
                mismatches.append(header.get("type"))
                log.warning(
                    "%s carries %s, not the %s a client subscribed to: not forwarded",
                    topic,
                    header.get("type"),
                    message_name,
                )

        return rospy.Subscriber(topic, RawMessage, deliver, tcp_nodelay=True, buff_size=SUBSCRIBER_READ_BYTES)

    @staticmethod
    def definition_from_publishers(topic: str) -> tuple[str, str] | None:
        """(type, full definition) as a publisher of `topic` on the graph states them in its TCPROS connection
        header (rostopic's way to know a type); None when no publisher answers."""
        me = rospy.get_name()
        try:
            publishers, _, _ = call_master("getSystemState", me)
            nodes: list[str] = next((nodes for name, nodes in publishers if name == topic), [])
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
                    sock.sendall(
                        rosgraph.network.encode_ros_handshake_header(
                            {"callerid": me, "topic": topic, "md5sum": "*", "type": "*", "message_definition": ""}
                        )
                    )
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
