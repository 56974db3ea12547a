"""Phase 8: the traffic of a Unity scene of a robot, both ways at once: what arrived, how late, and the endpoint's
CPU."""

from __future__ import annotations

import time

from bench.endpoint_bench.harness import Harness
from bench.endpoint_bench.records import Row
from bench.messages import HEADER_OFFSETS, MESSAGE_KINDS, paced, read_stamp, stamped
from measuring.stats import percentile


def run(harness: Harness) -> None:
    """What a Unity scene of a robot carries at once: down (ROS -> client) 4 PoseStamped and 4 JointState topics
    at 60 Hz and TF at 100 Hz, up (client -> ROS) a PoseStamped and a JointState at 60 Hz. Per direction: what
    arrived of what was sent and the one-way latency (header stamps); the endpoint's CPU meanwhile."""
    window = 2 * harness.settings.window_s
    down = (
        [("pose", f"/mix/pose{i}", 60) for i in range(4)]
        + [("joint_state", f"/mix/joints{i}", 60) for i in range(4)]
        + [("tf", "/mix/tf", 100)]
    )
    up = [("pose", "/mix_up/pose", 60), ("joint_state", "/mix_up/joints", 60)]
    arrived: dict[str, list[float]] = {topic: [] for _, topic, _ in down}
    with harness.clients_closed():
        client = harness.client()
        for kind, topic, _ in down:

            def record(
                payload: bytes, latencies: list = arrived[topic], offset: int = HEADER_OFFSETS.get(kind, 0)
            ) -> None:
                latencies.append((time.monotonic_ns() - read_stamp(payload, offset)[1]) / 1e6)

            client.subscribe(topic, MESSAGE_KINDS[kind][0], record)
        for kind, topic, _ in up:
            client.register_publisher(topic, MESSAGE_KINDS[kind][0], queue_size=10)
        listener = harness.node(
            "ages",
            "--seconds",
            str(window + 8),
            "--idle",
            "3",  # the client has stopped sending
            *[arg for kind, topic, _ in up for arg in ("--listen", f"{kind}:{topic}")],
        )
        listener.wait_for_output("CONNECTED", 30)
        cpu_before, started = harness.cpu(), time.monotonic()
        stream = harness.node(
            "stream",
            "--seconds",
            str(window),
            *[arg for kind, topic, hz in down for arg in ("--stream", f"{kind}:{topic}:{hz}")],
        )
        templates = [(topic, MESSAGE_KINDS[kind][1](), HEADER_OFFSETS.get(kind, 0)) for kind, topic, _ in up]
        sent_up = 0
        for seq in paced(60, int(window * 60), window + 5):
            for topic, template, offset in templates:
                client.publish(topic, stamped(template, seq, offset=offset))
            sent_up += 1
        sent_down = harness.result(stream, window + 60)["sent"]
        time.sleep(0.5)
        cpu_used, elapsed = harness.cpu() - cpu_before, time.monotonic() - started
    received_up = harness.result(listener, window + 30)["arrivals"]
    down_latencies = [latency for latencies in arrived.values() for latency in latencies]
    up_latencies = [age / 1e6 for pairs in received_up.values() for _, age in pairs]
    for direction, received, sent, latencies in (
        (
            "down: 4 poses + 4 joint states @ 60 Hz, TF @ 100 Hz",
            len(down_latencies),
            sum(sent_down.values()),
            down_latencies,
        ),
        ("up: a pose + a joint state @ 60 Hz", len(up_latencies), sent_up * len(up), up_latencies),
    ):
        harness.rows.append(
            Row(f"Unity mix {direction}: delivered", f"{received:,}/{sent:,}", target="all", ok=received == sent)
        )
        if latencies:
            harness.rows.append(
                Row(
                    "  one-way latency p50/p99/max [ms]",
                    "/".join(f"{percentile(latencies, q):.2f}" for q in (50, 99, 100)),
                )
            )
    harness.rows.append(Row("  endpoint CPU during the mix [% of a core]", f"{cpu_used / elapsed * 100:.1f}"))
