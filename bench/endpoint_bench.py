"""Benchmark of the ROS-TCP endpoint (`python -m bridge`) against the plain rospy ceiling, on one machine.

Run: `.venv/bin/python bench/endpoint_bench.py [--quick] [--keep-logs]` from the repository root.

Method. The script starts its own roscore (tests.rosenv.RosCore, free port, private ROS_HOME/ROS_LOG_DIR) and one
endpoint subprocess, and drives it from this process with `bridge.client.TcpClient`s (the Python twin of Unity's
client). Every ROS-side role is a separate rospy process (bench/endpoint_rosnode.py), so no two roles share a
GIL. All messages are one serialized 7-joint sensor_msgs/JointState; ping and stream messages carry a sequence
number and a CLOCK_MONOTONIC stamp in their header, so latency is computed from the bytes. The rospy nodes use a
raw (bytes-only) message class, like the endpoint, so the ceiling is rospy's transport, not its serializer.

  1. TCP->ROS: a TcpClient writes JointState frames as fast as it can (bounded by count and time) to the
     endpoint; a rospy subscriber process counts arrivals; rate = arrivals / (last - first arrival).
     Ceiling: a rospy publisher process flooding the same bytes to the same kind of subscriber process, in both
     publisher modes: synchronous (queue_size=None; usually the faster, and the one judged) and queued (queue_size
     100, what rospy nodes normally use; shown, not judged). Each throughput row names the reference it divides by.
     Every throughput flow (1 and 2) runs in 3 interleaved rounds (1 with --quick): one 5 s window varies by about
     +-12 % between runs on two cores, so each row shows the median round and the range of rounds.
  2. ROS->TCP: the same rospy flood publisher, received by a TcpClient through the endpoint. Same ceilings.
  3. RTT: a rospy relay process republishes /bench/ping bytes unchanged on /bench/pong. A TcpClient pings at
     100 Hz and 1 kHz (fixed schedule, no catch-up bursts) and times the pongs; the ceiling is a rospy process
     pinging the same relay on its own topic pair. The relay's CPU per round trip is the "rospy node" reference
     for the endpoint's CPU per round trip.
  4. Fan-out: 10 TcpClients subscribe to one topic published at 1 kHz for the window; delivered fraction per
     client (distinct sequence numbers received / published) and one-way latency.
  5. Endpoint CPU (utime + stime from /proc/<pid>/stat, all threads) per 10k messages, for runs 1-4.
  6. Hardening: (a) raw sockets announce a 0xFFFFFFF0-byte payload, then a 0xFFFFFFF0-byte destination, while
     another TcpClient receives a 1 kHz stream: endpoint RSS increase (VmRSS sampled every 5 ms) and that client's
     longest inter-arrival gap; (b) a client subscribes to a 1 kHz stream and never reads (tiny SO_RCVBUF) for
     60 s: endpoint RSS growth, and what a well-behaved client on the same topic still receives.
  7. Large messages: a 1280x720 RGB Image (2.7 MB) and a 1 MiB PointCloud2, each way, in interleaved rounds of the
     same run. TCP->ROS is read by a rospy subscriber process; its reference is a rospy sync publisher read by the
     same kind of subscriber (so both rates are bounded by that subscriber's read path). ROS->TCP has a rospy
     publisher of queue_size 10 as the source; its reference is the same source read by a raw TCPROS reader
     (bench/tcpros_reader.py: its own handshake, recv_into one buffer), not by a rospy subscriber, whose Python
     read path copies each message several times and reads a 2.7 MB image at a third of the rate the source
     delivers or less. Then TCP->ROS loss, a 1 MiB round trip at 30 Hz against rospy alone through the same relay,
     with the endpoint's CPU meanwhile, and its RSS after it all.
  8. The Unity-typical mix: down 4 PoseStamped and 4 JointState topics at 60 Hz and TF at 100 Hz, up a PoseStamped
     and a JointState at 60 Hz, for two windows: what arrived of what was sent, one-way latency each way, and the
     endpoint's CPU meanwhile.
  9. WebSocket clients (--websocket-port): JointState and the 2.7 MB Image both ways through WebSocket clients
     (bridge.client.TcpClient(websocket=True), as a browser or a Unity WebGL build connects) against TCP clients of
     the same endpoint in the same rounds, with the endpoint's CPU per message. The phase has an endpoint of its
     own with the WebSocket port open; every other phase's endpoint serves TCP only (the default). Skipped for a
     revision without the transport.
`--quick` shortens every window (2 s), the RTT sample counts and the soak (10 s) for a smoke run.
`--ab REVISION` runs REVISION's endpoint (a git worktree of it) beside this tree's, phase by phase alternately on
one roscore, and prints both tables and a comparison with the ratios.

Everything is loopback; every loop is bounded in count and time; every process is stopped by PID.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
BENCH = Path(__file__).resolve().parent
sys.path[:0] = [str(REPO), str(BENCH)]

from endpoint_common import (  # noqa: E402
    HEADER_OFFSETS,
    MESSAGE_KINDS,
    MESSAGE_NAME,
    joint_state_payload,
    paced,
    percentile,
    read_stamp,
    stamped,
)

from bridge import protocol  # noqa: E402
from bridge.client import TcpClient  # noqa: E402
from sim.processes import endpoint_ports  # noqa: E402
from tests.rosenv import PYTHON, EndpointProcess, ManagedProcess, RosCore, kill_process  # noqa: E402

ROSNODE = str(BENCH / "endpoint_rosnode.py")
TCPROS_READER = str(BENCH / "tcpros_reader.py")
MiB = 1024 * 1024
CLOCK_TICK_S = 1.0 / os.sysconf("SC_CLK_TCK")
FLOOD_MAX_MESSAGES = 5_000_000
PUBLISH_QUEUE = 100  # queue_size of the client's __publish and of the queued rospy flood publisher
FREEZE_GAP_MS = 50.0  # a 1 kHz stream pausing longer than this counts as frozen
FAN_CLIENTS = 10
LARGE_KINDS = (("image", "Image 2.7 MB"), ("cloud", "PointCloud2 1 MiB"))
LARGE_ROS_QUEUE = 10  # queue_size of the rospy publisher feeding large messages to the endpoint
LARGE_RTT_HZ = 30  # a camera's rate
LARGE_IDLE_S = 3.0  # the endpoint gives freed memory back after a quiet second (bridge.memory)
PHASES = ("throughput", "large", "unity_mix", "rtt", "fan_out", "huge_prefix", "never_reader", "websocket")


@dataclass(frozen=True)
class Settings:
    window_s: float
    throughput_rounds: int  # interleaved rounds of every throughput flow; the median round is judged
    rtt_samples: dict[int, int]  # rate in Hz -> number of pings
    soak_s: float
    quick: bool
    large_rtt_samples: int = 300
    bridge_dir: Path | None = None  # another checkout's `bridge` package, for A/B runs of a change
    endpoint_args: tuple[str, ...] = ()


@dataclass
class Row:
    name: str
    value: str
    ceiling: str = ""
    ratio: str = ""
    target: str = ""
    ok: bool | None = None  # None: informational


@dataclass
class Arrivals:
    """TcpClient callback recording arrival count, first/last time, sequence numbers and one-way latency."""

    keep_detail: bool = False
    count: int = 0
    first_ns: int = 0
    last_ns: int = 0
    seqs: set[int] = field(default_factory=set)
    times_ns: list[int] = field(default_factory=list)
    latencies_us: list[float] = field(default_factory=list)

    def __call__(self, payload: bytes) -> None:
        now = time.monotonic_ns()
        if self.count == 0:
            self.first_ns = now
        self.count += 1
        self.last_ns = now
        if self.keep_detail:
            seq, stamp_ns = read_stamp(payload)
            self.seqs.add(seq)
            self.times_ns.append(now)
            self.latencies_us.append((now - stamp_ns) / 1000.0)

    def rate(self) -> float:
        return rate_of(self.count, self.first_ns, self.last_ns)

    def wait_idle(self, idle_s: float, timeout_s: float) -> None:
        """Until nothing arrived for `idle_s` (or `timeout_s` passed)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.count and time.monotonic_ns() - self.last_ns > idle_s * 1e9:
                return
            time.sleep(0.05)


@dataclass(frozen=True)
class Flow:
    """One throughput run: arrival rate [msg/s], messages received and sent, endpoint CPU seconds used."""

    rate: float
    received: int
    sent: int
    cpu_s: float


def median_flow(flows: list[Flow]) -> Flow:
    """The round with the median rate (the lower middle one for an even count)."""
    ordered = sorted(flows, key=lambda flow: flow.rate)
    return ordered[(len(ordered) - 1) // 2]


def rate_range(flows: list[Flow]) -> str:
    """The range of several rounds' rates, " [lowest-highest]", shown beside their median; "" for one round."""
    rates = sorted(flow.rate for flow in flows)
    return f" [{rates[0]:.1f}-{rates[-1]:.1f}]" if len(rates) > 1 else ""


def rate_of(count: int, first_ns: int, last_ns: int) -> float:
    return (count - 1) / ((last_ns - first_ns) / 1e9) if count > 1 and last_ns > first_ns else 0.0


# --- /proc readings of the endpoint process -----------------------------------------------------------------------


def cpu_seconds(pid: int) -> float:
    """utime + stime of the whole process (all threads)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) * CLOCK_TICK_S  # fields 14 and 15 of proc(5)


def rss_bytes(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise RuntimeError(f"no VmRSS for pid {pid}")


class RssSampler:
    """Samples VmRSS of one process every `interval_s` on a thread, between start() and stop()."""

    def __init__(self, pid: int, interval_s: float) -> None:
        self.pid = pid
        self.interval_s = interval_s
        self.samples: list[tuple[float, int]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="rss-sampler", daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            self.samples.append((time.monotonic(), rss_bytes(self.pid)))
            self._stop.wait(self.interval_s)

    def start(self) -> RssSampler:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)

    def between(self, start: float, end: float) -> list[int]:
        return [rss for t, rss in self.samples if start <= t <= end]


# --- the benchmark --------------------------------------------------------------------------------------------------


class Bench:
    def __init__(self, settings: Settings, core: RosCore, log_dir: Path, name: str = "bench_endpoint") -> None:
        self.settings = settings
        self.core = core
        self.log_dir = log_dir
        self.payload = joint_state_payload()
        self.processes: list[ManagedProcess] = []
        self.clients: list[TcpClient] = []
        self.rows: list[Row] = []
        self.endpoint = self._track(
            start_endpoint(core.env, log_dir, settings.bridge_dir, settings.endpoint_args, name)
        )
        self.pid = self.endpoint.process.pid

    # --- process and client plumbing ---------------------------------------------------------------------------
    def _track(self, process: Any) -> Any:
        self.processes.append(process)
        return process

    def node(self, role: str, *args: str) -> ManagedProcess:
        return self._track(ManagedProcess([PYTHON, ROSNODE, role, *args], self.core.env, self.log_dir, f"{role}"))

    def raw_reader(self, *args: str) -> ManagedProcess:
        """A raw TCPROS subscriber process (bench/tcpros_reader.py), which prints RESULT as the roles do."""
        return self._track(ManagedProcess([PYTHON, TCPROS_READER, *args], self.core.env, self.log_dir, "tcpros_reader"))

    @staticmethod
    def result(process: ManagedProcess, timeout: float) -> dict[str, Any]:
        """Wait for a role process to finish by itself and return its RESULT json."""
        try:
            process.process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.stop()
            raise RuntimeError(f"{process.log_path.name} did not finish within {timeout:.0f} s") from None
        for line in process.output().splitlines():
            if line.startswith("RESULT "):
                return json.loads(line[len("RESULT ") :])
        raise RuntimeError(f"{process.log_path.name} printed no RESULT:\n{process.output()[-2000:]}")

    def client(self, websocket: bool = False) -> TcpClient:
        port = self.endpoint.websocket_port if websocket else self.endpoint.port
        client = TcpClient("127.0.0.1", port, reconnect=False, websocket=websocket).connect(timeout=10.0)
        self.clients.append(client)
        return client

    @contextmanager
    def clients_closed(self) -> Iterator[None]:
        """Close the clients made inside the block when it ends (the endpoint then drops their registrations)."""
        before = len(self.clients)
        try:
            yield
        finally:
            for client in self.clients[before:]:
                client.close()
            del self.clients[before:]
            time.sleep(0.2)

    def close(self) -> None:
        for client in self.clients:
            client.close()
        for process in reversed(self.processes):
            kill_process(process.process)

    def cpu(self) -> float:
        return cpu_seconds(self.pid)

    # --- 1 + 2 + 5: throughput ------------------------------------------------------------------------------------
    def rospy_to_rospy(self, queue_size: int, kind: str = "joint_state") -> Flow:
        """The ceiling: a rospy flood publisher process -> a rospy counting subscriber process."""
        window = self.settings.window_s
        topic = f"/bench/ceiling_{kind}_q{queue_size}"
        counter = self.node("count", "--topic", topic, "--max-seconds", str(window + 40), "--kind", kind)
        flood = self.node(
            "flood", "--topic", topic, "--seconds", str(window), "--queue-size", str(queue_size), "--kind", kind
        )
        sent = self.result(flood, window + 40)["sent"]
        counted = self.result(counter, 20)
        return Flow(rate_of(counted["count"], counted["first"], counted["last"]), counted["count"], sent, 0.0)

    def tcp_to_ros(self, kind: str = "joint_state", websocket: bool = False) -> Flow:
        """A TcpClient writing frames as fast as the endpoint takes them -> a rospy counting subscriber process."""
        window = self.settings.window_s
        topic = f"/bench/{'ws' if websocket else 'tcp'}_in_{kind}"
        counter = self.node("count", "--topic", topic, "--max-seconds", str(window + 40), "--kind", kind)
        message_name, make_payload = MESSAGE_KINDS[kind]
        with self.clients_closed():
            client = self.client(websocket)
            client.register_publisher(topic, message_name, queue_size=PUBLISH_QUEUE)
            counter.wait_for_output("CONNECTED", 30)
            time.sleep(0.3)
            frame = client.wire(protocol.encode_frame(topic, make_payload()))  # framed once, for every write
            cpu_before = self.cpu()
            sent = 0
            deadline = time.monotonic() + window
            while sent < FLOOD_MAX_MESSAGES and (sent % 100 or time.monotonic() < deadline):
                client.send_raw(frame, as_is=True)  # one write per frame, as Unity's client does
                sent += 1
            counted = self.result(counter, 40)
            cpu_used = self.cpu() - cpu_before
        return Flow(rate_of(counted["count"], counted["first"], counted["last"]), counted["count"], sent, cpu_used)

    def ros_to_tcp(self, queue_size: int, kind: str = "joint_state", websocket: bool = False) -> Flow:
        """A rospy flood publisher process -> the endpoint -> a counting TcpClient."""
        window = self.settings.window_s
        topic = f"/bench/ros_out_{kind}_q{queue_size}{'_ws' if websocket else ''}"
        arrivals = Arrivals()
        with self.clients_closed():
            client = self.client(websocket)
            client.subscribe(topic, MESSAGE_KINDS[kind][0], arrivals)
            time.sleep(0.3)
            cpu_before = self.cpu()
            flood = self.node(
                "flood", "--topic", topic, "--seconds", str(window), "--queue-size", str(queue_size), "--kind", kind
            )
            sent = self.result(flood, window + 40)["sent"]
            arrivals.wait_idle(1.0, 20.0)
            cpu_used = self.cpu() - cpu_before
        return Flow(arrivals.rate(), arrivals.count, sent, cpu_used)

    def rospy_to_raw_reader(self, queue_size: int, kind: str) -> Flow:
        """The ROS->TCP reference: the flood publisher process of ros_to_tcp, read by a raw TCPROS reader process."""
        window = self.settings.window_s
        topic = f"/bench/raw_out_{kind}_q{queue_size}"
        reader = self.raw_reader("--topic", topic, "--kind", kind, "--max-seconds", str(window + 40))
        flood = self.node(
            "flood", "--topic", topic, "--seconds", str(window), "--queue-size", str(queue_size), "--kind", kind
        )
        sent = self.result(flood, window + 40)["sent"]
        counted = self.result(reader, 20)
        return Flow(rate_of(counted["count"], counted["first"], counted["last"]), counted["count"], sent, 0.0)

    def throughput(self) -> None:
        """Judged against the faster rospy publisher mode (normally the synchronous one, queue_size=None); the
        queued mode (queue_size 100, what rospy nodes normally use) is shown as a second, unjudged reference. The
        endpoint's client publishers are rospy synchronous publishers fed by the endpoint's own pump thread.

        One 5 s window of a flood varies by +-12 % from run to run on two cores (the rospy ceiling alone measured
        179k-233k msg/s in one afternoon), so every flow runs in several interleaved rounds and each row shows the
        median round, with the range of rounds beside it."""
        flows: dict[str, list[Flow]] = {name: [] for name in ("sync", "queued", "tcp_in", "out_sync", "out_queued")}
        for _ in range(self.settings.throughput_rounds):
            flows["sync"].append(self.rospy_to_rospy(0))
            flows["queued"].append(self.rospy_to_rospy(PUBLISH_QUEUE))
            flows["tcp_in"].append(self.tcp_to_ros())
            flows["out_sync"].append(self.ros_to_tcp(0))
            flows["out_queued"].append(self.ros_to_tcp(PUBLISH_QUEUE))
        sync_ceiling, queued_ceiling = median_flow(flows["sync"]), median_flow(flows["queued"])
        tcp_in, ros_out_sync, ros_out_queued = (
            median_flow(flows[name]) for name in ("tcp_in", "out_sync", "out_queued")
        )
        best_is_sync = sync_ceiling.rate >= queued_ceiling.rate
        ceiling = sync_ceiling.rate if best_is_sync else queued_ceiling.rate
        best = "sync" if best_is_sync else f"queued q {PUBLISH_QUEUE}"
        rounds = self.settings.throughput_rounds
        if rounds > 1:
            window = self.settings.window_s
            self.rows.append(
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
            self.rows.append(
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
            self.rows.append(
                Row(f"  delivered/sent, {label}", f"{received:,}/{sent:,}", target=f"({received / max(sent, 1):.1%})")
            )
        for label, flow in (
            ("TCP->ROS", tcp_in),
            ("ROS->TCP (sync source)", ros_out_sync),
            ("ROS->TCP (queued source)", ros_out_queued),
        ):
            self.rows.append(
                Row(
                    f"Endpoint CPU s / 10k msgs, {label}",
                    f"{flow.cpu_s / max(flow.received, 1) * 1e4:.3f}",
                    target="(per delivered msg, median round)",
                )
            )

    # --- 7: large messages ------------------------------------------------------------------------------------------
    def large(self) -> None:
        """Camera images and point clouds both ways, each against a reference with the same reader (TCP->ROS) or the
        same source (ROS->TCP) for the same message in the same run (interleaved rounds, median judged); then a 1 MiB
        round trip at a camera's 30 Hz.

        TCP->ROS ends in a rospy subscriber process, so its reference is a rospy sync publisher read by the same kind
        of subscriber. ROS->TCP starts at a rospy publisher of queue_size 10, so its reference is that source read by
        a raw TCPROS reader: a rospy subscriber reads large messages slower than the endpoint forwards them, and
        would be a floor, not a ceiling."""
        rounds = self.settings.throughput_rounds
        for kind, label in LARGE_KINDS:
            flows: dict[str, list[Flow]] = {name: [] for name in ("rospy_sub", "tcp_in", "raw_reader", "ros_out")}
            for _ in range(rounds):
                flows["rospy_sub"].append(self.rospy_to_rospy(0, kind))
                flows["tcp_in"].append(self.tcp_to_ros(kind))
                flows["raw_reader"].append(self.rospy_to_raw_reader(LARGE_ROS_QUEUE, kind))
                flows["ros_out"].append(self.ros_to_tcp(LARGE_ROS_QUEUE, kind))
            for name, path, reference_name, reference_label in (
                ("tcp_in", "TCP->ROS", "rospy_sub", "rospy sync publisher, same rospy subscriber"),
                ("ros_out", f"ROS->TCP (q {LARGE_ROS_QUEUE} source)", "raw_reader", "raw TCPROS reader, same source"),
            ):
                flow, reference = median_flow(flows[name]), median_flow(flows[reference_name]).rate
                ratio = flow.rate / reference if reference else 0.0
                self.rows.append(
                    Row(
                        f"{label} {path} [msg/s] vs {reference_label}",
                        f"{flow.rate:.1f}{rate_range(flows[name])}",
                        f"{reference:.1f}{rate_range(flows[reference_name])}",
                        f"{ratio:.2f}",
                        # ROS->TCP ends in the bench's own Python client (TcpClient), which is slower than the raw
                        # reader at these sizes (the endpoint reports it reading too slowly): the ratio describes
                        # that whole chain, so it is shown, not judged
                        ">= 0.95 x reference" if name == "tcp_in" else "",
                        ratio >= 0.95 if name == "tcp_in" else None,
                    )
                )
                self.rows.append(
                    Row(
                        "  endpoint CPU s / 100 msgs",
                        f"{flow.cpu_s / max(flow.received, 1) * 100:.3f}",
                        target="(median round)",
                    )
                )
            received, sent = sum(f.received for f in flows["tcp_in"]), sum(f.sent for f in flows["tcp_in"])
            self.rows.append(
                Row(f"  {label} TCP->ROS delivered/sent", f"{received:,}/{sent:,}", target="all", ok=received == sent)
            )
            # the q 10 source drops what its writer thread cannot send in time: the share read shows who kept up
            delivered = [
                f"{sum(f.received for f in flows[name]):,}/{sum(f.sent for f in flows[name]):,}"
                for name in ("ros_out", "raw_reader")
            ]
            self.rows.append(Row(f"  {label} ROS->TCP delivered/published", *delivered))
        self.large_round_trip()
        self.rows.append(Row("Endpoint RSS right after the large messages [MiB]", f"{rss_bytes(self.pid) / MiB:.1f}"))
        time.sleep(LARGE_IDLE_S)
        self.rows.append(
            Row(f"  and after {LARGE_IDLE_S:g} s without traffic [MiB]", f"{rss_bytes(self.pid) / MiB:.1f}")
        )

    def large_round_trip(self) -> None:
        """1 MiB PointCloud2 pings at 30 Hz through a rospy relay: from a TcpClient via the endpoint, and from a rospy
        node alone (the reference); with the endpoint's CPU over the TcpClient's runs. The two take turns in rounds
        (settings.throughput_rounds) and each pools its samples: rospy alone varies by a third from one minute to
        the next (1.6-2.1 ms p50 within one run), which one run of each would charge to the endpoint."""
        hz, rounds = LARGE_RTT_HZ, self.settings.throughput_rounds
        count = max(1, self.settings.large_rtt_samples // rounds)
        relay = self.node(
            "relay",
            "--pair",
            "/bench/big_ping:/bench/big_pong",
            "--pair",
            "/bench/big_rping:/bench/big_rpong",
            "--kind",
            "cloud",
        )
        relay.wait_for_output("READY", 30)
        message_name, make_payload = MESSAGE_KINDS["cloud"]
        template = make_payload()
        rtts_us: list[float] = []
        mine: list[float] = []
        theirs: list[float] = []
        sent, elapsed, cpu_used = 0, 0.0, 0.0
        with self.clients_closed():
            client = self.client()
            client.subscribe(
                "/bench/big_pong",
                message_name,
                lambda payload: rtts_us.append((time.monotonic_ns() - read_stamp(payload)[1]) / 1000.0),
            )
            client.register_publisher("/bench/big_ping", message_name, queue_size=10)
            for seq in paced(10, 300, 30.0):  # until the whole loop is connected
                if rtts_us:
                    break
                client.publish("/bench/big_ping", stamped(template, seq))
            for _ in range(rounds):
                time.sleep(0.5)
                rtts_us.clear()
                cpu_before, started = self.cpu(), time.monotonic()
                for seq in paced(hz, count, count / hz * 1.5 + 2.0):
                    client.publish("/bench/big_ping", stamped(template, seq))
                    sent += 1
                elapsed, cpu_used = elapsed + time.monotonic() - started, cpu_used + self.cpu() - cpu_before
                time.sleep(0.5)
                mine += rtts_us
                ping = self.node(
                    "ping",
                    "--out-topic",
                    "/bench/big_rping",
                    "--in-topic",
                    "/bench/big_rpong",
                    "--rates",
                    f"{hz}:{count}",
                    "--kind",
                    "cloud",
                )
                theirs += self.result(ping, count / hz * 1.5 + 60)["rates"][str(hz)]["rtts_us"]
        relay.stop()
        if not mine or not theirs:
            self.rows.append(Row(f"1 MiB round trip @ {hz} Hz", "no pongs", ok=False))
            return
        for label, q, bound in (("p50", 50.0, 1.3), ("max", 100.0, 2.0)):
            value, reference = percentile(mine, q) / 1000.0, percentile(theirs, q) / 1000.0
            self.rows.append(
                Row(
                    f"1 MiB round trip @ {hz} Hz {label} [ms]",
                    f"{value:.2f}",
                    f"{reference:.2f}",
                    f"{value / reference:.2f}",
                    f"<= {bound:g} x rospy",
                    value <= bound * reference,
                )
            )
        self.rows.append(Row(f"  pongs received @ {hz} Hz", f"{len(mine)}/{sent}", f"{len(theirs)}/{count * rounds}"))
        self.rows.append(Row("  endpoint CPU during the round trips [% of a core]", f"{cpu_used / elapsed * 100:.1f}"))

    # --- 9: WebSocket clients -------------------------------------------------------------------------------------
    def websocket(self) -> None:
        """WebSocket clients against TCP clients, JointState and Image both ways, on an endpoint of this phase's own
        with the WebSocket port open; the TCP and WebSocket flows take turns in rounds, the median round is shown."""
        if not ((self.settings.bridge_dir or REPO) / "bridge" / "websocket.py").exists():
            self.rows.append(Row("WebSocket clients", "not served by this revision"))
            return
        plain, plain_pid = self.endpoint, self.pid
        settings = self.settings
        self.endpoint = self._track(
            start_endpoint(
                self.core.env,
                self.log_dir,
                settings.bridge_dir,
                (*settings.endpoint_args, "--websocket-port", "0"),
                f"{plain.name}_ws",
            )
        )
        self.pid = self.endpoint.process.pid
        try:
            for kind, label, queue_size in (
                ("joint_state", "JointState", 0),
                ("image", "Image 2.7 MB", LARGE_ROS_QUEUE),
            ):
                flows: dict[str, list[Flow]] = {name: [] for name in ("in_tcp", "in_ws", "out_tcp", "out_ws")}
                for _ in range(settings.throughput_rounds):
                    flows["in_tcp"].append(self.tcp_to_ros(kind))
                    flows["in_ws"].append(self.tcp_to_ros(kind, websocket=True))
                    flows["out_tcp"].append(self.ros_to_tcp(queue_size, kind))
                    flows["out_ws"].append(self.ros_to_tcp(queue_size, kind, websocket=True))
                for direction, tcp_name, ws_name in (
                    ("client->ROS", "in_tcp", "in_ws"),
                    ("ROS->client", "out_tcp", "out_ws"),
                ):
                    tcp, ws = median_flow(flows[tcp_name]), median_flow(flows[ws_name])
                    digits = 0 if kind == "joint_state" else 1
                    self.rows.append(
                        Row(
                            f"WebSocket {label} {direction} [msg/s] vs TCP client",
                            f"{ws.rate:,.{digits}f}",
                            f"{tcp.rate:,.{digits}f}",
                            f"{ws.rate / tcp.rate if tcp.rate else 0.0:.2f}",
                        )
                    )
                    per = 1e4 if kind == "joint_state" else 100
                    self.rows.append(
                        Row(
                            f"  endpoint CPU s / {per:,.0f} msgs, WebSocket vs TCP",
                            f"{ws.cpu_s / max(ws.received, 1) * per:.3f}",
                            f"{tcp.cpu_s / max(tcp.received, 1) * per:.3f}",
                        )
                    )
                    received, sent = sum(f.received for f in flows[ws_name]), sum(f.sent for f in flows[ws_name])
                    self.rows.append(Row("  WebSocket delivered/sent", f"{received:,}/{sent:,}"))
        finally:
            kill_process(self.endpoint.process)
            self.endpoint, self.pid = plain, plain_pid

    # --- 8: the Unity-typical mix -------------------------------------------------------------------------------
    def unity_mix(self) -> None:
        """What a Unity scene of a robot carries at once: down (ROS -> client) 4 PoseStamped and 4 JointState topics
        at 60 Hz and TF at 100 Hz, up (client -> ROS) a PoseStamped and a JointState at 60 Hz. Per direction: what
        arrived of what was sent and the one-way latency (header stamps); the endpoint's CPU meanwhile."""
        window = 2 * self.settings.window_s
        down = (
            [("pose", f"/mix/pose{i}", 60) for i in range(4)]
            + [("joint_state", f"/mix/joints{i}", 60) for i in range(4)]
            + [("tf", "/mix/tf", 100)]
        )
        up = [("pose", "/mix_up/pose", 60), ("joint_state", "/mix_up/joints", 60)]
        arrived: dict[str, list[float]] = {topic: [] for _, topic, _ in down}
        with self.clients_closed():
            client = self.client()
            for kind, topic, _ in down:

                def record(
                    payload: bytes, latencies: list = arrived[topic], offset: int = HEADER_OFFSETS.get(kind, 0)
                ) -> None:
                    latencies.append((time.monotonic_ns() - read_stamp(payload, offset)[1]) / 1e6)

                client.subscribe(topic, MESSAGE_KINDS[kind][0], record)
            for kind, topic, _ in up:
                client.register_publisher(topic, MESSAGE_KINDS[kind][0], queue_size=10)
            listener = self.node(
                "ages",
                "--seconds",
                str(window + 8),
                *[arg for kind, topic, _ in up for arg in ("--listen", f"{kind}:{topic}")],
            )
            listener.wait_for_output("CONNECTED", 30)
            cpu_before, started = self.cpu(), time.monotonic()
            stream = self.node(
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
            sent_down = self.result(stream, window + 60)["sent"]
            time.sleep(0.5)
            cpu_used, elapsed = self.cpu() - cpu_before, time.monotonic() - started
        received_up = self.result(listener, window + 30)["arrivals"]
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
            self.rows.append(
                Row(f"Unity mix {direction}: delivered", f"{received:,}/{sent:,}", target="all", ok=received == sent)
            )
            if latencies:
                self.rows.append(
                    Row(
                        "  one-way latency p50/p99/max [ms]",
                        "/".join(f"{percentile(latencies, q):.2f}" for q in (50, 99, 100)),
                    )
                )
        self.rows.append(Row("  endpoint CPU during the mix [% of a core]", f"{cpu_used / elapsed * 100:.1f}"))

    # --- 3: round-trip time ---------------------------------------------------------------------------------------
    def rtt(self) -> None:
        relay = self.node("relay", "--pair", "/bench/ping:/bench/pong", "--pair", "/bench/rping:/bench/rpong")
        relay.wait_for_output("READY", 30)
        relay_pid = relay.process.pid
        tcp: dict[int, tuple[list[float], int, float]] = {}
        with self.clients_closed():
            client = self.client()
            rtts_us: list[float] = []

            def on_pong(payload: bytes) -> None:
                rtts_us.append((time.monotonic_ns() - read_stamp(payload)[1]) / 1000.0)

            client.subscribe("/bench/pong", MESSAGE_NAME, on_pong)
            client.register_publisher("/bench/ping", MESSAGE_NAME, queue_size=PUBLISH_QUEUE)
            for seq in paced(100, 3000, 30.0):  # warm-up until the whole loop is connected
                if rtts_us:
                    break
                client.publish("/bench/ping", stamped(self.payload, seq))
            time.sleep(0.5)
            for hz, count in self.settings.rtt_samples.items():
                rtts_us.clear()
                cpu_before = self.cpu()
                sent = 0
                for seq in paced(hz, count, count / hz * 1.5 + 2.0):
                    client.publish("/bench/ping", stamped(self.payload, seq))
                    sent += 1
                time.sleep(0.5)
                tcp[hz] = (list(rtts_us), sent, self.cpu() - cpu_before)
        ros: dict[int, tuple[list[float], int, float]] = {}
        for hz, count in self.settings.rtt_samples.items():
            relay_before = cpu_seconds(relay_pid)
            ping = self.node(
                "ping", "--out-topic", "/bench/rping", "--in-topic", "/bench/rpong", "--rates", f"{hz}:{count}"
            )
            result = self.result(ping, count / hz * 1.5 + 60)["rates"][str(hz)]
            ros[hz] = (result["rtts_us"], result["sent"], cpu_seconds(relay_pid) - relay_before)
        relay.stop()

        for hz in self.settings.rtt_samples:
            mine, sent, cpu_used = tcp[hz]
            theirs, their_sent, relay_cpu = ros[hz]
            if not mine or not theirs:
                self.rows.append(Row(f"RTT @ {hz} Hz", "no pongs", ok=False))
                continue
            for label, q in (("p50", 50.0), ("p99", 99.0), ("max", 100.0)):
                value, reference = percentile(mine, q) / 1000.0, percentile(theirs, q) / 1000.0
                target, ok = "", None
                if hz == 1000 and label == "p99":
                    target, ok = "<= 1.0 ms", value <= 1.0
                if hz == 1000 and label == "max":
                    target, ok = "< 10 ms", value < 10.0
                self.rows.append(
                    Row(
                        f"RTT @ {hz} Hz {label} [ms]",
                        f"{value:.3f}",
                        f"{reference:.3f}",
                        f"{value / reference:.2f}",
                        target,
                        ok,
                    )
                )
            self.rows.append(Row(f"  pongs received @ {hz} Hz", f"{len(mine)}/{sent}", f"{len(theirs)}/{their_sent}"))
            self.rows.append(
                Row(
                    f"  CPU s / 10k round trips @ {hz} Hz",
                    f"{cpu_used / sent * 1e4:.3f}",
                    f"{relay_cpu / their_sent * 1e4:.3f}",
                    f"{cpu_used / sent / (relay_cpu / their_sent):.2f}",
                    "(ceiling: relay node)",
                )
            )

    # --- 4: fan-out -------------------------------------------------------------------------------------------------
    def fan_out(self) -> None:
        window = self.settings.window_s
        topic = "/bench/fan"
        recorders = [Arrivals(keep_detail=True) for _ in range(FAN_CLIENTS)]
        with self.clients_closed():
            for recorder in recorders:
                self.client().subscribe(topic, MESSAGE_NAME, recorder)
            time.sleep(0.5)
            cpu_before = self.cpu()
            rate = self.node("rate", "--topic", topic, "--hz", "1000", "--seconds", str(window), "--delay", "1.0")
            sent = self.result(rate, window + 40)["sent"]
            for recorder in recorders:
                recorder.wait_idle(1.0, 10.0)
            cpu_used = self.cpu() - cpu_before
        fractions = [len({seq for seq in r.seqs if seq < sent}) / sent for r in recorders]
        latencies = [latency for r in recorders for latency in r.latencies_us]
        self.rows.append(
            Row(
                f"Fan-out {FAN_CLIENTS} clients x 1 kHz: min delivered",
                f"{min(fractions):.4f}",
                target="1.0000 (all)",
                ok=min(fractions) >= 1.0,
            )
        )
        self.rows.append(
            Row("  delivered per client", " ".join(f"{f:.3f}" for f in fractions), target=f"({sent:,} published)")
        )
        if latencies:
            self.rows.append(
                Row(
                    "  one-way latency p50/p99/max [ms]",
                    "/".join(f"{percentile(latencies, q) / 1000:.2f}" for q in (50, 99, 100)),
                )
            )
        delivered = sum(r.count for r in recorders)
        self.rows.append(Row("  endpoint CPU s / 10k delivered frames", f"{cpu_used / max(delivered, 1) * 1e4:.3f}"))

    # --- 6a: 4 GiB length prefix ------------------------------------------------------------------------------------
    def huge_prefix(self) -> None:
        topic = "/bench/stream_a"
        victim = Arrivals(keep_detail=True)
        outcomes: list[str] = []
        with self.clients_closed():
            self.client().subscribe(topic, MESSAGE_NAME, victim)
            time.sleep(0.3)
            rate = self.node("rate", "--topic", topic, "--hz", "1000", "--seconds", "8", "--delay", "0.5")
            rate.wait_for_output("PUBLISHING", 30)
            sampler = RssSampler(self.pid, 0.005).start()
            time.sleep(1.5)
            event_start = time.monotonic()
            destination = b"/bench/evil"
            outcomes.append(
                huge_length_attack(
                    self.endpoint.port,
                    struct.pack("<I", len(destination)) + destination + struct.pack("<I", 0xFFFFFFF0),
                )
            )
            outcomes.append(huge_length_attack(self.endpoint.port, struct.pack("<I", 0xFFFFFFF0)))
            event_end = time.monotonic()
            time.sleep(1.0)
            sampler.stop()
            self.result(rate, 40)
        baseline = sampler.between(event_start - 1.0, event_start)
        during = sampler.between(event_start, event_end + 1.0)
        increase = (max(during) - min(baseline)) / MiB if baseline and during else float("nan")
        gap_during = max_gap_ms(victim.times_ns, event_start, event_end + 1.0)
        gap_before = max_gap_ms(victim.times_ns, event_start - 1.0, event_start)
        self.rows.append(
            Row(
                "4 GiB length prefix: endpoint RSS increase [MiB]",
                f"{increase:.2f}",
                target="< 10 MiB",
                ok=increase < 10.0,
            )
        )
        self.rows.append(
            Row(
                "4 GiB prefix: other client's max gap [ms]",
                f"{gap_during:.1f}",
                f"{gap_before:.1f} before",
                target=f"< {FREEZE_GAP_MS:.0f} ms (no freeze)",
                ok=gap_during < FREEZE_GAP_MS,
            )
        )
        self.rows.append(Row("  attacker connection (payload len, dest len)", "; ".join(outcomes)))

    # --- 6b: never-reading client -------------------------------------------------------------------------------------
    def never_reader(self) -> None:
        topic = "/bench/stream_b"
        soak = self.settings.soak_s
        good = Arrivals(keep_detail=True)
        with self.clients_closed():
            self.client().subscribe(topic, MESSAGE_NAME, good)
            stalled = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            try:
                stalled.connect(("127.0.0.1", self.endpoint.port))
                stalled.sendall(
                    protocol.KEEPALIVE_FRAME
                    + protocol.encode_syscommand("__subscribe", {"topic": topic, "message_name": MESSAGE_NAME})
                )
                time.sleep(0.5)
                baseline = rss_bytes(self.pid)
                rate = self.node("rate", "--topic", topic, "--hz", "1000", "--seconds", str(soak), "--delay", "0.5")
                rate.wait_for_output("PUBLISHING", 30)
                samples: list[int] = []
                deadline = time.monotonic() + soak
                while time.monotonic() < deadline:
                    samples.append(rss_bytes(self.pid))
                    time.sleep(0.5)
                sent = self.result(rate, 40)["sent"]
                good.wait_idle(1.0, 10.0)
                samples.append(rss_bytes(self.pid))
            finally:
                stalled.close()
        growth = (max(samples) - baseline) / MiB
        delivered = len({seq for seq in good.seqs if seq < sent}) / max(sent, 1)
        self.rows.append(
            Row(
                f"Never-reading client, {soak:.0f} s @ 1 kHz: RSS growth [MiB]",
                f"{growth:.2f}",
                target="< 10 MiB",
                ok=growth < 10.0,
            )
        )
        self.rows.append(Row("  RSS at end - at start [MiB]", f"{(samples[-1] - baseline) / MiB:.2f}"))
        self.rows.append(
            Row(
                "  well-behaved client on the same topic: delivered", f"{delivered:.4f}", target=f"({sent:,} published)"
            )
        )
        if good.latencies_us:
            self.rows.append(
                Row(
                    "  its one-way latency p99/max [ms]",
                    "/".join(f"{percentile(good.latencies_us, q) / 1000:.2f}" for q in (99, 100)),
                )
            )


def start_endpoint(
    env: dict[str, str], log_dir: Path, bridge_dir: Path | None, extra: tuple[str, ...], name: str = "bench_endpoint"
) -> Any:
    """The endpoint under test, as ROS node `name`: this checkout's (tests.rosenv.EndpointProcess) or the `bridge`
    in `bridge_dir`."""
    if bridge_dir is None:
        return EndpointProcess(env, log_dir, name=name, extra=extra)
    launcher = (
        f"import sys; sys.path.insert(0, {str(bridge_dir)!r}); from bridge.__main__ import main; sys.exit(main())"
    )
    process = ManagedProcess(
        [PYTHON, "-c", launcher, "--tcp-port", "0", "--node-name", name, *extra], env, log_dir, name
    )
    ports = endpoint_ports(process, "--websocket-port" in extra)
    process.port, process.websocket_port = ports  # type: ignore[attr-defined]
    return process


def huge_length_attack(port: int, header: bytes) -> str:
    """Send a keepalive and then a frame header announcing ~4 GiB; describe how the endpoint answers."""
    with socket.create_connection(("127.0.0.1", port), timeout=5.0) as sock:
        sock.sendall(protocol.KEEPALIVE_FRAME + header)
        received = b""
        deadline = time.monotonic() + 3.0
        closed = False
        try:
            while time.monotonic() < deadline:
                sock.settimeout(max(0.01, deadline - time.monotonic()))
                data = sock.recv(65536)
                if not data:
                    closed = True
                    break
                received += data
        except socket.timeout:
            pass
        except ConnectionResetError:
            closed = True
        error = b"__error" in received
        if not closed:  # still open: push 1 MiB of junk, as a client streaming a huge body would
            try:
                sock.sendall(b"\xab" * MiB)
            except OSError:
                pass
        return ("__error" if error else "no __error") + (" + closed" if closed else ", still open")


def max_gap_ms(times_ns: list[int], start: float, end: float) -> float:
    """Longest gap between consecutive arrivals, over arrivals in [start, end] (monotonic seconds)."""
    window = [t for t in times_ns if start * 1e9 <= t <= end * 1e9]
    if len(window) < 2:
        return float("inf")
    return max(b - a for a, b in zip(window, window[1:])) / 1e6


def print_table(rows: list[Row], header: str) -> None:
    columns = ("measurement", "endpoint", "reference (named in the row)", "ratio", "target", "result")
    cells = [
        (r.name, r.value, r.ceiling, r.ratio, r.target, "" if r.ok is None else "PASS" if r.ok else "MISS")
        for r in rows
    ]
    widths = [max(len(c[i]) for c in [columns, *cells]) for i in range(len(columns))]
    line = "  ".join("-" * w for w in widths)
    print(header)
    print(line)
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths)))
    print(line)
    for c in cells:
        print("  ".join(v.ljust(w) for v, w in zip(c, widths)).rstrip())
    print(line)
    verdicts = [r.ok for r in rows if r.ok is not None]
    print(f"{sum(verdicts)}/{len(verdicts)} targets met")


def compare_tables(ours: list[Row], theirs: list[Row], our_name: str, their_name: str) -> None:
    """The rows of both endpoints side by side, with the ratio of their leading numbers (ours / theirs)."""
    their_values = dict(zip(occurrences(theirs), (row.value for row in theirs)))
    columns = ("measurement", our_name, their_name, "ratio")
    cells = []
    for key, row in zip(occurrences(ours), ours):
        other = their_values.get(key, "")
        a, b = leading_number(row.value), leading_number(other)
        ratio = f"{a / b:.2f}" if a is not None and b else ""
        cells.append((row.name, row.value, other, ratio))
    widths = [max(len(c[i]) for c in [columns, *cells]) for i in range(len(columns))]
    line = "  ".join("-" * w for w in widths)

    def show(values: tuple[str, ...]) -> None:
        print("  ".join(v.ljust(w) for v, w in zip(values, widths)).rstrip())

    print(f"A/B: {our_name} against {their_name}, phase by phase on one roscore (ratio = {our_name} / {their_name})")
    print(line)
    show(columns)
    print(line)
    for values in cells:
        show(values)
    print(line)


def occurrences(rows: list[Row]) -> list[tuple[str, int]]:
    """Each row's name with how many rows of that name came before it (rows such as "  endpoint CPU" repeat)."""
    seen: dict[str, int] = {}
    keys = []
    for row in rows:
        keys.append((row.name, seen.get(row.name, 0)))
        seen[row.name] = keys[-1][1] + 1
    return keys


def leading_number(text: str) -> float | None:
    """The number a cell starts with ("1,234.5 [..]" -> 1234.5); None when it starts with none or is a count of a
    count ("90/90")."""
    token = text.split(" ", 1)[0].replace(",", "")
    try:
        return float(token)
    except ValueError:
        return None


@contextmanager
def worktree_of(revision: str) -> Iterator[Path]:
    """A detached git worktree of `revision` of this repository, removed afterwards."""
    path = Path(tempfile.mkdtemp(prefix="endpoint_bench_ab_"))
    subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "--quiet", str(path), revision], check=True)
    try:
        yield path
    finally:
        subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(path)], check=False)
        shutil.rmtree(path, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smoke run: 2 s windows, fewer RTT samples, 10 s soak")
    parser.add_argument("--keep-logs", action="store_true", help="keep roscore/endpoint/node logs (path printed)")
    parser.add_argument("--bridge-dir", type=Path, help="benchmark the `bridge` package in this directory instead")
    parser.add_argument(
        "--ab",
        metavar="REVISION",
        help="also run REVISION's endpoint (a git worktree), phase by phase alternately on one roscore, and compare",
    )
    parser.add_argument(
        "--their-first",
        action="store_true",
        help="with --ab: REVISION's endpoint runs first in every phase (a phase's first side may meet a different "
        "machine than its second: run both orders to tell)",
    )
    parser.add_argument("--endpoint-arg", action="append", default=[], help="extra endpoint argument (repeatable)")
    parser.add_argument("--only", nargs="+", choices=PHASES, help="run only these phases")
    args = parser.parse_args(argv)
    if args.ab is not None and args.bridge_dir is not None:
        parser.error("--ab compares this tree with REVISION; it takes no --bridge-dir")
    if args.their_first and args.ab is None:
        parser.error("--their-first orders the two sides of --ab REVISION")
    if args.ab is not None:
        known = subprocess.run(
            ["git", "-C", str(REPO), "rev-parse", "--verify", "--quiet", args.ab + "^{commit}"],
            capture_output=True,
            text=True,
        )
        if known.returncode != 0:
            parser.error(f"--ab: {args.ab!r} is not a commit of this repository")
    endpoint_args = tuple(args.endpoint_arg)
    settings = (
        Settings(
            window_s=2.0,
            throughput_rounds=1,
            rtt_samples={100: 300, 1000: 1000},
            soak_s=10.0,
            quick=True,
            large_rtt_samples=90,
            endpoint_args=endpoint_args,
        )
        if args.quick
        else Settings(
            window_s=5.0,
            throughput_rounds=3,
            rtt_samples={100: 2000, 1000: 5000},
            soak_s=60.0,
            quick=False,
            endpoint_args=endpoint_args,
        )
    )
    # Harness processes (this one stands in for Unity; bench/endpoint_rosnode.py for the rospy nodes) freeze what
    # start-up made, as the endpoint does, so no side is charged for a harness's full GC pass over its modules.
    gc.collect()
    gc.freeze()
    with contextlib.ExitStack() as stack:
        sides = [("this tree" if args.ab else str(args.bridge_dir or REPO), args.bridge_dir)]
        if args.ab is not None:
            sides.append((args.ab, stack.enter_context(worktree_of(args.ab))))
        if args.their_first:
            sides.reverse()
        return run(settings, sides, args.only or PHASES, args.keep_logs)


def run(settings: Settings, sides: list[tuple[str, Path | None]], phases: tuple[str, ...], keep_logs: bool) -> int:
    """Run the phases for every endpoint in `sides` ((name, bridge directory or None for this tree)), phase by phase
    alternately, on one roscore; print each endpoint's table, and the comparison when there are two."""
    started = time.monotonic()
    load_at_start = os.getloadavg()[0]
    core = RosCore()
    log_dir = core.tmp / "bench"
    log_dir.mkdir()
    benches: list[Bench] = []
    failed = True
    try:
        for index, (_, bridge_dir) in enumerate(sides):
            side_logs = log_dir / f"side{index}"
            side_logs.mkdir()
            benches.append(Bench(replace(settings, bridge_dir=bridge_dir), core, side_logs, f"bench_endpoint_{index}"))
        for name in phases:
            for (side, _), bench in zip(sides, benches):
                print(f"[{time.monotonic() - started:5.0f} s] {name} ({side}) ...", file=sys.stderr, flush=True)
                phase: Callable[[], None] = getattr(bench, name)
                phase()
        for (side, _), bench in zip(sides, benches):
            alive = bench.endpoint.process.poll() is None
            bench.rows.append(Row("Endpoint alive at the end", "yes" if alive else "NO", ok=alive))
            header = (
                f"ROS-TCP endpoint benchmark ({'quick' if settings.quick else 'full'} run, "
                f"{time.monotonic() - started:.0f} s): {MESSAGE_NAME} 7 joints, {len(bench.payload)} B payload; "
                f"{os.cpu_count()} CPUs; Python {sys.version.split()[0]}; TCP congestion control "
                f"{congestion_control()} (rospy's connections; the endpoint's local clients are never paced); "
                f"endpoint: {side} "
                f"{' '.join(settings.endpoint_args)}\nload average (1 min) at start {load_at_start:.2f}, at end "
                f"{os.getloadavg()[0]:.2f} (other processes on these CPUs skew every figure)"
            )
            print_table(bench.rows, header)
            print()
        if len(benches) == 2:  # this tree's figures over the other's, whichever ran first
            (ours, our_bench), (theirs, their_bench) = sorted(
                zip(sides, benches), key=lambda side_bench: side_bench[0][1] is not None
            )
            compare_tables(our_bench.rows, their_bench.rows, ours[0], theirs[0])
        failed = False
    finally:
        for bench in benches:
            bench.close()
        stop_core(core, keep_logs or failed)
    return 0


def congestion_control() -> str:
    """The kernel's default TCP congestion control: with BBR, rospy's loopback connections (the ceilings) are paced."""
    try:
        return Path("/proc/sys/net/ipv4/tcp_congestion_control").read_text().strip()
    except OSError:
        return "unknown"


def stop_core(core: RosCore, keep_logs: bool) -> None:
    """Stop the benchmark's roscore; its logs and the nodes' are kept (their path printed) or removed."""
    core.stop(keep_logs=keep_logs)
    if keep_logs:
        print(f"logs kept in {core.tmp}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
