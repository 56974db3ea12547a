"""Who the page's server answers, as data: the Host names it serves, the launch's secret that the served page
carries, and the page's own Origin on its WebSocket. Pure logic: no socket; the secret is made by the caller.

Any program that reaches the server's port would otherwise get the endpoint through `/ros`, and a foreign web page
could reach it too, by DNS rebinding: its own name pointed at this machine, so that its Host and its Origin agree
with each other. Three checks close that door, each on every request:

- the Host must be one of this machine's names or addresses (or a name the user gave), never the rebinding page's
  own name; any port, since `adb reverse` or a forwarded port may show the browser another one;
- the request must carry the secret made at this launch: in the address the server prints (`?key=...`), from which
  the server sets it as a cookie (HttpOnly, SameSite=Strict) that the page's own requests then carry: its modules,
  its settings, its meshes and its WebSocket. A page of another site never gets the cookie, nor reads it;
- a WebSocket's Origin, when a browser sends one, must be this server's own (`scheme://Host`): another page on the
  same machine's name (another port) would carry the cookie, which is not kept apart by port.
"""

from __future__ import annotations

import hmac
import ipaddress
import re
from collections.abc import Iterable
from dataclasses import dataclass
from urllib.parse import parse_qs

__all__ = ["SECRET_PARAMETER", "Access", "host_name", "is_host_name", "is_loopback", "normal_names"]

SECRET_PARAMETER = "key"  # the query parameter of the printed address that carries the secret
_HOST_NAME = re.compile(r"[A-Za-z0-9](?:[A-Za-z0-9-]*[A-Za-z0-9])?(?:\.[A-Za-z0-9-]+)*\.?")
LOCAL_NAMES = ("localhost",)  # always this machine, as every loopback address is


def host_name(host: str) -> str:
    """The name in a Host header, without its port, in lower case ("" when there is none): `[::1]:8443` is `::1`,
    `lab.example.:8443` is `lab.example`."""
    host = host.strip().lower()
    if host.startswith("["):
        return host[1 : host.find("]")] if "]" in host else ""
    if host.count(":") == 1:
        host = host.split(":", 1)[0]
    return host.rstrip(".")


def is_host_name(text: str) -> bool:
    """`text` is a host name (letters, digits, hyphens, dots) or an IP address: no scheme, port or path."""
    return _is_ip(text) or _HOST_NAME.fullmatch(text) is not None


def is_loopback(host: str) -> bool:
    """`host` (a listening address) reaches this machine only: localhost or a loopback address. Plain HTTP is for
    such a host alone: on any other, the key and its cookie would cross the network in clear."""
    return host.strip().lower() in LOCAL_NAMES or (_is_ip(host) and ipaddress.ip_address(host.strip()).is_loopback)


def normal_names(names: Iterable[str]) -> frozenset[str]:
    """The names and addresses as host_name gives them from a Host header (an IPv6 address compressed)."""
    return frozenset(_normal(host_name(name) if not _is_ip(name) else name) for name in names if name.strip())


def _is_ip(text: str) -> bool:
    try:
        ipaddress.ip_address(text.strip())
    except ValueError:
        return False
    return True


def _normal(name: str) -> str:
    return str(ipaddress.ip_address(name)) if _is_ip(name) else name


@dataclass(frozen=True)
class Access:
    """The server's rules for one launch: `secret` (made at the launch), `hosts` (the names and addresses it answers
    to, besides every loopback address and localhost), `scheme` (http or https) and `cookie` (the name of the
    cookie that keeps the secret: one per server, since two servers of one machine share its cookies)."""

    secret: str
    hosts: frozenset[str]
    scheme: str
    cookie: str = "sim_study_key"

    def refusal(self, host: str, target: str, cookie_header: str, origin: str, websocket: bool) -> str | None:
        """Why a request is refused (HTTP 403), or None when it may be served: `host`, `cookie_header` and
        `origin` as the request's headers give them ("" when absent), `target` its path with its query."""
        name = host_name(host)
        if not self.host_allowed(name):
            return (
                f"this server answers to this machine's names and addresses only, not to the Host {host!r}: open the "
                "address it printed, or give the name you open it by with --allow-host"
            )
        if not self.carries_secret(target, cookie_header):
            return (
                "this request does not carry this launch's key: open the address the server printed, with its "
                f"?{SECRET_PARAMETER}=... (a new launch makes a new key)"
            )
        own = f"{self.scheme}://{host}"
        if websocket and origin and origin.lower() != own.lower():
            return f"only this server's page ({own}) may open its WebSocket, not the page {origin}"
        return None

    def host_allowed(self, name: str) -> bool:
        if name in LOCAL_NAMES:
            return True
        if _is_ip(name):
            address = ipaddress.ip_address(name)
            return address.is_loopback or str(address) in self.hosts
        return name in self.hosts

    def carries_secret(self, target: str, cookie_header: str) -> bool:
        """The request's query names the secret (the printed address), or its cookie holds it."""
        return self.secret_in_query(target) or self._is_secret(self.cookie_values(cookie_header))

    def secret_in_query(self, target: str) -> bool:
        query = target.split("?", 1)[1] if "?" in target else ""
        return self._is_secret(parse_qs(query).get(SECRET_PARAMETER, []))

    def _is_secret(self, given: list[str]) -> bool:
        return any(hmac.compare_digest(value.encode(), self.secret.encode()) for value in given)

    def cookie_values(self, cookie_header: str) -> list[str]:
        """The values of this server's cookie in a Cookie header (a browser may send several of one name)."""
        pairs = (part.strip().partition("=") for part in cookie_header.split(";"))
        return [value.strip() for name, _, value in pairs if name.strip() == self.cookie]

    def set_cookie(self) -> str:
        """The Set-Cookie header's value that keeps the secret for the page's own requests: not for scripts
        (HttpOnly), not sent with another site's requests (SameSite=Strict), over TLS only when served so."""
        secure = "; Secure" if self.scheme == "https" else ""
        return f"{self.cookie}={self.secret}; Path=/; HttpOnly; SameSite=Strict{secure}"

    def page_address(self, host: str, port: int) -> str:
        """The address to open: the page, with the secret."""
        shown = f"[{host}]" if ":" in host else host
        return f"{self.scheme}://{shown}:{port}/?{SECRET_PARAMETER}={self.secret}"
