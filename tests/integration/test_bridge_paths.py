"""The endpoint's fast paths keep their promises: client -> ROS through the per-topic pump (batched TCPROS writes,
latching, order, flow control), and per-client service-call workers (one client's slow calls never delay
another's)."""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from std_msgs.msg import String
from std_srvs.srv import Trigger, TriggerResponse

from bridge import protocol
from tests.integration.bridge_helpers import (
    RawConnection,
    RosInbox,
    bridge,  # noqa: F401 - module-scoped endpoint fixture (service timeout 2 s)
    serialize,
    tcp_client,
    unique,
)
from tests.rosenv import PYTHON, ManagedProcess, wait_for

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))


@contextmanager
def publishing_client(port: int, rospy, name: str, queue_size: int) -> Iterator[tuple[str, RawConnection, RosInbox]]:
    """A raw client registered to publish std_msgs/String on a fresh topic, and a ROS subscriber of that topic
    already connected to the endpoint: (topic, client, inbox)."""
    topic = unique(name)
    inbox = RosInbox(rospy, topic)
    try:
        with RawConnection(port) as client:
            client.register_publisher(topic, "std_msgs/String", queue_size=queue_size)
            client.sync()
            inbox.wait_connected()
            yield topic, client, inbox
    finally:
        inbox.close()


def test_a_burst_reaches_every_ros_subscriber_whole_and_in_order(bridge, ros_node) -> None:
    topic = unique("burst")
    inboxes = [RosInbox(ros_node, topic), RosInbox(ros_node, topic)]
    payloads = [serialize(String(f"message {index} " + "x" * (index % 50))) for index in range(300)]
    with RawConnection(bridge.port) as client:
        client.register_publisher(topic, "std_msgs/String", queue_size=1000)
        client.sync()
        for inbox in inboxes:
            inbox.wait_connected()
        client.send(b"".join(protocol.encode_frame(topic, payload) for payload in payloads))  # one write
        for inbox in inboxes:
            assert inbox.wait_count(len(payloads)) == payloads
        client.sync()
        assert not client.errors()
    for inbox in inboxes:
        inbox.close()


def test_single_frames_and_bursts_reach_ros_in_the_order_they_were_sent(bridge, ros_node) -> None:
    """A frame that comes alone is written on the reader's thread, a burst goes through the pump: the two ways
    must never overtake each other."""
    payloads = [serialize(String(f"message {index}")) for index in range(400)]
    with publishing_client(bridge.port, ros_node, "mixed", queue_size=1000) as (topic, client, inbox):
        index = 0
        while index < len(payloads):
            size = 1 if (index // 10) % 2 == 0 else 25  # ten single writes, then a burst of 25 in one write
            client.send(b"".join(protocol.encode_frame(topic, payload) for payload in payloads[index : index + size]))
            index += size
            if size == 1:
                time.sleep(0.001)  # so single writes arrive as single reads
        assert inbox.wait_count(len(payloads), timeout=30) == payloads
        client.sync()
        assert not client.errors()


def test_messages_written_together_with_a_command_reach_ros_before_the_command_takes_effect(bridge, ros_node) -> None:
    """The reader hands a read's messages to the publisher together; a command in the same read must still come
    after the messages before it: here the topic is unadvertised only once they are published."""
    payloads = [serialize(String(f"message {index}")) for index in range(50)]
    with publishing_client(bridge.port, ros_node, "then_removed", queue_size=100) as (topic, client, inbox):
        client.send(
            b"".join(protocol.encode_frame(topic, payload) for payload in payloads)
            + protocol.encode_syscommand("__remove_publisher", {"topic": topic})
        )  # one write
        assert inbox.wait_count(len(payloads)) == payloads
        client.sync()
        assert not client.errors()


def test_an_invalid_message_in_a_burst_is_refused_alone_and_the_rest_keep_their_order(bridge, ros_node) -> None:
    payloads = [serialize(String(f"message {index}")) for index in range(40)]
    with publishing_client(bridge.port, ros_node, "burst_with_garbage", queue_size=100) as (topic, client, inbox):
        frames = [protocol.encode_frame(topic, payload) for payload in payloads]
        frames.insert(20, protocol.encode_frame(topic, serialize(String("trailing")) + b"\0"))
        client.send(b"".join(frames))  # one write
        client.expect_error(topic, "trailing", "not published")
        assert inbox.wait_count(len(payloads)) == payloads
        client.sync()
        assert len(client.errors()) == 1


class SlowRosInbox(RosInbox):
    """A ROS subscriber whose callback takes `delay_s` per message, or blocks while `hold` is set."""

    def __init__(self, rospy, topic: str, delay_s: float = 0.0) -> None:
        self.delay_s = delay_s
        self.hold = threading.Event()
        self.released = threading.Event()
        super().__init__(rospy, topic)

    def __call__(self, payload: bytes) -> None:
        if self.hold.is_set():
            self.released.wait(60)
        time.sleep(self.delay_s)
        super().__call__(payload)


def test_a_client_faster_than_the_ros_subscriber_is_slowed_to_its_pace_and_loses_nothing(bridge, ros_node) -> None:
    topic = unique("paced")
    inbox = SlowRosInbox(ros_node, topic, delay_s=0.002)
    payloads = [serialize(String(f"message {index}")) for index in range(200)]
    with RawConnection(bridge.port) as client:
        client.register_publisher(topic, "std_msgs/String", queue_size=5)  # 40 times fewer than the burst
        client.sync()
        inbox.wait_connected()
        client.send(b"".join(protocol.encode_frame(topic, payload) for payload in payloads))  # one write
        assert inbox.wait_count(len(payloads), timeout=30) == payloads
        client.sync()
        assert not client.errors()
        assert not [frame for frame in client.received if frame.destination == "__warn"]
    inbox.close()


def _socket_buffers_bytes() -> int:
    """The most loopback TCP can hold between the endpoint and a subscriber that stopped reading."""
    most = 0
    for name in ("tcp_rmem", "tcp_wmem"):
        try:
            most += int(Path(f"/proc/sys/net/ipv4/{name}").read_text().split()[2])
        except (OSError, ValueError, IndexError):
            most += 8 << 20
    return most


def test_a_stalled_ros_subscriber_costs_its_topic_old_messages_never_the_clients_other_traffic(
    bridge, ros_node
) -> None:
    stuck_topic, other_topic = unique("stuck"), unique("unstuck")
    stuck, other = SlowRosInbox(ros_node, stuck_topic), RosInbox(ros_node, other_topic)
    big = serialize(String("x" * 256 * 1024))
    count = min(400, _socket_buffers_bytes() // len(big) + 50)  # more than the kernel buffers and the queue hold
    with RawConnection(bridge.port) as client:
        client.register_publisher(stuck_topic, "std_msgs/String", queue_size=10)
        client.register_publisher(other_topic, "std_msgs/String")
        client.sync()
        stuck.wait_connected()
        other.wait_connected()
        stuck.hold.set()
        for _ in range(count):
            client.send_frame(stuck_topic, big)
        client.send_frame(other_topic, serialize(String("still served")))
        # One wait for room (bridge.ros.publisher.PUBLISH_WAIT_S), then the stuck topic drops oldest without waiting.
        assert other.wait_count(1, timeout=10) == [serialize(String("still served"))]
        warning = client.wait_command("__warn", timeout=10)["text"]
        assert "ROS subscribers take this client's messages too slowly" in warning
        client.sync()
        assert not client.errors()
    stuck.released.set()
    wait_for(lambda: len(stuck) > 0, 30, "the stuck subscriber to be served again once it reads")
    stuck.close()
    other.close()


# A rospy node subscribing to argv[1]; prints GOT at its first message. The test freezes it with SIGSTOP.
_SUBSCRIBER_NODE = """
import sys
import rospy
from std_msgs.msg import String
rospy.init_node("frozen_subscriber", anonymous=True)
got = []
def on_message(message):
    if not got:
        got.append(message)
        print("GOT", flush=True)
rospy.Subscriber(sys.argv[1], String, on_message, tcp_nodelay=True)
rospy.spin()
"""


def test_a_frozen_ros_subscriber_is_cut_off_and_never_holds_up_the_topics_other_subscribers(
    bridge, roscore, ros_node, tmp_path: Path
) -> None:
    big = serialize(String("x" * 256 * 1024))
    count = min(400, _socket_buffers_bytes() // len(big) + 50)  # more than the kernel buffers hold
    marker = serialize(String("sent after the freeze"))
    with publishing_client(bridge.port, ros_node, "frozen", queue_size=10) as (topic, client, healthy):
        frozen = ManagedProcess([PYTHON, "-c", _SUBSCRIBER_NODE, topic], roscore.env, tmp_path, "frozen_subscriber")
        try:

            def node_got_a_message() -> bool:  # publish until the node's connection is up and it has heard one
                client.send_frame(topic, serialize(String("hello")))
                return "GOT" in frozen.output()

            wait_for(node_got_a_message, 30, "the subscriber node's first message", interval=0.05)
            os.kill(frozen.pid, signal.SIGSTOP)
            for _ in range(count):
                client.send_frame(topic, big)
            client.send_frame(topic, marker)
            wait_for(lambda: marker in healthy.snapshot(), 30, "the healthy subscriber to get the last message")
            client.sync()
            assert not client.errors()
        finally:
            os.kill(frozen.pid, signal.SIGCONT)
            frozen.stop()
    assert "connection closed (a rospy subscriber connects again)" in bridge.output()


def test_a_latched_topic_reaches_a_subscriber_that_comes_later(bridge, ros_node) -> None:
    topic = unique("latched")
    first, last = serialize(String("first")), serialize(String("last"))
    with RawConnection(bridge.port) as client:
        client.register_publisher(topic, "std_msgs/String", latch=True)
        client.sync()
        early = RosInbox(ros_node, topic)
        early.wait_connected()
        client.send_frame(topic, first)
        client.send_frame(topic, last)
        assert early.wait_count(2) == [first, last]  # both are published: "last" is now the latched message
        late = RosInbox(ros_node, topic)
        assert late.wait_count(1) == [last]
        early.close()
        late.close()


def test_one_clients_slow_service_calls_do_not_delay_another_clients_call(bridge, ros_node) -> None:
    """The busy client's calls stay blocked in the ROS service until the other client has had its answer: if the
    other call waited behind them, it could not complete (it would time out) while they are still held."""
    slow, fast = unique("slow"), unique("fast")
    release = threading.Event()
    held = threading.Semaphore(0)

    def handle_slow(_request) -> TriggerResponse:
        held.release()
        release.wait(timeout=30)
        return TriggerResponse(success=True, message="slow")

    services = [
        ros_node.Service(slow, Trigger, handle_slow),
        ros_node.Service(fast, Trigger, lambda _request: TriggerResponse(success=True, message="fast")),
    ]
    with RawConnection(bridge.port) as busy, tcp_client(bridge.port, reconnect=False) as other:
        busy.command("__ros_service", topic=slow, message_name="std_srvs/Trigger")
        other.register_ros_service(fast, "std_srvs/Trigger")
        busy.sync()
        for srv_id in range(101, 111):  # more calls than the endpoint had workers in total before (8)
            busy.command("__request", srv_id=srv_id)
            busy.send_frame(slow, b"")
        assert held.acquire(timeout=10), "the busy client's calls never reached the slow service"
        try:
            response = other.call_service(fast, b"", timeout=10)  # raises if it waited behind the held calls
        finally:
            release.set()
        assert response == serialize(TriggerResponse(success=True, message="fast"))
        busy.wait_frame(lambda frame: frame.destination == "__response", "the busy client's first answer")
    for service in services:
        service.shutdown()
