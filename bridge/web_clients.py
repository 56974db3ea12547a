"""Who may open a WebSocket to the endpoint, and from where (pure: strings in, decisions out).

Browsers let any page open a WebSocket to any host, loopback and the LAN included, and send the page's origin with
the upgrade request: the server is the only one who can tell a page it trusts from any other page that a browser on
the lab's machine has open (cross-site WebSocket hijacking). So an upgrade that carries an Origin is served only
when the origin matches one of the endpoint's patterns (--websocket-origin); one without an Origin comes from a
program that is not a browser (Unity's player, a Python client, a proxy that checked the page itself) and is served
as a TCP client is.

A proxy in front of the endpoint (the VR page's server) connects from its own address for every browser. It says
whose request it passes on in X-Forwarded-For, which the endpoint believes only from the addresses it is told to
trust (--trusted-proxy): from anyone else the header would let a client choose its own address.
"""

from __future__ import annotations

import fnmatch
import ipaddress
from typing import Sequence

__all__ = ["normal_origin", "origin_allowed", "forwarded_client", "is_address"]


def normal_origin(origin: str) -> str:
    """An origin as patterns are matched against it: lower case (scheme and host are case-insensitive), without
    surrounding space or a trailing slash."""
    return origin.strip().rstrip("/").lower()


def origin_allowed(origin: str | None, patterns: Sequence[str]) -> bool:
    """Whether an upgrade with this Origin header is served: always without one; with one, when it matches one of
    the fnmatch `patterns` (e.g. "http://localhost:8000", "https://*.lab.example", "*" for any page). A page with
    an opaque origin (a file, a sandboxed frame) sends "null", which only the pattern "null" allows."""
    if origin is None:
        return True
    origin = normal_origin(origin)
    return any(
        origin == "null" if pattern == "null" else origin != "null" and fnmatch.fnmatchcase(origin, pattern)
        for pattern in (normal_origin(pattern) for pattern in patterns)
    )


def forwarded_client(header: str | None) -> str | None:
    """The client's address in a trusted proxy's X-Forwarded-For: the last one listed (the proxy's own entry;
    those before it were written by whoever the proxy heard from, and prove nothing). None without the header;
    ValueError when the entry is not an IP address."""
    if header is None:
        return None
    entry = header.rsplit(",", 1)[-1].strip()
    if not is_address(entry):
        raise ValueError(f"X-Forwarded-For names {entry!r}, not an IP address")
    return str(ipaddress.ip_address(entry))


def is_address(text: str) -> bool:
    """Whether `text` is an IPv4 or IPv6 address."""
    try:
        ipaddress.ip_address(text)
    except ValueError:
        return False
    return True
