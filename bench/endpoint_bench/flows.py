"""One throughput flow each way through the endpoint, and the references they are divided by; each returns its
Flow (arrival rate, received, sent, the endpoint's CPU meanwhile)."""

from __future__ import annotations

import time

from bench.endpoint_bench.harness import Harness
from bench.endpoint_bench.records import Arrivals, Flow, rate_of
from bench.endpoint_bench.settings import PUBLISH_QUEUE
from bench.messages import MESSAGE_KINDS
from bridge import protocol

FLOOD_MAX_MESSAGES = 5_000_000


def rospy_to_rospy(harness: Harness, queue_size: int, kind: str = "joint_state") -> Flow:
    """The ceiling: a rospy flood publisher process -> a rospy counting subscriber process."""
    window = harness.settings.window_s
    topic = f"/bench/ceiling_{kind}_q{queue_size}"
    counter = harness.node("count", "--topic", topic, "--max-seconds", str(window + 40), "--kind", kind)
    flood = harness.node(
        "flood", "--topic", topic, "--seconds", str(window), "--queue-size", str(queue_size), "--kind", kind
    )
    sent = harness.result(flood, window + 40)["sent"]
    counted = harness.result(counter, 20)
    return Flow(rate_of(counted["count"], counted["first"], counted["last"]), counted["count"], sent, 0.0)


def tcp_to_ros(harness: Harness, kind: str = "joint_state", websocket: bool = False) -> Flow:
    """A TcpClient writing frames as fast as the endpoint takes them -> a rospy counting subscriber process."""
    window = harness.settings.window_s
    topic = f"/bench/{'ws' if websocket else 'tcp'}_in_{kind}"
    counter = harness.node("count", "--topic", topic, "--max-seconds", str(window + 40), "--kind", kind)
    message_name, make_payload = MESSAGE_KINDS[kind]
    with harness.clients_closed():
        client = harness.client(websocket)
        client.register_publisher(topic, message_name, queue_size=PUBLISH_QUEUE)
        counter.wait_for_output("CONNECTED", 30)
        time.sleep(0.3)
        frame = client.wire(protocol.encode_frame(topic, make_payload()))  # framed once, for every write
        cpu_before = harness.cpu()
        sent = 0
        deadline = time.monotonic() + window
        while sent < FLOOD_MAX_MESSAGES and (sent % 100 or time.monotonic() < deadline):
            client.send_raw(frame, as_is=True)  # one write per frame, as Unity's client does
            sent += 1
        counted = harness.result(counter, 40)
        cpu_used = harness.cpu() - cpu_before
    return Flow(rate_of(counted["count"], counted["first"], counted["last"]), counted["count"], sent, cpu_used)


def ros_to_tcp(harness: Harness, queue_size: int, kind: str = "joint_state", websocket: bool = False) -> Flow:
    """A rospy flood publisher process -> the endpoint -> a counting TcpClient."""
    window = harness.settings.window_s
    topic = f"/bench/ros_out_{kind}_q{queue_size}{'_ws' if websocket else ''}"
    arrivals = Arrivals()
    with harness.clients_closed():
        client = harness.client(websocket)
        client.subscribe(topic, MESSAGE_KINDS[kind][0], arrivals)
        time.sleep(0.3)
        cpu_before = harness.cpu()
        flood = harness.node(
            "flood", "--topic", topic, "--seconds", str(window), "--queue-size", str(queue_size), "--kind", kind
        )
        sent = harness.result(flood, window + 40)["sent"]
        arrivals.wait_idle(1.0, 20.0)
        cpu_used = harness.cpu() - cpu_before
    return Flow(arrivals.rate(), arrivals.count, sent, cpu_used)


def rospy_to_raw_reader(harness: Harness, queue_size: int, kind: str) -> Flow:
    """The ROS->TCP reference: the flood publisher process of ros_to_tcp, read by a raw TCPROS reader process."""
    window = harness.settings.window_s
    topic = f"/bench/raw_out_{kind}_q{queue_size}"
    reader = harness.raw_reader("--topic", topic, "--kind", kind, "--max-seconds", str(window + 40))
    flood = harness.node(
        "flood", "--topic", topic, "--seconds", str(window), "--queue-size", str(queue_size), "--kind", kind
    )
    sent = harness.result(flood, window + 40)["sent"]
    counted = harness.result(reader, 20)
    return Flow(rate_of(counted["count"], counted["first"], counted["last"]), counted["count"], sent, 0.0)
