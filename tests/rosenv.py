"""Real ROS processes for tests (see sim.processes): roscore on a free port, node subprocesses killed by PID."""

from __future__ import annotations

from sim.processes import (  # noqa: F401  (re-exported for the tests)
    PYTHON,
    REPO,
    EndpointProcess,
    ManagedProcess,
    ProcessError,
    RosCore,
    free_port,
    kill_process,
    wait_for,
)
