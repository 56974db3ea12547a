"""The endpoint across machines: roscore on one host, the endpoint on a second, its client on a third, emulated by
network namespaces joined by veth links (sim.campaign.trials.network_hosts: 198.18.71.0/24 between ROS and the
endpoint, 198.18.72.0/24 between the endpoint and its client; made and removed here). No traffic leaves them.

What must work: topics and services both ways with ROS_IP or ROS_HOSTNAME set as the ROS wiki says. What must be
said at start-up, in one line naming the fix: the hostname trap (the name resolves to 127.0.1.1), a multi-homed
machine advertising the wrong network, a master that cannot be reached, an endpoint listening on loopback while ROS
runs across machines, and a port already taken. Each machine's /etc/hosts is its namespace's own
(/etc/netns/NAME/hosts, which `ip netns exec` mounts over /etc/hosts).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from sim.campaign.trials import Namespaces, network_hosts
from sim.processes import PYTHON, REPO, EndpointProcess, ManagedProcess, RosCore, plain_env, wait_for
from tests.integration.three_machines import (
    BRIDGE,
    BRIDGE_CLIENT_SIDE,
    ENDPOINT_NAME,
    FAR_ENDS,
    HOSTNAME,
    ROS,
    endpoint_env,
    hosts_file,
)

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))


@pytest.fixture(scope="module")
def hosts() -> Iterator[Namespaces]:
    """The three machines; the master's resolves the endpoint's name from the start, as the ROS wiki asks of
    ROS_HOSTNAME (a master started before it could would never reach the endpoint)."""
    with network_hosts("xm") as spaces, hosts_file(spaces.ros, {ENDPOINT_NAME: BRIDGE}):
        yield spaces


def start_up_output(hosts: Namespaces, env: dict[str, str], tmp_path: Path, host: str, until: str) -> str:
    """What the endpoint on the middle machine says at start-up, up to `until` (the end of the line awaited)."""
    endpoint = EndpointProcess(env, tmp_path, host=host, prefix=hosts.prefix(hosts.bridge))
    try:
        return endpoint.wait_for_output(until, timeout=10)
    finally:
        endpoint.stop()


def start_failing(command: list[str], env: dict[str, str], log_dir: Path, prefix: list[str]) -> tuple[int, str]:
    process = ManagedProcess(command, env, log_dir, "endpoint", prefix)
    try:
        code = process.wait(30)
    finally:
        process.stop()
    return code, process.output()


def run_far_ends(hosts: Namespaces, master: RosCore, endpoint: EndpointProcess, tmp_path: Path) -> str:
    """The ROS peer on the master's host and the client on the third: their output once all four exchanges are
    done (topics and services both ways)."""
    module = ["-m", "tests.integration.netns_peers"]
    ros = ManagedProcess([PYTHON, *module, "ros"], master.env, tmp_path, "ros_peer", hosts.prefix(hosts.ros))
    client_env = dict(plain_env(), PYTHONPATH=str(REPO))
    client = ManagedProcess(
        [PYTHON, *module, "client", BRIDGE_CLIENT_SIDE, str(endpoint.port)],
        client_env,
        tmp_path,
        "client",
        hosts.prefix(hosts.engine),
    )
    try:
        wait_for(
            lambda: all(line in ros.output() + client.output() for line in FAR_ENDS),
            30,
            "topics and services both ways",
        )
        return ros.output() + client.output()
    except Exception:
        print(ros.output(), client.output(), endpoint.output(), sep="\n---\n")
        raise
    finally:
        client.stop()
        ros.stop()


@pytest.mark.parametrize("how", ["ROS_IP", "ROS_HOSTNAME"])
def test_topics_and_services_both_ways_across_three_hosts(
    hosts: Namespaces, far_master: RosCore, tmp_path: Path, how: str
) -> None:
    """As the ROS wiki says: ROS_IP the endpoint's own address on the master's network, or ROS_HOSTNAME a name
    that every machine resolves to it."""
    name = ENDPOINT_NAME
    ros_settings = {"ROS_IP": BRIDGE} if how == "ROS_IP" else {"ROS_HOSTNAME": name}
    with hosts_file(hosts.bridge, {name: BRIDGE, HOSTNAME: "127.0.1.1"}):
        endpoint = EndpointProcess(
            endpoint_env(far_master, **ros_settings), tmp_path, host="0.0.0.0", prefix=hosts.prefix(hosts.bridge)
        )
        try:
            run_far_ends(hosts, far_master, endpoint, tmp_path)
            output = endpoint.output()
        finally:
            endpoint.stop()
    port = endpoint.port
    assert f"clients can connect to {BRIDGE}:{port}, {BRIDGE_CLIENT_SIDE}:{port}, 127.0.0.1:{port}" in output
    shown = BRIDGE if how == "ROS_IP" else name
    assert f"{how}={ros_settings[how]}" in output and f"told to reach this node at {shown}" in output
    assert "[WARNING] [bridge]" not in output, output


def test_a_hostname_resolving_to_loopback_is_named_with_its_fix(
    hosts: Namespaces, far_master: RosCore, tmp_path: Path
) -> None:
    """Ubuntu's /etc/hosts maps the machine's own name to 127.0.1.1; with neither ROS_IP nor ROS_HOSTNAME set,
    rospy advertises that name, and the master's machine cannot reach it."""
    with hosts_file(hosts.bridge, {HOSTNAME: "127.0.1.1"}):
        output = start_up_output(hosts, endpoint_env(far_master), tmp_path, "0.0.0.0", "before starting the endpoint")
    assert (
        f"to reach it at '{HOSTNAME}' (the hostname), which resolves to 127.0.1.1 here, an address no other machine "
        f"can reach: topics to and from other machines will stay empty. Set ROS_IP={BRIDGE}"
    ) in output


def test_a_machine_on_two_networks_advertising_the_wrong_one_is_named(
    hosts: Namespaces, far_master: RosCore, tmp_path: Path
) -> None:
    """The endpoint's machine is on the master's network and on the client's; its name resolves to the client's
    side, so the master's machine is told an address it has no route to."""
    with hosts_file(hosts.bridge, {HOSTNAME: BRIDGE_CLIENT_SIDE}):
        output = start_up_output(hosts, endpoint_env(far_master), tmp_path, "0.0.0.0", f"Set ROS_IP={BRIDGE}")
    assert f"this machine has several networks and tells the ROS master to reach it at '{HOSTNAME}'" in output
    assert f"({BRIDGE_CLIENT_SIDE}), while it reaches the master from {BRIDGE}" in output


def test_listening_on_loopback_while_ros_runs_across_machines_is_named(
    hosts: Namespaces, far_master: RosCore, tmp_path: Path
) -> None:
    env = endpoint_env(far_master, ROS_IP=BRIDGE)
    output = start_up_output(hosts, env, tmp_path, "127.0.0.1", "Pass --tcp-ip 0.0.0.0")
    assert (
        f"the endpoint listens on 127.0.0.1 only, yet the ROS master is on another machine ({far_master.uri}) and "
        f"ROS_IP is {BRIDGE}: a client (Unity) on another machine cannot connect"
    ) in output


@pytest.mark.parametrize("where", ["refused", "no route"])
def test_a_master_that_cannot_be_reached_is_named_at_once(
    hosts: Namespaces, far_master: RosCore, tmp_path: Path, where: str
) -> None:
    """Without --wait, the endpoint says in one line why it cannot start, and exits 2: rospy alone would wait
    without a word."""
    # refused: the master's host, a port nothing listens on; no route: the client's machine has none to ROS's
    namespace, uri = (hosts.bridge, f"http://{ROS}:9/") if where == "refused" else (hosts.engine, far_master.uri)
    env = endpoint_env(far_master, ROS_MASTER_URI=uri, ROS_IP=BRIDGE)
    code, output = start_failing([PYTHON, "-m", "bridge", "--tcp-port", "0"], env, tmp_path, hosts.prefix(namespace))
    assert code == 2, output
    why = "connection refused: no roscore listens there" if where == "refused" else "Network is unreachable"
    assert f"python -m bridge: cannot reach the ROS master at {uri} (ROS_MASTER_URI): " in output
    assert why in output and "Start roscore there, or set ROS_MASTER_URI to where it runs" in output


def test_a_port_already_taken_is_named_with_its_fix(hosts: Namespaces, far_master: RosCore, tmp_path: Path) -> None:
    env = endpoint_env(far_master, ROS_IP=BRIDGE)
    first = EndpointProcess(env, tmp_path, name="first", host="0.0.0.0", prefix=hosts.prefix(hosts.bridge))
    try:
        command = [PYTHON, "-m", "bridge", "--tcp-ip", "0.0.0.0", "--tcp-port", str(first.port), "--node-name", "two"]
        code, output = start_failing(command, env, tmp_path, hosts.prefix(hosts.bridge))
    finally:
        first.stop()
    assert code == 2, output
    assert f"python -m bridge: port {first.port} on 0.0.0.0 is already taken" in output
    assert "choose another with --tcp-port" in output
