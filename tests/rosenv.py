"""Real ROS processes for tests (see sim.processes): roscore on a free port, node subprocesses killed by PID."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from sim.processes import (  # noqa: F401  (re-exported for the tests)
    PYTHON,
    REPO,
    ManagedProcess,
    ProcessError,
    RosCore,
    free_port,
    kill_process,
    wait_for,
)

NodeProcess = ManagedProcess


class EndpointProcess(ManagedProcess):
    """`python -m bridge --tcp-port 0` on the session's roscore; `port` is the port it reports."""

    def __init__(self, env: dict[str, str], log_dir: Path, name: str = "endpoint", extra: Sequence[str] = ()) -> None:
        super().__init__(
            [PYTHON, "-m", "bridge", "--tcp-port", "0", "--node-name", name, *extra], env, log_dir, name
        )
        text = self.wait_for_output("listening on", timeout=30)
        line = next(line for line in text.splitlines() if "listening on" in line)
        self.port = int(line.rsplit(":", 1)[1])
