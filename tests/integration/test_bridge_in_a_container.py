"""The endpoint in a Docker container, as docs/across_machines.md tells a new user to run it, with network namespaces
standing in (tag `dk`, made and removed here): the container (roscore, a ROS node and the endpoint, all inside,
nothing set but what Docker sets: the container's hostname resolves to its own address), the machine that runs it
(where `docker run -p PORT:PORT` puts a relay from the machine's port to the container's, as docker-proxy does), and
Unity's PC, which knows only the machine's address. Host networking needs no test of its own: the container is then
the machine, and tests/integration/test_bridge_across_machines.py covers an endpoint on a machine of its own, with
ROS_IP or ROS_HOSTNAME set.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from sim.campaign.trials import Namespaces, network_hosts
from sim.processes import PYTHON, REPO, EndpointProcess, ManagedProcess, RosCore, plain_env, wait_for
from tests.integration.three_machines import (
    BRIDGE_CLIENT_SIDE,
    FAR_ENDS,
    HOSTNAME,
    ROS,
    endpoint_env,
    hosts_file,
)

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))

CONTAINER = ROS  # the container's own address (Docker's 172.17.0.x), on the link to the machine that runs it
PUBLISHED_PORT = 10000  # docker run -p 10000:10000; the namespaces are ours alone, so a fixed port is free


@pytest.fixture(scope="module")
def machines() -> Iterator[Namespaces]:
    """ros: the container; bridge: the machine running it; engine: Unity's PC."""
    with network_hosts("dk") as spaces, hosts_file(spaces.ros, {HOSTNAME: CONTAINER}):
        yield spaces


@pytest.mark.parametrize("listen", ["0.0.0.0", "127.0.0.1"])
def test_unity_reaches_an_endpoint_in_a_container_through_its_published_port(
    machines: Namespaces, tmp_path: Path, listen: str
) -> None:
    """As the docs say: through a published port with --tcp-ip 0.0.0.0, topics and services work both ways with no
    ROS_IP set; on the default 127.0.0.1 the container refuses what the published port brings."""
    inside = machines.prefix(machines.ros)
    master = RosCore(host=CONTAINER, prefix=inside)
    processes: list[ManagedProcess] = [master]
    try:
        env = endpoint_env(master)  # neither ROS_IP nor ROS_HOSTNAME: the container's hostname is its address
        endpoint = EndpointProcess(env, tmp_path, host=listen, prefix=inside)
        processes.append(endpoint)
        module = [PYTHON, "-m", "tests.integration.netns_peers"]
        published = ["port", "0.0.0.0", str(PUBLISHED_PORT), CONTAINER, str(endpoint.port)]
        docker_proxy = ManagedProcess([*module, *published], env, tmp_path, "port", machines.prefix(machines.bridge))
        processes.append(docker_proxy)
        docker_proxy.wait_for_output("ok listening", timeout=20)
        ros_node = ManagedProcess([*module, "ros"], env, tmp_path, "ros", inside)
        processes.append(ros_node)
        unity = [*module, "client", BRIDGE_CLIENT_SIDE, str(PUBLISHED_PORT)]
        client_env = dict(plain_env(), PYTHONPATH=str(REPO))
        client = ManagedProcess(unity, client_env, tmp_path, "client", machines.prefix(machines.engine))
        processes.append(client)
        if listen == "0.0.0.0":
            wait_for(
                lambda: all(line in ros_node.output() + client.output() for line in FAR_ENDS),
                30,
                "topics and services both ways",
            )
        else:
            docker_proxy.wait_for_output("Connection refused", timeout=20)
        start_up, heard = endpoint.output(), client.output()
    except BaseException:
        for process in processes:
            print(f"--- {process.name}\n{process.output()[-3000:]}")
        raise
    finally:
        for process in reversed(processes):
            process.stop()
    if listen == "0.0.0.0":
        assert f"clients can connect to {CONTAINER}:{endpoint.port}" in start_up
        assert "[WARNING]" not in start_up, start_up  # nothing is wrong: no start-up warning
    else:
        assert "ok client heard ros" not in heard
