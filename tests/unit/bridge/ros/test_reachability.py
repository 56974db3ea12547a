"""What the endpoint says at start-up about being reached across machines (bridge.ros.reachability, pure)."""

from __future__ import annotations

from dataclasses import replace

from bridge.ros.reachability import NetworkFacts, findings, is_loopback, reachable_at, summary

# The endpoint's machine: on the master's network (10.0.0.0/24) and a second one (192.168.5.0/24)
FACTS = NetworkFacts(
    ros_ip="10.0.0.2",
    ros_hostname=None,
    advertised_host="10.0.0.2",
    advertised_addresses=("10.0.0.2",),
    local_addresses=("127.0.0.1", "10.0.0.2", "192.168.5.7", "::1", "fe80::1"),
    master_uri="http://10.0.0.1:11311/",
    master_addresses=("10.0.0.1",),
    route_to_master="10.0.0.2",
    bind_address="0.0.0.0",
    port=10000,
)
UBUNTU_HOSTNAME = replace(FACTS, ros_ip=None, advertised_host="labpc", advertised_addresses=("127.0.1.1",))


def test_loopback_is_recognised_in_every_spelling() -> None:
    assert all(is_loopback(a) for a in ("127.0.0.1", "127.0.1.1", "::1", "::ffff:127.0.0.1"))
    assert not any(is_loopback(a) for a in ("10.0.0.2", "::ffff:10.0.0.2", "labpc", "", "0.0.0.0"))


def test_listening_on_every_address_lists_each_non_loopback_one_first() -> None:
    assert reachable_at(FACTS) == ["10.0.0.2:10000", "192.168.5.7:10000", "127.0.0.1:10000", "[::1]:10000"]
    assert reachable_at(replace(FACTS, bind_address="10.0.0.2")) == ["10.0.0.2:10000"]


def test_the_summary_names_the_ros_settings_in_force() -> None:
    assert summary(UBUNTU_HOSTNAME)[-1] == (
        "ROS_IP=(unset) ROS_HOSTNAME=(unset); the ROS master (http://10.0.0.1:11311/) and other nodes are told to "
        "reach this node at labpc"
    )


def test_a_set_up_that_works_says_nothing() -> None:
    assert findings(FACTS) == []
    # all on one machine: loopback everywhere is fine
    alone = replace(
        UBUNTU_HOSTNAME,
        master_uri="http://localhost:11311/",
        master_addresses=("127.0.0.1", "::1"),
        route_to_master="127.0.0.1",
        bind_address="127.0.0.1",
    )
    assert findings(alone) == []


def test_a_hostname_resolving_to_loopback_with_a_remote_master_names_ros_ip() -> None:
    (finding,) = findings(UBUNTU_HOSTNAME)
    assert finding.startswith(
        "this node tells the ROS master on another machine to reach it at 'labpc' (the hostname), which resolves "
        "to 127.0.1.1 here"
    )
    assert finding.endswith(
        "Set ROS_IP=10.0.0.2 (this machine's address on the master's network) before starting the endpoint"
    )


def test_a_name_that_does_not_resolve_is_named() -> None:
    (finding,) = findings(replace(UBUNTU_HOSTNAME, ros_hostname="labpc", advertised_addresses=()))
    assert "at 'labpc' (ROS_HOSTNAME), a name that does not resolve even here: set ROS_IP=10.0.0.2" in finding


def test_a_multi_homed_machine_advertising_its_other_network_is_named() -> None:
    other = replace(UBUNTU_HOSTNAME, advertised_addresses=("192.168.5.7",))
    (finding,) = findings(other)
    assert "several networks" in finding and "while it reaches the master from 10.0.0.2" in finding
    assert finding.endswith("Set ROS_IP=10.0.0.2")
    # one network only: the advertised address is the one there is
    single = replace(other, local_addresses=("127.0.0.1", "192.168.5.7"), route_to_master="192.168.5.7")
    assert findings(single) == []


def test_a_ros_ip_of_another_machine_is_named() -> None:
    (finding,) = findings(
        replace(FACTS, ros_ip="10.0.0.9", advertised_host="10.0.0.9", advertised_addresses=("10.0.0.9",))
    )
    assert finding.startswith("ROS_IP=10.0.0.9 is not an address of this machine (10.0.0.2, 192.168.5.7)")
    assert finding.endswith("set ROS_IP to this machine's address on the master's network (10.0.0.2)")


def test_listening_on_loopback_while_ros_runs_across_machines_is_named() -> None:
    (finding,) = findings(replace(FACTS, bind_address="127.0.0.1"))
    assert finding.startswith(
        "the endpoint listens on 127.0.0.1 only, yet the ROS master is on another machine (http://10.0.0.1:11311/) "
        "and ROS_IP is 10.0.0.2: a client (Unity) on another machine cannot connect. Pass --tcp-ip 0.0.0.0"
    )
    # ROS_IP alone says so too: users set it expecting the endpoint to listen there
    local_master = replace(
        FACTS, bind_address="127.0.0.1", master_addresses=("127.0.0.1",), master_uri="http://localhost:11311/"
    )
    (finding,) = findings(local_master)
    assert "yet ROS_IP is 10.0.0.2" in finding and "not the ROS_IP environment variable" in finding


def test_listening_on_loopback_in_a_container_is_noted_not_warned() -> None:
    """Inside Docker, a published port (-p 10000:10000) reaches the container's own address, which an endpoint on
    loopback refuses; ROS and every client may be in the container too, so it is a note beside the addresses."""
    alone = replace(
        UBUNTU_HOSTNAME,
        master_uri="http://localhost:11311/",
        master_addresses=("127.0.0.1",),
        bind_address="127.0.0.1",
        in_container=True,
    )
    assert findings(alone) == []
    note = summary(alone)[1]
    assert note.startswith("in a container: a port it publishes (docker run -p) arrives on the container's own")
    assert note.endswith("clients outside it need --tcp-ip 0.0.0.0")
    assert len(summary(replace(alone, bind_address="0.0.0.0"))) == 2
