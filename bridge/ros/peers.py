"""The facts bridge.ros.peer_links judges: which TCPROS links of the bridged topics the master's registrations call for
(one getSystemState), which rospy holds up, and for a link down too long, the peer's address (lookupNode) and what
connecting to it from here gives.
"""

from __future__ import annotations

import socket
from typing import Collection
from urllib.parse import urlsplit

import rospy
import rospy.core
import rospy.impl.registration

from bridge.ros.master import MasterError, call_master
from bridge.ros.peer_links import ANSWERS, PeerLink, PeerProblem

__all__ = ["PROBE_S", "peer_links", "describe_peer"]

PROBE_S = 1.0  # how long connecting to a peer's address from here may take when a link is found down


def peer_links(published: Collection[str], subscribed: Collection[str]) -> tuple[set[PeerLink], set[PeerLink]]:
    """(the links the master's registrations call for, those rospy holds up) for the topics the endpoint publishes
    and subscribes to; MasterError when the master does not answer in time."""
    me = rospy.get_name()
    publishers, subscribers, _ = call_master("getSystemState", me)
    publishing_nodes = {topic: nodes for topic, nodes in publishers}
    subscribing_nodes = {topic: nodes for topic, nodes in subscribers}
    listed = {PeerLink(t, node, True) for t in published for node in subscribing_nodes.get(t, ()) if node != me}
    listed |= {PeerLink(t, node, False) for t in subscribed for node in publishing_nodes.get(t, ()) if node != me}
    manager = rospy.impl.registration.get_topic_manager()
    up = set()
    for topic in published:
        impl = manager.get_publisher_impl(topic)
        # an accepted subscriber's connection is named by its node (the callerid of its handshake)
        up |= {PeerLink(topic, c.endpoint_id, True) for c in (impl.connections if impl else ())}
    for topic in subscribed:
        impl = manager.get_subscriber_impl(topic)
        # a connection to a publisher is made before it is up; the publisher's handshake names its node
        connections = impl.connections if impl else ()
        up |= {
            PeerLink(topic, c.callerid_pub, False) for c in connections if not c.done and c.callerid_pub != "unknown"
        }
    return listed, up


def describe_peer(link: PeerLink, down_s: float) -> PeerProblem:
    """The problem of a link down too long: where the master says its peer is, and whether that answers here."""
    try:
        uri = str(call_master("lookupNode", rospy.get_name(), link.peer))
    except MasterError:
        uri = ""
    return PeerProblem(link, down_s, uri, _reach(uri) if uri else "", rospy.core.get_node_uri() or "")


def _reach(uri: str) -> str:
    """What connecting to the host and port of `uri` gives from here, in a few words."""
    parts = urlsplit(uri)
    host, port = parts.hostname or "", parts.port
    if not host or port is None:
        return f"'{uri}' is not an address"
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError):
        return f"'{host}' does not resolve here"
    family, kind, proto, _, address = infos[0]
    with socket.socket(family, kind, proto) as probe:
        probe.settimeout(PROBE_S)
        try:
            probe.connect(address)
        except ConnectionRefusedError:
            return f"connection to {address[0]}:{port} refused"
        except socket.timeout:
            return f"no answer from {address[0]}:{port} within {PROBE_S:g} s"
        except OSError as error:
            return f"{address[0]}:{port}: {error.strerror or error}"
    return ANSWERS
