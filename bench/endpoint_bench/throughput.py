"""Phases 1, 2 and 5: small JointState floods each way against rospy alone, and the endpoint's CPU per message."""

from __future__ import annotations

from bench.endpoint_bench.flows import ros_to_tcp, rospy_to_rospy, tcp_to_ros
from bench.endpoint_bench.harness import Harness
from bench.endpoint_bench.records import Flow, Row, median_flow
from bench.endpoint_bench.settings import PUBLISH_QUEUE


def run(harness: Harness) -> None:
    """Judged against the faster rospy publisher mode (normally the synchronous one, queue_size=None); the
    queued mode (queue_size 100, what rospy nodes normally use) is shown as a second, unjudged reference. The
    endpoint's client publishers are rospy synchronous publishers fed by the endpoint's own pump thread.

    One 5 s window of a flood varies by +-12 % from run to run on two cores (the rospy ceiling alone measured
    179k-233k msg/s in one afternoon), so every flow runs in several interleaved rounds and each row shows the
    median round, with the range of rounds beside it."""
    flows: dict[str, list[Flow]] = {name: [] for name in ("sync", "queued", "tcp_in", "out_sync", "out_queued")}
    for _ in range(harness.settings.throughput_rounds):
        flows["sync"].append(rospy_to_rospy(harness, 0))
        flows["queued"].append(rospy_to_rospy(harness, PUBLISH_QUEUE))
        flows["tcp_in"].append(tcp_to_ros(harness))
        flows["out_sync"].append(ros_to_tcp(harness, 0))
        flows["out_queued"].append(ros_to_tcp(harness, PUBLISH_QUEUE))
    sync_ceiling, queued_ceiling = median_flow(flows["sync"]), median_flow(flows["queued"])
    tcp_in, ros_out_sync, ros_out_queued = (median_flow(flows[name]) for name in ("tcp_in", "out_sync", "out_queued"))
    best_is_sync = sync_ceiling.rate >= queued_ceiling.rate
    ceiling = sync_ceiling.rate if best_is_sync else queued_ceiling.rate
    best = "sync" if best_is_sync else f"queued q {PUBLISH_QUEUE}"
    rounds = harness.settings.throughput_rounds
    if rounds > 1:
        window = harness.settings.window_s
        harness.rows.append(
            Row(
                f"Throughput: median of {rounds} interleaved rounds of {window:g} s per flow",
                "",
                target="(range of rounds in [ ])",
            )
        )

    def spread(name: str) -> str:
        rates = sorted(flow.rate for flow in flows[name])
        return f" [{rates[0] / 1000:,.0f}k-{rates[-1] / 1000:,.0f}k]" if len(rates) > 1 else ""

    def add(label: str, name: str, flow: Flow, reference: float, reference_name: str, judged: bool) -> None:
        ratio = flow.rate / reference if reference else 0.0
        harness.rows.append(
            Row(
                label,
                f"{flow.rate:,.0f}{spread(name)}",
                f"{reference:,.0f}{spread(reference_name)}",
                f"{ratio:.2f}",
                ">= 0.95 x ceiling" if judged else "",
                ratio >= 0.95 if judged else None,
            )
        )

    best_name = "sync" if best_is_sync else "queued"
    add(f"TCP->ROS [msg/s] vs rospy {best} publisher", "tcp_in", tcp_in, ceiling, best_name, True)
    add(
        f"  same, vs rospy queued publisher (q {PUBLISH_QUEUE})",
        "tcp_in",
        tcp_in,
        queued_ceiling.rate,
        "queued",
        False,
    )
    add(f"ROS->TCP [msg/s], sync source, vs rospy {best}", "out_sync", ros_out_sync, ceiling, best_name, True)
    add(
        f"  queued source (q {PUBLISH_QUEUE}) vs rospy queued",
        "out_queued",
        ros_out_queued,
        queued_ceiling.rate,
        "queued",
        False,
    )
    for label, name in (
        ("rospy->rospy sync", "sync"),
        ("rospy->rospy queued", "queued"),
        ("TCP->ROS", "tcp_in"),
        ("ROS->TCP sync source", "out_sync"),
        ("ROS->TCP queued source", "out_queued"),
    ):
        received, sent = sum(f.received for f in flows[name]), sum(f.sent for f in flows[name])
        harness.rows.append(
            Row(f"  delivered/sent, {label}", f"{received:,}/{sent:,}", target=f"({received / max(sent, 1):.1%})")
        )
    for label, flow in (
        ("TCP->ROS", tcp_in),
        ("ROS->TCP (sync source)", ros_out_sync),
        ("ROS->TCP (queued source)", ros_out_queued),
    ):
        harness.rows.append(
            Row(
                f"Endpoint CPU s / 10k msgs, {label}",
                f"{flow.cpu_s / max(flow.received, 1) * 1e4:.3f}",
                target="(per delivered msg, median round)",
            )
        )
