"""The network as the endpoint sees it at start-up: the facts bridge.ros.reachability judges, and whether the ROS master
answers at all. Only the standard library and rosgraph (how ROS itself names this node's host and finds the master).

Local addresses come from the kernel (an ioctl per interface for IPv4, /proc/net/if_inet6 for IPv6), not from
rosgraph's own look-up, which needs netifaces: Debian builds that for its own Python only, not for Noetic's 3.8.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import socket
import struct
import xmlrpc.client
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

import rosgraph
import rosgraph.network

from bridge.ros.reachability import NetworkFacts

__all__ = ["MASTER_PROBE_S", "MasterProblem", "gather_facts", "master_problem", "port_problem"]

MASTER_PROBE_S = 3.0  # how long the master has to answer at start-up before the endpoint says it cannot reach it

_SIOCGIFADDR = 0x8915
CONTAINER_MARKS = ("/.dockerenv", "/run/.containerenv")  # Docker's and Podman's


def _ipv4_addresses() -> list[str]:
    found = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        for _, name in socket.if_nameindex():
            try:
                reply = fcntl.ioctl(probe.fileno(), _SIOCGIFADDR, struct.pack("256s", name.encode()[:15]))
            except OSError:  # an interface without an IPv4 address
                continue
            found.append(socket.inet_ntoa(reply[20:24]))
    return found


def _ipv6_addresses() -> list[str]:
    table = Path("/proc/net/if_inet6")
    if not table.exists():
        return []
    found = []
    for line in table.read_text().splitlines():
        hexed = line.split()[0]
        found.append(socket.inet_ntop(socket.AF_INET6, bytes.fromhex(hexed)))
    return found


def local_addresses() -> tuple[str, ...]:
    return tuple(dict.fromkeys([*_ipv4_addresses(), *_ipv6_addresses()]))


def _resolve(host: str) -> tuple[str, ...]:
    try:
        infos = socket.getaddrinfo(host, None, proto=socket.IPPROTO_TCP)
    except (OSError, UnicodeError):
        return ()
    return tuple(dict.fromkeys(str(info[4][0]) for info in infos))


def _route_from(address: str) -> str | None:
    """The local address the kernel would send from to reach `address` (a UDP connect sends nothing)."""
    family = socket.AF_INET6 if ":" in address else socket.AF_INET
    with socket.socket(family, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect((address, 9))
        except OSError:
            return None
        return str(probe.getsockname()[0])


def gather_facts(bind_address: str, port: int) -> NetworkFacts:
    master_uri = rosgraph.get_master_uri()
    master_host = urlsplit(master_uri).hostname or ""
    master_addresses = _resolve(master_host)
    advertised = rosgraph.network.get_host_name()
    return NetworkFacts(
        ros_ip=os.environ.get("ROS_IP") or None,
        ros_hostname=os.environ.get("ROS_HOSTNAME") or None,
        advertised_host=advertised,
        advertised_addresses=_resolve(advertised),
        local_addresses=local_addresses(),
        master_uri=master_uri,
        master_addresses=master_addresses,
        route_to_master=_route_from(master_addresses[0]) if master_addresses else None,
        bind_address=bind_address,
        port=port,
        in_container=any(Path(mark).exists() for mark in CONTAINER_MARKS),
    )


class _TimeoutTransport(xmlrpc.client.Transport):
    def __init__(self, timeout: float) -> None:
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host: object) -> object:  # type: ignore[override]
        connection = super().make_connection(host)  # type: ignore[arg-type]
        connection.timeout = self._timeout
        return connection


@dataclass(frozen=True)
class MasterProblem:
    """Why the master did not answer, in one line; `certain` when it cannot be there (refused, no such name, no
    route), as against a silence that a master on a starved machine might still end."""

    line: str
    certain: bool


def master_problem(timeout: float = MASTER_PROBE_S) -> MasterProblem | None:
    """None when the ROS master answers within the timeout; else why not and what to do."""
    uri = rosgraph.get_master_uri()
    host = urlsplit(uri).hostname or ""
    where = f"cannot reach the ROS master at {uri} (ROS_MASTER_URI)"
    if not _resolve(host):
        return MasterProblem(f"{where}: the name '{host}' does not resolve here", certain=True)
    proxy = xmlrpc.client.ServerProxy(uri, transport=_TimeoutTransport(timeout))
    certain = True
    try:
        proxy.getPid("/ros_tcp_endpoint")
    except ConnectionRefusedError:
        why = "connection refused: no roscore listens there"
    except socket.timeout:
        why, certain = f"no answer within {timeout:g} s: a firewall, or a wrong address", False
    except OSError as error:
        why = error.strerror or str(error)
    except (xmlrpc.client.Error, ValueError) as error:
        why = f"what answers is not a ROS master ({error})"
    else:
        return None
    finally:
        with contextlib.suppress(Exception):
            proxy("close")()
    fix = "Start roscore there, or set ROS_MASTER_URI to where it runs; --wait waits for it"
    return MasterProblem(f"{where}: {why}. {fix}", certain)


def port_problem(error: OSError, address: str, port: int) -> str:
    """One line for a failed listen on address:port, naming the fix."""
    if error.errno == errno.EADDRINUSE:
        return (
            f"port {port} on {address} is already taken (another endpoint still running? `ss -ltnp 'sport = :{port}'` "
            "shows who has it): stop that program, or choose another with --tcp-port"
        )
    if error.errno == errno.EADDRNOTAVAIL:
        return (
            f"{address} is not an address of this machine, so the endpoint cannot listen on it: pass --tcp-ip with "
            "one of this machine's addresses, or 0.0.0.0 for all of them"
        )
    return f"cannot listen on {address}:{port}: {error}"
