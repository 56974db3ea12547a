"""Who comes in: the endpoint's limits on clients, checked at connect (room made where a connection does not use its
slot: bridge.admission.room), and a WebSocket client's upgrade request (its page's Origin, the address a proxy that
proved itself says it has: bridge.admission.web_clients).

The Endpoint (bridge.server) owns one Gate and asks it about every new connection and every upgrade request.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from typing import TYPE_CHECKING, ContextManager, Mapping

from bridge.admission.room import Suspects, pace, to_evict
from bridge.admission.throttle import LogThrottle
from bridge.admission.web_clients import (
    forwarded_client,
    normal_address,
    normal_origin,
    origin_allowed,
    proxy_doubt,
    trusted_addresses,
)
from bridge.config import EndpointConfig

if TYPE_CHECKING:  # wsproto is optional: bridge.protocol.websocket is imported only for WebSocket clients
    from bridge.connection.session import ClientSession
    from bridge.connection.web_session import WebSocketSession
    from bridge.protocol.websocket import UpgradeRequest

__all__ = ["Gate"]

log = logging.getLogger(__name__)


class Gate:
    """The endpoint's admission of clients. `clients` and `lock` are the endpoint's: every connected session, under
    the lock that guards them."""

    def __init__(
        self, config: EndpointConfig, clients: Mapping[ClientSession, object], lock: ContextManager[object]
    ) -> None:
        self._config = config
        self._clients = clients
        self._lock = lock
        self._trusted = trusted_addresses(config.trusted_proxies)
        self._turned_away = LogThrottle(log)
        self._refused_upgrades = LogThrottle(log)  # any page a browser opens may try: logged at most once a second
        self._ignored_forwards = LogThrottle(log)  # any local process may try: logged at most once a second
        self._counts_lock = threading.Lock()  # upgrades are decided on the clients' reader threads
        self._refused_origins = 0
        self._suspects = Suspects()  # under _counts_lock

    @property
    def refused_origins(self) -> int:
        """WebSocket upgrades refused for their Origin (on /diagnostics)."""
        with self._counts_lock:
            return self._refused_origins

    def behind_proxy(self, peer: str) -> bool:
        """Whether a WebSocket client connecting from `peer` may be a trusted proxy's, whose own address its upgrade
        request will say: its per-address limit waits for that (upgrade_refusal). Only with a proxy secret: without
        one, no proxy can prove itself."""
        return self._config.proxy_secret is not None and normal_address(peer) in self._trusted

    def turn_away(self, name: str, reason: str) -> None:
        """Log a client turned away for a limit (at most once a second: a crowd may come)."""
        self._turned_away.warning("turned away a client at %s: %s", name, reason)

    def misused_slot(self, host: str) -> None:
        """A connection from `host` was closed for not using its slot (a deadline passed): its address becomes a
        suspect (bridge.admission.room)."""
        with self._counts_lock:
            self._suspects.note(host, time.monotonic())

    def refusal(self, host: str, per_address: bool = True, newcomer: ClientSession | None = None) -> str | None:
        """Why a new client from `host` cannot be served now (a limit reached, and no connection there not using its
        slot: bridge.admission.room); None when it can, room having been made if needed. With `per_address` False, only
        the endpoint's limit is checked; for a `newcomer` already connected (a WebSocket client whose address its
        proxy has just said), only its address's."""
        now = time.monotonic()
        with self._lock:
            # those leaving hold no slot; a newcomer's own is not counted against it
            sessions = [session for session in self._clients if not session.closing and session is not newcomer]
        from_host = [session for session in sessions if session.host == host]
        if newcomer is None and len(sessions) >= self._config.max_clients:
            limit, among = f"the endpoint serves {len(sessions)} clients already, its limit (--max-clients)", sessions
        elif per_address and len(from_host) >= self._config.max_clients_per_address:
            limit = (
                f"the endpoint serves {len(from_host)} clients from {host} already, its limit per address "
                "(--max-clients-per-address)"
            )
            among = from_host
        else:
            return None
        with self._counts_lock:
            if self._suspects.is_suspect(host, now):  # its own slow senders would keep every slot young
                return f"{limit}; and {host} makes no room, one of its connections did not use its slot lately"
            suspect = {session.host: self._suspects.is_suspect(session.host, now) for session in among}
        uses = [dataclasses.replace(session.slot_use(now), suspect=suspect[session.host]) for session in among]
        victim = to_evict(uses)
        if victim is None:
            return limit
        use = uses[victim]
        self.misused_slot(among[victim].host)
        doing = (
            f"{use.frame_bytes} bytes of a frame in {use.frame_for_s:.1f} s"
            if use.frame_for_s is not None
            else f"no {'__auth' if not use.authenticated else 'frame'} in {use.connected_for_s:.1f} s"
        )
        if pace(use) is None:  # too young to judge, from a suspect address
            doing += f" (young, from {among[victim].host}, where a connection did not use its slot in the last minute)"

        log.warning(
            "client %s closed to make room for a new client from %s (%s): %s", among[victim].name, host, limit, doing
        )
        among[victim].close(
            f"closed to make room for a new client: {limit}, and this connection sent {doing}", tell_client=True
        )
        return None

    def upgrade_refusal(self, session: WebSocketSession, request: UpgradeRequest) -> tuple[str, str] | None:
        """A WebSocket client's upgrade request: refused (HTTP 403) when its Origin is not allowed, a page's that no
        --websocket-origin matches. From a trusted proxy that proves itself (--proxy-secret, in X-Proxy-Secret), the
        client's own address is taken from X-Forwarded-For (HTTP 400 for an address that is none); from one that
        does not, the header is ignored, and said. Behind a trusted proxy, the per-address limit is checked here
        (HTTP 503 past it), by whichever address the client then has."""
        if not origin_allowed(request.origin, self._config.websocket_origins):
            with self._counts_lock:
                self._refused_origins += 1
            origin = normal_origin(request.origin or "")
            self._refused_upgrades.warning(
                "refused a WebSocket upgrade from %s: its Origin %s is not allowed (--websocket-origin)",
                session.name,
                origin,
            )
            return "403 Forbidden", f"the origin {origin} may not open a WebSocket here (--websocket-origin)"
        if normal_address(session.peer_host) not in self._trusted:
            return None  # not a proxy: its X-Forwarded-For is its own word, and its limit was checked at connect
        doubt = proxy_doubt(self._config.proxy_secret, request.proxy_secret)
        if doubt is None:
            try:
                client = forwarded_client(request.forwarded_for)
            except ValueError as error:
                self._refused_upgrades.warning("refused a WebSocket upgrade from %s: %s", session.name, error)
                return "400 Bad Request", str(error)
            if client is not None:
                session.use_forwarded_address(client)
        elif request.forwarded_for is not None:
            self._ignored_forwards.warning(
                "client %s: X-Forwarded-For ignored, %s; the client counts as %s", session.name, doubt, session.host
            )
        if not self.behind_proxy(session.peer_host):
            return None  # its limit per address was checked at connect
        refusal = self.refusal(session.host, newcomer=session)
        if refusal is None:
            return None
        self.turn_away(session.name, refusal)
        return "503 Service Unavailable", f"connection refused: {refusal}"
