"""The endpoint under test and what its phases start around it: the rospy node and raw reader processes, the
TcpClients; and the rows the phases add."""

from __future__ import annotations

import json
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from bench.endpoint_bench.records import Row
from bench.endpoint_bench.settings import Settings
from bench.messages import joint_state_payload
from bridge.client import TcpClient
from measuring.procfs import cpu_seconds, rss_bytes
from sim.processes import PYTHON, EndpointProcess, ManagedProcess, RosCore, endpoint_ports, kill_process

# bench.endpoint_rosnode runs from the repository root (ManagedProcess's working directory), on this Python
ROSNODE = (PYTHON, "-m", "bench.endpoint_rosnode")


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
