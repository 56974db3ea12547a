"""While the endpoint runs: a ROS link of a bridged topic that never comes up is told once to each client bridging
the topic, in an __error naming the topic, the peer and its address, and shown on /diagnostics (bridge.ros.peer_links).
The three machines of tests/integration/test_bridge_across_machines.py (namespaces made and removed here, tag `pl`):
ROS on one, the endpoint on a second, its client on the third; each machine's hosts file maps the hostname they share
to 127.0.1.1, as Ubuntu's does.

Broken both ways at once: the endpoint advertises ROS_HOSTNAME=endpoint-pc, a name its own machine resolves (so it
says nothing at start-up) but the master's machine does not, so the ROS subscriber of the topic the client publishes
never connects; the ROS node advertises its hostname (neither ROS_IP nor ROS_HOSTNAME set), 127.0.1.1 wherever it is
resolved, so the endpoint cannot connect to the publisher of the topic the client subscribes to.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from sim.campaign.trials import Namespaces, network_hosts
from sim.processes import PYTHON, REPO, EndpointProcess, ManagedProcess, RosCore, plain_env, wait_for
from tests.integration.netns_peers import FROM_ROS, TO_ROS
from tests.integration.three_machines import (
    BRIDGE,
    BRIDGE_CLIENT_SIDE,
    ENDPOINT_NAME,
    FAR_ENDS,
    HOSTNAME,
    endpoint_env,
    hosts_file,
)

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))

PEER = "/far_ros_peer"  # the ROS node of tests.integration.netns_peers
# Diagnostics arrays (1 Hz) watched after the fact, long enough for two more checks of the links (every 2 s), or,
# in the working layout, for a link down since the client registered to be found (5 s down, checked every 2 s)
MORE_ARRAYS, ARRAYS_WATCHED = 5, 10


@pytest.fixture(scope="module")
def hosts() -> Iterator[Namespaces]:
    with network_hosts("pl") as spaces, hosts_file(spaces.ros, {HOSTNAME: "127.0.1.1"}):
        with hosts_file(spaces.bridge, {HOSTNAME: "127.0.1.1", ENDPOINT_NAME: BRIDGE}):
            yield spaces


class Layout:
    """The endpoint, the ROS node on the master's machine, the client on the third, and, when asked, a /diagnostics
    reader on the endpoint's machine (the one place the endpoint's own address surely works)."""

    def __init__(
        self, hosts: Namespaces, master: RosCore, tmp_path: Path, ros_env: dict[str, str], bridge_env: dict[str, str]
    ) -> None:
        module = ["-m", "tests.integration.netns_peers"]
        self.processes: list[ManagedProcess] = []
        try:
            self.endpoint = self._add(
                EndpointProcess(bridge_env, tmp_path, host="0.0.0.0", prefix=hosts.prefix(hosts.bridge))
            )
            self.ros = self._add(
                ManagedProcess([PYTHON, *module, "ros"], ros_env, tmp_path, "ros", hosts.prefix(hosts.ros))
            )
            client = [PYTHON, *module, "client", BRIDGE_CLIENT_SIDE, str(self.endpoint.port)]
            client_env = dict(plain_env(), PYTHONPATH=str(REPO))
            self.client = self._add(ManagedProcess(client, client_env, tmp_path, "client", hosts.prefix(hosts.engine)))
        except BaseException:
            self.stop()
            raise

        self._diagnostics_command = (
            [PYTHON, *module, "diagnostics"],
            bridge_env,
            tmp_path,
            "diag",
            hosts.prefix(hosts.bridge),
        )

    def read_diagnostics(self) -> None:
        """Start the /diagnostics reader once the endpoint has advertised /diagnostics: the master then names the
        publisher in its answer to the reader's registration. A reader that came first would wait for the master to
        tell it, which a master that cannot reach the endpoint's machine (the broken layout) never does."""
        self.diagnostics = self._add(ManagedProcess(*self._diagnostics_command))

    def _add(self, process: ManagedProcess) -> ManagedProcess:
        self.processes.append(process)
        return process

    def stop(self) -> None:
        for process in reversed(self.processes):
            process.stop()

    def arrays(self) -> list[str]:
        """The /diagnostics arrays read so far: the peer-link warnings each held."""
        lines = self.diagnostics.output().splitlines()
        return [line.split(": ", 1)[1] if ": " in line else "" for line in lines if line.startswith("diagnostics ")]

    def errors_about(self, topic: str) -> list[str]:
        return [line for line in self.client.output().splitlines() if line.startswith(f"error {topic}: ")]

    def watch_more_arrays(self, count: int) -> None:
        seen = len(self.arrays())
        wait_for(lambda: len(self.arrays()) >= seen + count, count * 3, f"{count} more /diagnostics arrays")

    def dump(self) -> None:
        for process in self.processes:
            print(f"--- {process.name}\n{process.output()[-4000:]}")


def test_links_that_cannot_come_up_both_ways_are_told_once_per_topic_and_shown(
    hosts: Namespaces, far_master: RosCore, tmp_path: Path
) -> None:
    ros_env = {k: v for k, v in far_master.env.items() if k not in ("ROS_IP", "ROS_HOSTNAME")}
    layout = Layout(hosts, far_master, tmp_path, ros_env, endpoint_env(far_master, ROS_HOSTNAME=ENDPOINT_NAME))
    to_link, from_link = f"topic {TO_ROS}: link to {PEER}", f"topic {FROM_ROS}: link from {PEER}"
    try:
        wait_for(
            lambda: layout.errors_about(TO_ROS) and layout.errors_about(FROM_ROS),
            40,
            "an __error about each topic",
        )
        layout.read_diagnostics()
        wait_for(lambda: any(to_link in a and from_link in a for a in layout.arrays()[-1:]), 20, "/diagnostics")
        layout.watch_more_arrays(MORE_ARRAYS)
        to_ros, from_ros, arrays = layout.errors_about(TO_ROS), layout.errors_about(FROM_ROS), layout.arrays()
        start_up = layout.endpoint.output()
    except BaseException:
        layout.dump()
        raise
    finally:
        layout.stop()
    assert len(to_ros) == 1 and len(from_ros) == 1, (to_ros, from_ros)
    assert all(to_link in array and from_link in array for array in arrays[-MORE_ARRAYS:]), arrays
    peer_uri = f"http://{HOSTNAME}:"
    # the client publishes /far/to_ros: the ROS node subscribes, and cannot reach the endpoint's advertised name
    assert to_ros[0].startswith(f"error {TO_ROS}: the ROS node {PEER} ({peer_uri}"), to_ros
    assert f"that machine cannot reach this node at http://{ENDPOINT_NAME}:" in to_ros[0]
    assert "On the endpoint's machine set ROS_IP" in to_ros[0]
    # the client subscribes to /far/from_ros: the endpoint cannot reach its ROS publisher at 127.0.1.1
    assert from_ros[0].startswith(f"error {FROM_ROS}: the endpoint cannot connect to its ROS publisher {PEER} at "), (
        from_ros
    )
    assert f"at {peer_uri}" in from_ros[0] and "(connection to 127.0.1.1:" in from_ros[0] and "refused)" in from_ros[0]
    assert "On that node's machine set ROS_IP" in from_ros[0]
    # the endpoint's own side looked right: start-up said nothing, only the links told
    assert "[WARNING]" not in start_up.split("connected; handshake sent")[0], start_up


def test_the_working_layout_gets_no_word_about_links(hosts: Namespaces, far_master: RosCore, tmp_path: Path) -> None:
    layout = Layout(hosts, far_master, tmp_path, far_master.env, endpoint_env(far_master, ROS_IP=BRIDGE))
    try:
        wait_for(
            lambda: all(line in layout.ros.output() + layout.client.output() for line in FAR_ENDS),
            30,
            "topics and services both ways",
        )
        layout.read_diagnostics()
        layout.watch_more_arrays(ARRAYS_WATCHED)
        errors, arrays = layout.errors_about(TO_ROS) + layout.errors_about(FROM_ROS), layout.arrays()
    except BaseException:
        layout.dump()
        raise
    finally:
        layout.stop()
    assert errors == []
    assert arrays and all(array == "" for array in arrays), arrays
