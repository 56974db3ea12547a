"""Who may open a WebSocket to the endpoint, and from where (pure: strings in, decisions out).

Browsers let any page open a WebSocket to any host, loopback and the LAN included, and send the page's origin with
the upgrade request: the server is the only one who can tell a page it trusts from any other page that a browser on
the lab's machine has open (cross-site WebSocket hijacking). So an upgrade that carries an Origin is served only
when the origin matches one of the endpoint's patterns (--websocket-origin); one without an Origin comes from a
program that is not a browser (Unity's player, a Python client, a proxy that checked the page itself) and is served
as a TCP client is.

A proxy in front of the endpoint (the VR page's server) connects from its own address for every browser. It says
whose request it passes on in X-Forwarded-For, which the endpoint believes only from a proxy that proves itself: its
address is one the endpoint is told to trust (--trusted-proxy), compared as an IP address, and its upgrade request
carries the secret the endpoint was given (--proxy-secret) in X-Proxy-Secret. From anyone else the header would let
a client choose its own address, for instance to dodge the back-off after wrong tokens; an address alone proves
nothing when any local process can connect from 127.0.0.1.
"""

from __future__ import annotations

import hmac
import ipaddress
import re
from typing import Iterable, Sequence

__all__ = [
    "normal_origin",
    "origin_allowed",
    "forwarded_client",
    "is_address",
    "normal_address",
    "trusted_addresses",
    "proxy_doubt",
]


def normal_origin(origin: str) -> str:
    """An origin as patterns are matched against it: lower case (scheme and host are case-insensitive), without
    surrounding space or a trailing slash."""
    return origin.strip().rstrip("/").lower()


def origin_allowed(origin: str | None, patterns: Sequence[str]) -> bool:
    """Whether an upgrade with this Origin header is served: always without one; with one, when it matches one of
    the `patterns` (e.g. "http://localhost:8000", "http://[::1]:8000", "https://*.lab.example", "*" for any page).
    A pattern is the origin itself, where `*` alone stands for any text: no other character is special, so an IPv6
    literal's brackets are brackets. A page with an opaque origin (a file, a sandboxed frame) sends "null", which
    only the pattern "null" allows."""
    if origin is None:
        return True
    origin = normal_origin(origin)
    return any(
        origin == "null" if pattern == "null" else origin != "null" and _origin_matches(origin, pattern)
        for pattern in (normal_origin(pattern) for pattern in patterns)
    )


def _origin_matches(origin: str, pattern: str) -> bool:
    if "*" not in pattern:
        return origin == pattern
    literal_parts = (re.escape(part) for part in pattern.split("*"))
    return re.fullmatch(".*".join(literal_parts), origin, re.DOTALL) is not None


def forwarded_client(header: str | None) -> str | None:
    """The client's address in a trusted proxy's X-Forwarded-For: the last one listed (the proxy's own entry;
    those before it were written by whoever the proxy heard from, and prove nothing). None without the header;
    ValueError when the entry is not an IP address."""
    if header is None:
        return None
    entry = header.rsplit(",", 1)[-1].strip()
    if not is_address(entry):
        raise ValueError(f"X-Forwarded-For names {entry!r}, not an IP address")
    return normal_address(entry)


def normal_address(text: str) -> str:
    """An IP address as the endpoint keeps and compares it: IPv6 in its short form, and an IPv4 address mapped into
    IPv6 (`::ffff:127.0.0.1`, a dual-stack socket's view of an IPv4 peer) as the IPv4 address. ValueError when
    `text` is not an IP address."""
    address = ipaddress.ip_address(text.strip())
    mapped = address.ipv4_mapped if isinstance(address, ipaddress.IPv6Address) else None
    return str(mapped or address)


def trusted_addresses(proxies: Iterable[str]) -> frozenset[str]:
    """The trusted proxies' addresses, normal (normal_address): a peer is one when its normal address is in it."""
    return frozenset(normal_address(proxy) for proxy in proxies)


def proxy_doubt(secret: str | None, given: str | None) -> str | None:
    """Why a peer at a trusted proxy's address has not proved itself the proxy (None when it has): the endpoint has
    no secret to check (--proxy-secret), or the request's X-Proxy-Secret is missing or wrong (compared in constant
    time)."""
    if secret is None:
        return "no --proxy-secret is set"
    if given is None:
        return "its request carries no X-Proxy-Secret"
    if not hmac.compare_digest(given.encode("utf-8"), secret.encode("utf-8")):
        return "its X-Proxy-Secret is wrong"
    return None


def is_address(text: str) -> bool:
    """Whether `text` is an IPv4 or IPv6 address."""
    try:
        ipaddress.ip_address(text)
    except ValueError:
        return False
    return True
