"""The three machines the endpoint's across-machines tests emulate with network namespaces
(sim.campaign.trials.network_hosts): ROS on one, the endpoint on a second, its client on a third. Their addresses,
each machine's hosts file, and the environments their processes get. The master on the ROS machine is the fixture
`far_master` (tests/integration/conftest.py), which uses the requesting module's `hosts`."""

from __future__ import annotations

import contextlib
import shutil
import socket
from collections.abc import Iterator
from pathlib import Path

from sim.campaign.trials import NETNS_HOSTS
from sim.processes import RosCore

__all__ = [
    "BRIDGE",
    "BRIDGE_CLIENT_SIDE",
    "CLIENT",
    "ENDPOINT_NAME",
    "FAR_ENDS",
    "HOSTNAME",
    "ROS",
    "endpoint_env",
    "hosts_file",
]

ROS, BRIDGE, BRIDGE_CLIENT_SIDE, CLIENT = (
    NETNS_HOSTS["ros"],
    NETNS_HOSTS["bridge"],
    NETNS_HOSTS["bridge_engine_side"],
    NETNS_HOSTS["engine"],
)
HOSTNAME = socket.gethostname()  # namespaces share the machine's hostname; each resolves it by its own hosts file
FAR_ENDS = (
    "ok ros heard the client",
    "ok ros called the client's service",
    "ok client called the ros service",
    "ok client heard ros",
)


@contextlib.contextmanager
def hosts_file(namespace: str, entries: dict[str, str]) -> Iterator[None]:
    """/etc/hosts as processes in `namespace` see it, while the block runs: localhost plus name -> address."""
    folder = Path("/etc/netns") / namespace
    folder.mkdir(parents=True, exist_ok=True)
    lines = ["127.0.0.1 localhost", "::1 localhost", *(f"{address} {name}" for name, address in entries.items())]
    (folder / "hosts").write_text("\n".join(lines) + "\n")
    try:
        yield
    finally:
        shutil.rmtree(folder, ignore_errors=True)


ENDPOINT_NAME = "endpoint-pc"  # the endpoint's machine by name, as every machine's hosts file has it


def endpoint_env(master: RosCore, **ros: str) -> dict[str, str]:
    """The master's environment without its ROS_IP/ROS_HOSTNAME (those are the ROS host's), plus `ros`."""
    env = {k: v for k, v in master.env.items() if k not in ("ROS_IP", "ROS_HOSTNAME")}
    return {**env, **ros}
