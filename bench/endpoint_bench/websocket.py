"""Phase 9: WebSocket clients against TCP clients of one endpoint (its WebSocket port open), JointState and a
2.7 MB Image each way, with the endpoint's CPU per message."""

from __future__ import annotations

from bench.endpoint_bench.flows import ros_to_tcp, tcp_to_ros
from bench.endpoint_bench.harness import Harness, start_endpoint
from bench.endpoint_bench.records import Flow, Row, median_flow
from bench.endpoint_bench.settings import LARGE_ROS_QUEUE
from sim.processes import REPO, kill_process


def run(harness: Harness) -> None:
    """WebSocket clients against TCP clients, JointState and Image both ways, on an endpoint of this phase's own
    with the WebSocket port open; the TCP and WebSocket flows take turns in rounds, the median round is shown."""
    if not ((harness.settings.bridge_dir or REPO) / "bridge" / "websocket.py").exists():
        harness.rows.append(Row("WebSocket clients", "not served by this revision"))
        return
    plain, plain_pid = harness.endpoint, harness.pid
    settings = harness.settings
    harness.endpoint = harness.track(
        start_endpoint(
            harness.core.env,
            harness.log_dir,
            settings.bridge_dir,
            (*settings.endpoint_args, "--websocket-port", "0"),
            f"{plain.name}_ws",
        )
    )
    harness.pid = harness.endpoint.process.pid
    try:
        for kind, label, queue_size in (
            ("joint_state", "JointState", 0),
            ("image", "Image 2.7 MB", LARGE_ROS_QUEUE),
        ):
            flows: dict[str, list[Flow]] = {name: [] for name in ("in_tcp", "in_ws", "out_tcp", "out_ws")}
            for _ in range(settings.throughput_rounds):
                flows["in_tcp"].append(tcp_to_ros(harness, kind))
                flows["in_ws"].append(tcp_to_ros(harness, kind, websocket=True))
                flows["out_tcp"].append(ros_to_tcp(harness, queue_size, kind))
                flows["out_ws"].append(ros_to_tcp(harness, queue_size, kind, websocket=True))
            for direction, tcp_name, ws_name in (
                ("client->ROS", "in_tcp", "in_ws"),
                ("ROS->client", "out_tcp", "out_ws"),
            ):
                tcp, ws = median_flow(flows[tcp_name]), median_flow(flows[ws_name])
                digits = 0 if kind == "joint_state" else 1
                harness.rows.append(
                    Row(
                        f"WebSocket {label} {direction} [msg/s] vs TCP client",
                        f"{ws.rate:,.{digits}f}",
                        f"{tcp.rate:,.{digits}f}",
                        f"{ws.rate / tcp.rate if tcp.rate else 0.0:.2f}",
                    )
                )
                per = 1e4 if kind == "joint_state" else 100
                harness.rows.append(
                    Row(
                        f"  endpoint CPU s / {per:,.0f} msgs, WebSocket vs TCP",
                        f"{ws.cpu_s / max(ws.received, 1) * per:.3f}",
                        f"{tcp.cpu_s / max(tcp.received, 1) * per:.3f}",
                    )
                )
                received, sent = sum(f.received for f in flows[ws_name]), sum(f.sent for f in flows[ws_name])
                harness.rows.append(Row("  WebSocket delivered/sent", f"{received:,}/{sent:,}"))
    finally:
        kill_process(harness.endpoint.process)
        harness.endpoint, harness.pid = plain, plain_pid
