"""The endpoint's fast paths keep their promises: client -> ROS through the per-topic pump (batched TCPROS writes,
latching, order), and per-client service-call workers (one client's slow calls never delay another's)."""
from __future__ import annotations

import time

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
    slow, fast = unique("slow"), unique("fast")

    def handle_slow(_request) -> TriggerResponse:
        time.sleep(1.5)
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
        busy.sync()
        started = time.monotonic()
        response = other.call_service(fast, b"", timeout=10)
        assert time.monotonic() - started < 1.0
        assert response == serialize(TriggerResponse(success=True, message="fast"))
        busy.wait_frame(lambda frame: frame.destination == "__response", "the busy client's first answer")
    for service in services:
        service.shutdown()
