"""The endpoint under test and what its phases start around it: the rospy node and raw reader processes, the
TcpClients, and the rows of the table; the records a flow keeps (Arrivals, Flow)."""

from __future__ import annotations

import json
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.endpoint_bench.settings import Settings
from bench.messages import joint_state_payload, read_stamp
from bridge.client import TcpClient
from measuring.procfs import cpu_seconds, rss_bytes
from sim.processes import PYTHON, EndpointProcess, ManagedProcess, RosCore, endpoint_ports, kill_process

# bench.endpoint_rosnode runs from the repository root (ManagedProcess's working directory), on this Python
ROSNODE = (PYTHON, "-m", "bench.endpoint_rosnode")


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


class Harness:
    """One endpoint under test on the run's roscore, with the client and rospy node processes its phases start
    (each stopped by PID at the end) and the rows they add."""

    def __init__(self, settings: Settings, core: RosCore, log_dir: Path, name: str = "bench_endpoint") -> None:
        self.settings = settings
        self.core = core
        self.log_dir = log_dir
        self.payload = joint_state_payload()
        self.processes: list[ManagedProcess] = []
        self.clients: list[TcpClient] = []
        self.rows: list[Row] = []
        self.endpoint = self.track(start_endpoint(core.env, log_dir, settings.bridge_dir, settings.endpoint_args, name))
        self.pid = self.endpoint.process.pid

    # --- process and client plumbing ---------------------------------------------------------------------------
    def track(self, process: Any) -> Any:
        self.processes.append(process)
        return process

    def node(self, role: str, *args: str) -> ManagedProcess:
        return self.track(ManagedProcess([*ROSNODE, role, *args], self.core.env, self.log_dir, f"{role}"))

    def raw_reader(self, *args: str) -> ManagedProcess:
        """A raw TCPROS subscriber process (bench.tcpros_reader), which prints RESULT as the roles do."""
        return self.track(
            ManagedProcess([PYTHON, "-m", "bench.tcpros_reader", *args], self.core.env, self.log_dir, "tcpros_reader")
        )

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
        """The endpoint's CPU seconds so far."""
        return cpu_seconds(self.pid)

    def rss(self) -> int:
        """The endpoint's resident memory now, in bytes."""
        return rss_bytes(self.pid)


def start_endpoint(
    env: dict[str, str], log_dir: Path, bridge_dir: Path | None, extra: tuple[str, ...], name: str = "bench_endpoint"
) -> Any:
    """The endpoint under test, as ROS node `name`: this checkout's (sim.processes.EndpointProcess) or the `bridge`
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
