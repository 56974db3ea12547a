"""An endpoint process as the tests and benches measure it: its figures count from when it has settled."""

from __future__ import annotations

from sim.processes import RosCore, wait_for


def settled(roscore: RosCore, node: str, timeout: float = 10.0) -> None:
    """Until the endpoint `node` has all its own threads started (the last, /diagnostics' publisher, comes with its
    first tick): the baseline for counting its threads and descriptors."""
    wait_for(lambda: node in roscore.publishers("/diagnostics"), timeout, f"{node} to publish /diagnostics")
