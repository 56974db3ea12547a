"""Bad input, broken framing, slow readers and reconnects: one client's trouble never reaches another client."""

from __future__ import annotations

import itertools
import json
import struct
import time
from pathlib import Path

import pytest
from std_msgs.msg import String

from bridge import protocol
from bridge.protocol import encode_frame
from measuring.procfs import MiB, rss_bytes
from tests.integration.bridge_helpers import (
    Inbox,
    RawConnection,
    RosInbox,
    bridge,  # noqa: F401 - module-scoped endpoint fixture
    serialize,
    start_endpoint,
    tcp_client,
    unique,
    wait_new_subscriber,
    wait_subscribers,
)
from tests.rosenv import free_port, wait_for

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))

_observer_messages = itertools.count()


class Observer:
    """A well-behaved TcpClient subscribed to a topic; `check()` proves it is still served, on its first connection."""

    def __init__(self, rospy, port: int) -> None:
        self.topic = unique("observer")
        self.publisher = rospy.Publisher(self.topic, String, queue_size=10)
        self.inbox = Inbox()
        self.client = tcp_client(port, reconnect=False)
        self.client.subscribe(self.topic, "std_msgs/String", self.inbox)
        self.client.topic_list()
        wait_subscribers(self.publisher)

    def check(self) -> None:
        text = f"still here {next(_observer_messages)}"
        self.publisher.publish(String(text))
        wait_for(lambda: serialize(String(text)) in self.inbox.snapshot(), 10, f"observer to receive {text!r}")
        assert self.client.is_connected and self.client.connections == 1 and self.client.errors == []


@pytest.fixture(scope="module")
def observer(bridge, ros_node):
    watcher = Observer(ros_node, bridge.port)
    yield watcher
    watcher.client.close()


def u32(value: int) -> bytes:
    return struct.pack("<I", value)


def syscommand(name: str, payload: bytes) -> bytes:
    return protocol.encode_frame(name, payload)


# (what is sent, fragments the __error must contain). Framing stays intact: the connection must stay open.
BAD_INPUTS = {
    "unknown command": (syscommand("__frobnicate", b"{}"), ["unknown system command", "__frobnicate"]),
    "client handshake": (syscommand("__handshake", b'{"version":"v0.7.0"}'), ["unknown system command"]),
    "malformed JSON": (syscommand("__subscribe", b'{"topic": "/x",'), ["__subscribe", "malformed JSON"]),
    "non-object JSON": (syscommand("__publish", b"[1, 2]"), ["__publish", "JSON object"]),
    "non-UTF-8 JSON": (syscommand("__subscribe", b"\xff\xfe"), ["__subscribe", "UTF-8"]),
    "missing field": (syscommand("__subscribe", b'{"topic":"/x"}'), ["__subscribe", "missing field 'message_name'"]),
    "negative queue size": (
        syscommand("__subscribe", b'{"topic":"/x","message_name":"std_msgs/String","queue_size":-1}'),
        ["__subscribe", "'queue_size'", "-1"],
    ),
    "bool as int": (syscommand("__request", b'{"srv_id":true}'), ["__request", "'srv_id'", "integer"]),
    "bad topic": (
        syscommand("__subscribe", b'{"topic":"/with space","message_name":"std_msgs/String"}'),
        ["__subscribe", "'topic'", "/with space"],
    ),
    "bad message_name": (
        syscommand("__subscribe", b'{"topic":"/x","message_name":"NoPackage"}'),
        ["__subscribe", "'message_name'", "NoPackage"],
    ),
    "unknown message type": (
        syscommand("__publish", b'{"topic":"/bt_unknown_type","message_name":"no_such_pkg/Nope"}'),
        ["unknown message type", "no_such_pkg/Nope", "ROS_PACKAGE_PATH", "no publisher of /bt_unknown_type"],
    ),
    "unknown service type": (
        syscommand("__ros_service", b'{"topic":"/bt_unknown_srv","message_name":"std_srvs/NoSuchSrv"}'),
        ["unknown service type", "std_srvs/NoSuchSrv"],
    ),
    # Names the master's XML-RPC cannot carry: rospy would retry their registration forever (the one-frame wedge)
    "control character in a subscribed topic": (
        syscommand("__subscribe", b'{"topic":"/bt_\\u0001x","message_name":"std_msgs/String"}'),
        ["__subscribe", "'topic'", "U+0001"],
    ),
    "escape in a published topic": (
        syscommand("__publish", b'{"topic":"/bt_\\u001bx","message_name":"std_msgs/String"}'),
        ["__publish", "'topic'", "U+001B"],
    ),
    "U+FFFF in a service name": (
        syscommand("__unity_service", b'{"topic":"/bt_\\uffffx","message_name":"std_srvs/Trigger"}'),
        ["__unity_service", "'topic'", "U+FFFF"],
    ),
    "topic longer than a destination": (
        syscommand("__subscribe", b'{"topic":"/' + b"a" * 1024 + b'","message_name":"std_msgs/String"}'),
        ["__subscribe", "'topic'", "1025 bytes long"],
    ),
    "deeply nested JSON": (syscommand("__subscribe", b"[" * 50_000 + b"]" * 50_000), ["__subscribe", "nested"]),
    "importable module as a type": (
        syscommand("__publish", b'{"topic":"/bt_zen","message_name":"this/Foo"}'),
        ["this/Foo", "not a ROS package", "nothing was imported"],
    ),
    "non-UTF-8 destination": (u32(4) + b"/a\xff\xfe" + u32(2) + b"{}", ["not valid UTF-8"]),
    "topic never registered": (protocol.encode_frame("/bt_nobody", b"\0" * 4), ["/bt_nobody", "__publish"]),
}


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_input_gets_a_named_error_and_the_connection_is_kept(bridge, observer, case: str) -> None:
    data, fragments = BAD_INPUTS[case]
    with RawConnection(bridge.port) as client:
        for piece in (data[:3], data[3:]):  # fragmented on purpose
            client.send(piece)
        client.expect_error(*fragments)
        client.sync()  # still framed, still served
        assert len(client.errors()) == 1, client.errors()
    with RawConnection(bridge.port) as newcomer:  # still accepting: a handshake, and a command answered
        newcomer.sync()
    observer.check()


def test_a_type_name_never_imports_a_module_that_is_not_a_ros_message_package(bridge) -> None:
    """`this` prints the Zen of Python when imported: any import-time code would run the same way."""
    with RawConnection(bridge.port) as client:
        for command in ("__publish", "__subscribe", "__ros_service", "__unity_service"):
            client.command(command, topic=unique("zen"), message_name="this/Foo")
        client.sync()
    assert "Beautiful is better than ugly" not in bridge.output()


def test_undeserializable_payload_is_refused_and_not_published(bridge, ros_node, observer) -> None:
    topic = unique("garbage")
    inbox = RosInbox(ros_node, topic)
    with RawConnection(bridge.port) as client:
        client.register_publisher(topic, "std_msgs/String")
        client.sync()
        inbox.wait_connected()
        client.send_frame(topic, u32(100) + b"short")  # claims a 100-byte string, has 5
        assert "9 bytes" in client.expect_error(topic, "std_msgs/String", "not published")
        client.send_frame(topic, serialize(String("trailing")) + b"\0")
        assert "trailing" in client.expect_error(topic, "std_msgs/String", "not published")
        client.send_frame(topic, serialize(String("good")))
        assert inbox.wait_count(1) == [serialize(String("good"))]
        client.sync()
        assert inbox.snapshot() == [serialize(String("good"))]
    inbox.close()
    observer.check()


def test_type_conflict_on_a_bridged_topic_is_refused(bridge, observer) -> None:
    topic = unique("conflict")
    with RawConnection(bridge.port) as client:
        client.subscribe(topic, "std_msgs/String")
        client.subscribe(topic, "sensor_msgs/JointState")
        assert "std_msgs/String" in client.expect_error(topic, "already bridged")
        client.register_publisher(topic + "_pub", "std_msgs/String")
        client.register_publisher(topic + "_pub", "std_msgs/Bool")
        client.expect_error(topic + "_pub", "already published")
        client.sync()
    observer.check()


@pytest.mark.parametrize(
    "prefix",
    [
        pytest.param(u32(8) + b"/payload" + u32(0xFFFFFFF0), id="4GiB-payload"),
        pytest.param(u32(0xFFFFFFFF), id="4GiB-destination"),
        pytest.param(u32(2048), id="2KiB-destination"),
    ],
)
def test_oversized_length_gets_an_error_and_closes_only_that_connection(bridge, observer, prefix: bytes) -> None:
    with RawConnection(bridge.port) as client:
        client.sync()
        started = time.monotonic()
        client.send(prefix)
        assert "exceeds the limit" in client.expect_error("framing lost")
        client.wait_closed(timeout=5)
        assert time.monotonic() - started < 3
    observer.check()
    with RawConnection(bridge.port) as newcomer:  # the endpoint still accepts and serves new clients
        newcomer.sync()


def test_many_bad_clients_at_once_do_not_disturb_a_good_one(bridge, observer) -> None:
    clients = [RawConnection(bridge.port) for _ in range(5)]
    try:
        for index, client in enumerate(clients):
            client.send(syscommand("__subscribe", b"{") if index % 2 else u32(0xFFFFFFF0))
        for index, client in enumerate(clients):
            if index % 2:
                client.expect_error("malformed JSON")
                client.sync()
            else:
                client.expect_error("framing lost")
                client.wait_closed(timeout=5)
        observer.check()
    finally:
        for client in clients:
            client.close()


def _flood_count(message_bytes: int) -> int:
    """Enough messages to overflow the kernel's largest send buffer plus the endpoint's queue (bounded)."""
    try:
        send_buffer_max = int(Path("/proc/sys/net/ipv4/tcp_wmem").read_text().split()[2])
    except (OSError, ValueError, IndexError):
        send_buffer_max = 4 << 20
    return min(1500, max(300, (2 * send_buffer_max + (8 << 20)) // message_bytes + 1))


def test_slow_reader_loses_old_messages_and_others_stay_served(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--queue-frames", "16")
    topic, side_topic = unique("flood"), unique("flood_side")
    publisher = ros_node.Publisher(topic, String, queue_size=500)
    side_publisher = ros_node.Publisher(side_topic, String, queue_size=10)
    big = "x" * 64 * 1024
    count = _flood_count(len(big))  # far more than the socket buffers and the 16-frame queue hold
    try:
        slow = RawConnection(endpoint.port, rcvbuf=4096)
        slow.subscribe(topic, "std_msgs/String")
        slow.sync()
        fast = tcp_client(endpoint.port, reconnect=False)
        fast_inbox, side_inbox = Inbox(), Inbox()
        fast.subscribe(topic, "std_msgs/String", fast_inbox)
        fast.subscribe(side_topic, "std_msgs/String", side_inbox)
        fast.topic_list()
        wait_subscribers(publisher)
        wait_subscribers(side_publisher)
        last = serialize(String(big + " last"))
        for index in range(count - 1):
            publisher.publish(String(big + f" {index}"))
        publisher.publish(String(big + " last"))
        # The slow client reads nothing meanwhile; the fast one gets the newest message and more traffic.
        wait_for(lambda: last in fast_inbox.snapshot(), 30, "the fast client to get the last flood message")
        side_publisher.publish(String("side"))
        side_inbox.wait_count(1)
        fast.topic_list(timeout=5)
        rss = rss_bytes(endpoint.process.pid)
        assert rss < 400 * MiB, f"endpoint RSS {rss / MiB:.0f} MiB with a stalled client"
        # Now the slow client reads: it is told how many messages it lost, and the newest one was kept.
        warning = slow.wait_command("__warn", timeout=30)["text"]
        assert "dropped" in warning and "too slowly" in warning
        if last not in slow.messages(topic):  # the warning goes out after the batch it reports on
            slow.wait_frame(lambda f: f.payload == last, "the last flood message", timeout=30)
        received = len(slow.messages(topic))
        dropped = sum(
            int(text.split(":", 1)[1].split()[0])
            for text in (json.loads(f.payload)["text"] for f in slow.received if f.destination == "__warn")
        )
        assert 0 < received < count and dropped > 0
        assert received + dropped <= count
        slow.sync()
        assert slow.errors() == [] and fast.errors == [] and fast.connections == 1
        slow.close()
        fast.close()
    finally:
        publisher.unregister()
        side_publisher.unregister()
        assert endpoint.stop() is not None


def test_client_reconnects_after_its_connection_is_cut_and_reregisters(bridge, ros_node, observer) -> None:
    topic, pub_topic = unique("cut_sub"), unique("cut_pub")
    publisher = ros_node.Publisher(topic, String, queue_size=10)
    ros_inbox = RosInbox(ros_node, pub_topic)
    inbox = Inbox()
    with tcp_client(bridge.port) as client:
        client.subscribe(topic, "std_msgs/String", inbox)
        client.register_publisher(pub_topic, "std_msgs/String")
        client.topic_list()
        wait_subscribers(publisher)
        before_cut = list(publisher.impl.connections)
        client.send_raw(u32(0xFFFFFFFF))  # the endpoint closes this connection; the client reconnects
        wait_for(lambda: client.connections >= 2 and client.is_connected, 10, "the client to reconnect")
        assert any("framing lost" in text for text in client.errors)
        client.topic_list()  # the re-sent registrations have been handled
        wait_new_subscriber(publisher, before_cut)  # the endpoint's new subscription, not the ended one
        ros_inbox.wait_connected()
        publisher.publish(String("after reconnect"))
        assert inbox.wait_count(1) == [serialize(String("after reconnect"))]
        client.publish(pub_topic, serialize(String("from the client")))
        assert ros_inbox.wait_count(1) == [serialize(String("from the client"))]
    ros_inbox.close()
    observer.check()


def test_client_reconnects_after_the_endpoint_restarts(roscore, ros_node, tmp_path: Path) -> None:
    port = free_port()
    topic, pub_topic = unique("restart_sub"), unique("restart_pub")
    publisher = ros_node.Publisher(topic, String, queue_size=10)
    ros_inbox = RosInbox(ros_node, pub_topic)
    inbox = Inbox()
    first = start_endpoint(roscore, tmp_path, "--tcp-port", str(port))
    second = None
    try:
        client = tcp_client(port)
        client.subscribe(topic, "std_msgs/String", inbox)
        client.register_publisher(pub_topic, "std_msgs/String")
        client.topic_list()
        wait_subscribers(publisher)
        publisher.publish(String("first endpoint"))
        inbox.wait_count(1)
        before_restart = list(publisher.impl.connections)
        assert first.stop() == 0
        wait_for(lambda: not client.is_connected, 10, "the client to notice the endpoint is gone")
        second = start_endpoint(roscore, tmp_path, "--tcp-port", str(port))
        wait_for(lambda: client.connections == 2 and client.is_connected, 15, "the client to reconnect")
        client.topic_list()
        wait_new_subscriber(publisher, before_restart)  # the second endpoint's, not the stopped one's
        publisher.publish(String("second endpoint"))
        assert inbox.wait_count(2)[1] == serialize(String("second endpoint"))
        ros_inbox.wait_connected()
        client.publish(pub_topic, serialize(String("hello again")))
        assert ros_inbox.wait_count(1) == [serialize(String("hello again"))]
        client.close()
    finally:
        first.stop()
        if second is not None:
            second.stop()
        publisher.unregister()
        ros_inbox.close()


def test_ros_subscribers_stay_connected_while_a_client_reconnects(bridge, ros_node) -> None:
    """The endpoint keeps a topic advertised while its client reconnects, so the first message after the
    reconnect reaches ROS subscribers (re-advertising would make them reconnect, losing what comes meanwhile)."""
    topic = unique("kept_advertised")
    ros_inbox = RosInbox(ros_node, topic)
    with tcp_client(bridge.port) as client:
        client.register_publisher(topic, "std_msgs/String")
        client.topic_list()
        ros_inbox.wait_connected()
        for round_ in range(3):
            connections = client.connections
            client.send_raw(u32(0xFFFFFFFF))  # cut; the client reconnects and re-sends __publish
            wait_for(
                lambda before=connections: client.connections > before and client.is_connected,
                10,
                "the client to reconnect",
            )
            client.topic_list()
            client.publish(topic, serialize(String(f"right after reconnect {round_}")))
            assert ros_inbox.wait_count(round_ + 1, timeout=5)[-1] == serialize(
                String(f"right after reconnect {round_}")
            )
    ros_inbox.close()


def test_a_departed_clients_publisher_ends_after_the_grace_period(roscore, ros_node, tmp_path: Path) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--publisher-grace", "1", name="grace_endpoint")
    topic = unique("grace")
    try:
        with RawConnection(endpoint.port) as client:
            client.register_publisher(topic, "std_msgs/String")
            client.sync()
            wait_for(lambda: roscore.publishers(topic) == ["/grace_endpoint"], 10, "the client's publisher")
        left = time.monotonic()
        with RawConnection(endpoint.port) as returning:  # back within the grace period: the same publisher
            returning.register_publisher(topic, "std_msgs/String")
            returning.sync()
        wait_for(lambda: roscore.publishers(topic) == [], 10, "the publisher to end")
        assert time.monotonic() - left >= 1.0
    finally:
        endpoint.stop()


def test_a_lingering_topic_can_be_registered_with_another_type_once_unused(bridge, ros_node) -> None:
    topic = unique("retyped")
    with RawConnection(bridge.port) as first:
        first.register_publisher(topic, "std_msgs/String")
        first.sync()
        host, port = first.sock.getsockname()[:2]
    # The endpoint releases a client's registrations when its reader sees the close, and then logs it.
    wait_for(lambda: f"{host}:{port} disconnected" in bridge.output(), 10, "the endpoint to release the first client")
    with RawConnection(bridge.port) as second:
        second.register_publisher(topic, "std_msgs/Int32")
        second.sync()
        assert second.errors() == []
        # Subscribe only now: a subscriber of the old advertisement would race rospy's re-advertise handling.
        inbox = RosInbox(ros_node, topic)
        inbox.wait_connected()
        second.send_frame(topic, u32(7))
        assert inbox.wait_count(1) == [u32(7)]
    inbox.close()


def test_a_client_flooding_bad_frames_without_reading_is_bounded_and_not_logged_per_frame(
    roscore, ros_node, tmp_path: Path
) -> None:
    endpoint = start_endpoint(roscore, tmp_path, "--queue-frames", "64")
    flood = 100_000  # each answer is a ~150-byte __error: 15 MB if the endpoint kept them all
    try:
        flooder = RawConnection(endpoint.port, rcvbuf=4096)
        watcher = tcp_client(endpoint.port, reconnect=False)
        watcher.topic_list()
        rss_before = rss_bytes(endpoint.process.pid)
        bad = b"".join(encode_frame("/never_registered", b"x") for _ in range(1000))
        for _ in range(flood // 1000):  # bounded: 100 writes
            flooder.send(bad)
        # The reader handles frames in order: the answer to this request proves the whole flood was handled.
        flooder.command("__topic_list")
        flooder.wait_command("__topic_list", timeout=60)
        errors = sum(1 for frame in flooder.received if frame.destination == "__error")
        assert errors < flood, "every error was kept for a client that did not read"
        assert rss_bytes(endpoint.process.pid) - rss_before < 8 * MiB, "the errors for the flood were all kept"
        logged = endpoint.output().count("which this client has not registered with __publish")
        assert 1 <= logged < 100, f"{logged} log lines for {flood} bad frames"
        assert watcher.errors == [] and watcher.connections == 1
        flooder.close()
        watcher.close()
    finally:
        assert endpoint.stop() is not None


def test_a_client_that_cannot_be_set_up_is_closed_and_the_endpoint_keeps_accepting(ros_node, monkeypatch) -> None:
    """Fault injection, in this process's endpoint: the first client's session fails to start (as when no thread
    can be had). That client is closed; the next one is served as usual."""
    from bridge import server
    from bridge.ros.graph import RosGraph

    failures = iter([RuntimeError("can't start new thread")])
    real_session = server.ClientSession

    def session_or_failure(*args, **kwargs):
        failure = next(failures, None)
        if failure is not None:
            raise failure
        return real_session(*args, **kwargs)

    monkeypatch.setattr(server, "ClientSession", session_or_failure)
    endpoint = server.Endpoint(RosGraph(), server.EndpointConfig(tcp_port=0))
    port = endpoint.start()
    try:
        with RawConnection(port, handshake=False) as refused:
            refused.wait_closed()
        with RawConnection(port) as served:  # RawConnection checks the handshake
            served.sync()
            assert served.errors() == []
    finally:
        endpoint.stop()
