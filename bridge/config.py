"""The endpoint's settings, checked before it listens: EndpointConfig (the defaults; bridge.settings says how each
is given, checked and shown) and the ConfigError a bad one raises. `python -m bridge.config` prints the README's
table of settings, with these defaults."""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass

from bridge.protocol import DEFAULT_MAX_PAYLOAD_BYTES, MAX_DESTINATION_BYTES
from bridge.protocol.framing import LARGE_PAYLOAD_BYTES
from bridge.settings import MAX_FRAME_LENGTH, SETTINGS, ConfigError, markdown_table

__all__ = ["ConfigError", "EndpointConfig", "MAX_FRAME_LENGTH"]


@dataclass
class EndpointConfig:
    tcp_ip: str = "127.0.0.1"
    tcp_port: int = 10000
    # Where WebSocket clients (browsers, Unity WebGL builds) are served, on tcp_ip; None: not at all (needs wsproto)
    websocket_port: int | None = None
    # Web pages allowed to open a WebSocket, as fnmatch patterns on their Origin ("http://localhost:8000", "*" for
    # any); an upgrade with another Origin gets HTTP 403. Clients that send none (not browsers) are always served.
    websocket_origins: tuple[str, ...] = ()
    # Proxies whose X-Forwarded-For the endpoint believes (the VR page's server, on this machine): their WebSocket
    # clients are limited, backed off and reported by the address the proxy says they have
    trusted_proxies: tuple[str, ...] = ("127.0.0.1",)
    # What a trusted proxy must send in X-Proxy-Secret for its X-Forwarded-For to be believed; None: never believed
    # (an address proves nothing: any local process connects from 127.0.0.1)
    proxy_secret: str | None = None
    max_payload_bytes: int = DEFAULT_MAX_PAYLOAD_BYTES
    max_destination_bytes: int = MAX_DESTINATION_BYTES
    client_queue_frames: int = 1024
    client_queue_bytes: int = 4 * 1024 * 1024
    auth_token: str | None = None  # off by default: Unity's client cannot send __auth
    allow_topics: tuple[str, ...] = ()  # fnmatch patterns on resolved names; empty = everything
    deny_topics: tuple[str, ...] = ()
    service_timeout_s: float = 10.0
    # How long a publisher stays advertised after its last client left (rosbridge's unregister_timeout): a client
    # that reconnects within it keeps its ROS subscribers connected.
    publisher_grace_s: float = 10.0
    validate_payloads: bool = True
    # A client that is behind gets only the newest waiting message of these topics (fnmatch patterns on resolved
    # names), and of any topic whose messages are latest_only_bytes or larger (camera images, point clouds; 0: no
    # such rule), instead of a backlog of stale ones. A queue_size the client gave in __subscribe wins over both.
    latest_only_topics: tuple[str, ...] = ()
    latest_only_bytes: int = LARGE_PAYLOAD_BYTES
    # A client that publishes and subscribes on one topic gets the others' messages, not its own back (what Unity's
    # users asked for in ROS-TCP-Endpoint PR #159); True sends them back as the original endpoint does.
    echo_own_publications: bool = False
    # Per client: ROS service calls in flight at once that no other client can take (past them, calls borrow from a
    # room of max_clients x client_call_workers that all clients share: bridge.connection.calls), and calls and
    # topic-list look-ups in progress or waiting. So a burst of calls starts at once, and one client calling missing
    # services (each waiting service_timeout_s) delays no other client's calls.
    client_call_workers: int = 4
    client_max_pending_calls: int = 64
    # Limits, so that no client (nor a crowd of them) can take what the others need: descriptors, threads, memory.
    # Past one, the client gets a clear __error and stays connected where that is safe.
    max_clients: int = 64
    max_clients_per_address: int = 16
    max_registrations_per_client: int = 256  # topics published and subscribed, services either way
    max_registrations: int = 2048  # topics and services bridged for all clients together (each a ROS object)
    max_partial_frame_bytes: int = 256 * 1024 * 1024  # frames not yet complete, all clients together
    # Deadlines: a frame begun must be complete within frame_timeout_s; with a token, __auth must come within
    # auth_timeout_s; a peer that vanished (no ACKs, no keepalive answers) is dropped within dead_peer_timeout_s.
    frame_timeout_s: float = 30.0
    auth_timeout_s: float = 10.0
    dead_peer_timeout_s: float = 10.0

    def __post_init__(self) -> None:
        """Refuse, before anything starts, settings that would fail later: at bind, or at every client's connect."""
        for setting in SETTINGS:
            setting.check(getattr(self, setting.name))
        if self.websocket_port is not None and self.websocket_port == self.tcp_port and self.tcp_port != 0:
            raise ConfigError("websocket_port", f"must differ from tcp_port, both are {self.tcp_port}")

    def latest_only(self, resolved_name: str) -> bool:
        """Whether a client behind on this topic gets only its newest message, whatever the messages' size."""
        return any(fnmatch.fnmatchcase(resolved_name, pattern) for pattern in self.latest_only_topics)

    def permits(self, resolved_name: str) -> bool:
        if any(fnmatch.fnmatchcase(resolved_name, pattern) for pattern in self.deny_topics):
            return False
        return not self.allow_topics or any(
            fnmatch.fnmatchcase(resolved_name, pattern) for pattern in self.allow_topics
        )


if __name__ == "__main__":
    print(markdown_table(EndpointConfig()))
