"""Whether the endpoint can be reached across machines, from facts gathered at start-up (pure; bridge.ros.network
gathers them).

ROS 1 has a quiet trap: every node tells the master an address of its own (the host in its URIs: ROS_HOSTNAME,
else ROS_IP, else the machine's hostname), and every peer connects to that address. When a peer cannot reach it,
topics simply stay empty. The endpoint cannot test the master's side of the link, but it can see the usual causes
on its own: a hostname that resolves to 127.0.1.1 (Ubuntu's default) while the master runs elsewhere, a ROS_IP that is
not this machine's, a multi-homed machine advertising another network than the master's, or an endpoint listening on
loopback while ROS runs across machines. Each finding is one line that names the fix.
"""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass

__all__ = ["NetworkFacts", "findings", "is_loopback", "reachable_at", "summary"]


def is_loopback(address: str) -> bool:
    """True for 127.0.0.0/8, ::1 and ::ffff:127.x; False for anything that is not an IP address."""
    try:
        ip = ipaddress.ip_address(address.split("%")[0])
    except ValueError:
        return False
    mapped = getattr(ip, "ipv4_mapped", None)
    return bool((mapped or ip).is_loopback)


def _is_wildcard(address: str) -> bool:
    return address in ("0.0.0.0", "::", "")


@dataclass(frozen=True)
class NetworkFacts:
    """What the endpoint knows about its network at start-up. Addresses are strings as the system gives them."""

    ros_ip: str | None  # the ROS_IP environment variable (None: unset)
    ros_hostname: str | None  # ROS_HOSTNAME
    advertised_host: str  # the host in the node's URIs, as the master and every peer are told
    advertised_addresses: tuple[str, ...]  # what that host resolves to on this machine (empty: it does not)
    local_addresses: tuple[str, ...]  # this machine's interface addresses, loopback included
    master_uri: str
    master_addresses: tuple[str, ...]  # what the master's host resolves to here
    route_to_master: str | None  # the local address this machine reaches the master from (None: no route)
    bind_address: str  # the endpoint's tcp_ip
    port: int
    in_container: bool = False  # Docker's or Podman's mark is on this machine's file system

    @property
    def master_is_remote(self) -> bool:
        """The master runs on another machine: none of its addresses is this machine's or loopback."""
        local = set(self.local_addresses)
        return bool(self.master_addresses) and not any(
            is_loopback(address) or address in local for address in self.master_addresses
        )

    @property
    def non_loopback_addresses(self) -> tuple[str, ...]:
        return tuple(a for a in self.local_addresses if not is_loopback(a) and not a.lower().startswith("fe80:"))


def reachable_at(facts: NetworkFacts) -> list[str]:
    """host:port pairs on which a client can reach the endpoint: every address of this machine when it listens on
    all of them, else the one it listens on."""
    if _is_wildcard(facts.bind_address):
        addresses = [*facts.non_loopback_addresses, *(a for a in facts.local_addresses if is_loopback(a))]
    else:
        addresses = [facts.bind_address]
    return [f"[{a}]:{facts.port}" if ":" in a else f"{a}:{facts.port}" for a in addresses]


def summary(facts: NetworkFacts) -> list[str]:
    """The start-up lines: where clients connect, and the ROS network settings in force."""
    lines = ["clients can connect to " + ", ".join(reachable_at(facts))]
    if facts.in_container and is_loopback(facts.bind_address):
        # a note, not a warning: ROS and its clients may all be in this container
        lines.append(
            "in a container: a port it publishes (docker run -p) arrives on the container's own address, which an "
            f"endpoint on {facts.bind_address} refuses; clients outside it need --tcp-ip 0.0.0.0"
        )
    return [
        *lines,
        f"ROS_IP={facts.ros_ip or '(unset)'} ROS_HOSTNAME={facts.ros_hostname or '(unset)'}; the ROS master "
        f"({facts.master_uri}) and other nodes are told to reach this node at {facts.advertised_host}",
    ]


def _fix_address(facts: NetworkFacts) -> str:
    """The address to suggest for ROS_IP: the one this machine reaches the master from, else any of its own."""
    if facts.route_to_master and not is_loopback(facts.route_to_master):
        return facts.route_to_master
    return facts.non_loopback_addresses[0] if facts.non_loopback_addresses else "<this machine's address>"


def findings(facts: NetworkFacts) -> list[str]:
    """Each problem found, in one line naming its fix; empty when nothing looks wrong."""
    found = []
    fix = _fix_address(facts)
    local = set(facts.local_addresses)
    if facts.ros_ip and not _is_wildcard(facts.ros_ip) and facts.ros_ip not in local:
        mine = ", ".join(facts.non_loopback_addresses) or "loopback only"
        found.append(
            f"ROS_IP={facts.ros_ip} is not an address of this machine ({mine}): peers told to connect there reach "
            f"nothing; set ROS_IP to this machine's address on the master's network ({fix})"
        )
    if facts.master_is_remote:
        source = "ROS_HOSTNAME" if facts.ros_hostname else "ROS_IP" if facts.ros_ip else "the hostname"
        if not facts.advertised_addresses:
            found.append(
                f"this node tells the ROS master on another machine to reach it at '{facts.advertised_host}' "
                f"({source}), a name that does not resolve even here: set ROS_IP={fix} before starting the endpoint"
            )
        elif all(is_loopback(a) for a in facts.advertised_addresses):
            found.append(
                f"this node tells the ROS master on another machine to reach it at '{facts.advertised_host}' "
                f"({source}), which resolves to {facts.advertised_addresses[0]} here, an address no other machine "
                f"can reach: topics to and from other machines will stay empty. Set ROS_IP={fix} (this machine's "
                "address on the master's network) before starting the endpoint"
            )
        elif (
            not facts.ros_ip
            and facts.route_to_master
            and facts.route_to_master not in facts.advertised_addresses
            and len(facts.non_loopback_addresses) > 1
        ):
            found.append(
                f"this machine has several networks and tells the ROS master to reach it at "
                f"'{facts.advertised_host}' ({', '.join(facts.advertised_addresses)}), while it reaches the master "
                f"from {facts.route_to_master}: if the master's machine cannot reach the former, topics stay empty. "
                f"Set ROS_IP={facts.route_to_master}"
            )
    if is_loopback(facts.bind_address):
        hints = []
        if facts.master_is_remote:
            hints.append(f"the ROS master is on another machine ({facts.master_uri})")
        if facts.ros_ip and not is_loopback(facts.ros_ip) and not _is_wildcard(facts.ros_ip):
            hints.append(f"ROS_IP is {facts.ros_ip}")
        if hints:
            found.append(
                f"the endpoint listens on {facts.bind_address} only, yet {' and '.join(hints)}: a client (Unity) on "
                f"another machine cannot connect. Pass --tcp-ip 0.0.0.0, or this machine's address (e.g. {fix}); "
                "the endpoint binds its tcp_ip setting (~tcp_ip, or the /ROS_IP rosparam), not the ROS_IP "
                "environment variable"
            )
    return found
