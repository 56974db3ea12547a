"""The endpoint's settings as one table: for each EndpointConfig field, its option, its rosparam, its kind (which says
how a value is read, checked and shown) and its help; the table is most of this module, one entry a setting. The command
line, the rosparams, the checks and the README's table are all derived from SETTINGS; the defaults are EndpointConfig's
(bridge.config, which imports this table, never the reverse). `python -m bridge.config` prints the README's table."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

from bridge.admission.web_clients import is_address
from bridge.errors import BridgeError

__all__ = [
    "ConfigError",
    "KINDS",
    "MAX_FRAME_LENGTH",
    "SETTINGS",
    "Setting",
    "describe",
    "markdown_table",
    "parse_size",
]


class ConfigError(BridgeError, ValueError):
    """A setting the endpoint cannot serve clients with; `setting` is the EndpointConfig field concerned."""

    def __init__(self, setting: str, problem: str) -> None:
        super().__init__(f"{setting}: {problem}")
        self.setting = setting
        self.problem = problem


# Unity's client reads frame lengths as signed 32-bit integers: nothing longer can be framed.
MAX_FRAME_LENGTH = 2**31 - 1

# How a value of each kind is read from the command line or a rosparam, checked, and shown:
#   address  a host name or address          port     a whole number from 0 to 65535
#   count    a whole number in a range       bytes    the same, shown (and accepted) as 64 MiB, 1 KiB, ...
#   seconds  a finite number of seconds      text     a string; empty means off
#   switch   on or off; its option sets the opposite of the default (--no-validate, --echo-own-publications)
#   patterns fnmatch patterns                ips      IP addresses
KINDS = ("address", "port", "count", "bytes", "seconds", "text", "switch", "patterns", "ips")


@dataclass(frozen=True)
class Setting:
    """One endpoint setting. `positive` refuses 0 (else a number may be 0 or more), `highest` bounds a count or a
    size, `optional` lets it be None (off), `group` is where --help and the README list it."""

    name: str  # the EndpointConfig field
    option: str
    param: str  # the private rosparam, as the node reads it
    kind: str
    help: str
    fallback_param: str | None = None  # the original endpoint's global rosparam, read when the private is unset
    # An environment variable read when the option is not given, before the rosparams: a secret given so never
    # shows in `ps` (nor in the parameter server)
    env: str | None = None
    positive: bool = False
    highest: int | None = None
    optional: bool = False
    group: str = "settings"
    empty: str = "none"  # what an empty list means, as --help and the README show it

    @property
    def metavar(self) -> str | None:
        names = {"address": "HOST", "port": "PORT", "count": "N", "bytes": "SIZE", "seconds": "S", "text": "TOKEN"}
        return {**names, "patterns": "PATTERN", "ips": "ADDRESS"}.get(self.kind)

    def source(self) -> str:
        """Where the setting is given, as an error message names it: `--tcp-port / ~tcp_port (/ROS_TCP_PORT)`."""
        fallback = f" ({self.fallback_param})" if self.fallback_param else ""
        env = f" / ${self.env}" if self.env else ""
        return f"{self.option}{env} / {self.param}{fallback}"

    def parse(self, value: Any) -> Any:
        """An option's or a rosparam's value (a rosparam may hold any YAML type) as this setting's type."""
        if self.kind in ("patterns", "ips"):
            return _items(self.name, value)
        if self.kind == "text":
            return _as(self.name, value, str) or None  # an empty token (the launch file's default) = off
        if self.kind == "bytes" and isinstance(value, str):
            return parse_size(self.name, value)
        kind = {"address": str, "switch": bool, "seconds": float}.get(self.kind, int)
        return _as(self.name, value, kind)

    def check(self, value: Any) -> None:
        """ConfigError unless the endpoint can serve clients with this value."""
        if value is None and self.optional:
            return
        if self.kind == "address" and (not isinstance(value, str) or not value):
            raise ConfigError(self.name, f"must be an address or host name, got {value!r}")
        if self.kind in ("port", "count", "bytes"):
            _check_whole(self.name, value, int(self.positive), 65535 if self.kind == "port" else self.highest)
        if self.kind == "seconds":
            _check_seconds(self.name, value, zero_allowed=not self.positive)
        if self.kind == "switch" and not isinstance(value, bool):
            raise ConfigError(self.name, f"must be true or false, got {value!r}")
        if self.kind == "text" and not isinstance(value, str):
            raise ConfigError(self.name, f"must be a string, got {value!r}")
        if self.kind == "patterns":
            for pattern in value:
                if not isinstance(pattern, str) or not pattern.strip():
                    raise ConfigError(self.name, f"each must be an origin or a pattern, got {pattern!r}")
        if self.kind == "ips":
            for address in value:
                if not isinstance(address, str) or not is_address(address):
                    raise ConfigError(self.name, f"each must be an IP address, got {address!r}")


_BYTES_HIGHEST = MAX_FRAME_LENGTH  # a size the protocol can frame: Unity's limit

SETTINGS: tuple[Setting, ...] = (
    Setting("tcp_ip", "--tcp-ip", "~tcp_ip", "address", "address to bind; 0.0.0.0 only when you ask for it", "/ROS_IP"),
    Setting(
        "tcp_port",
        "--tcp-port",
        "~tcp_port",
        "port",
        "port to listen on; 0 picks a free port, printed and stored in ~actual_port",
        "/ROS_TCP_PORT",
    ),
    Setting(
        "websocket_port",
        "--websocket-port",
        "~websocket_port",
        "port",
        "also serve WebSocket clients (browsers, Unity WebGL builds) on this port of tcp_ip, one frame per binary "
        "message; 0 picks a free port (~actual_websocket_port); needs python3-wsproto",
        optional=True,
    ),
    Setting(
        "websocket_origins",
        "--websocket-origin",
        "~websocket_origins",
        "patterns",
        "a web page allowed to open a WebSocket, by its origin (e.g. http://localhost:8000; * = any page; "
        "repeatable): an upgrade from another origin gets HTTP 403; one without an Origin (not a browser) is served",
    ),
    Setting(
        "trusted_proxies",
        "--trusted-proxy",
        "~trusted_proxies",
        "ips",
        "a proxy whose X-Forwarded-For gives a WebSocket client's own address, once it proves itself with "
        "--proxy-secret (repeatable; 127.0.0.1 is the VR page's server on this machine)",
    ),
    Setting(
        "proxy_secret",
        "--proxy-secret",
        "~proxy_secret",
        "text",
        "the secret a trusted proxy sends in X-Proxy-Secret with each upgrade; without it, or from a proxy that "
        "sends another, X-Forwarded-For is ignored (also from the environment, ROS_TCP_PROXY_SECRET)",
        optional=True,
        env="ROS_TCP_PROXY_SECRET",
    ),
    Setting(
        "auth_token",
        "--auth-token",
        "~auth_token",
        "text",
        "shared secret: a client's first command must be __auth with it",
        optional=True,
    ),
    Setting(
        "allow_topics",
        "--allow",
        "~allow_topics",
        "patterns",
        "bridge only topics and services whose resolved names match (repeatable)",
        empty="all",
    ),
    Setting("deny_topics", "--deny", "~deny_topics", "patterns", "never bridge those that match (repeatable)"),
    Setting(
        "validate_payloads",
        "--no-validate",
        "~validate_payloads",
        "switch",
        "check that each client payload (messages, service requests and responses) is exactly one message of its "
        "type; --no-validate turns it off",
    ),
    Setting(
        "echo_own_publications",
        "--echo-own-publications",
        "~echo_own_publications",
        "switch",
        "send a client its own messages back on a topic it also subscribes to, as Unity's endpoint does",
    ),
    Setting(
        "latest_only_topics",
        "--latest-only",
        "~latest_only_topics",
        "patterns",
        "a client behind on matching topics gets only their newest waiting message (repeatable; a queue_size "
        "given in __subscribe wins)",
    ),
    Setting(
        "latest_only_bytes",
        "--latest-only-bytes",
        "~latest_only_bytes",
        "bytes",
        "the same for any topic whose messages are this large or larger (camera images, point clouds); 0 = off",
        highest=_BYTES_HIGHEST,
    ),
    Setting(
        "service_timeout_s",
        "--service-timeout",
        "~service_timeout",
        "seconds",
        "how long a ROS service may take to answer a client's call",
        positive=True,
    ),
    Setting(
        "publisher_grace_s",
        "--publisher-grace",
        "~publisher_grace",
        "seconds",
        "how long a topic stays advertised after its last publishing client left (a client that reconnects "
        "within it keeps its ROS subscribers connected)",
    ),
    Setting(
        "max_payload_bytes",
        "--max-payload-bytes",
        "~max_payload_bytes",
        "bytes",
        "largest payload accepted; a longer frame gets __error and its connection closes",
        positive=True,
        highest=_BYTES_HIGHEST,
        group="limits",
    ),
    Setting(
        "max_destination_bytes",
        "--max-destination-bytes",
        "~max_destination_bytes",
        "bytes",
        "longest topic, service or command name in a frame",
        positive=True,
        highest=_BYTES_HIGHEST,
        group="limits",
    ),
    Setting(
        "client_queue_frames",
        "--queue-frames",
        "~queue_frames",
        "count",
        "frames waiting to go to one client; past it the oldest topic frame is dropped, and reported",
        positive=True,
        group="limits",
    ),
    Setting(
        "client_queue_bytes",
        "--queue-bytes",
        "~queue_bytes",
        "bytes",
        "bytes of answers (__topic_list, __ping, __request) waiting unread by one client; past it more are refused",
        positive=True,
        group="limits",
    ),
    Setting(
        "client_call_workers",
        "--call-workers",
        "~call_workers",
        "count",
        "ROS service calls a client may always have in flight; past them it borrows from a room all clients share "
        "(--max-clients x this): a call starts when asked (topic-list look-ups have a worker of their own)",
        positive=True,
        group="limits",
    ),
    Setting(
        "client_max_pending_calls",
        "--max-pending-calls",
        "~max_pending_calls",
        "count",
        "service calls and topic-list look-ups in progress or waiting (for room), per client",
        positive=True,
        group="limits",
    ),
    Setting(
        "max_clients",
        "--max-clients",
        "~max_clients",
        "count",
        "clients connected at once (when full, a connection that holds its slot without using it makes room)",
        positive=True,
        group="limits",
    ),
    Setting(
        "max_clients_per_address",
        "--max-clients-per-address",
        "~max_clients_per_address",
        "count",
        "clients connected at once from one IP address",
        positive=True,
        group="limits",
    ),
    Setting(
        "max_registrations_per_client",
        "--max-registrations-per-client",
        "~max_registrations_per_client",
        "count",
        "topics published and subscribed, and services either way, per client",
        positive=True,
        group="limits",
    ),
    Setting(
        "max_registrations",
        "--max-registrations",
        "~max_registrations",
        "count",
        "topics and services bridged for all clients together (each a ROS object with its thread and descriptors)",
        positive=True,
        group="limits",
    ),
    Setting(
        "max_partial_frame_bytes",
        "--max-partial-frame-bytes",
        "~max_partial_frame_bytes",
        "bytes",
        "frames not yet complete, all clients together (the first 1 MiB of each client's is not counted)",
        positive=True,
        group="limits",
    ),
    Setting(
        "frame_timeout_s",
        "--frame-timeout",
        "~frame_timeout",
        "seconds",
        "how long a frame may take to arrive once begun",
        positive=True,
        group="limits",
    ),
    Setting(
        "auth_timeout_s",
        "--auth-timeout",
        "~auth_timeout",
        "seconds",
        "with --auth-token: how long a client has to send __auth",
        positive=True,
        group="limits",
    ),
    Setting(
        "dead_peer_timeout_s",
        "--dead-peer-timeout",
        "~dead_peer_timeout",
        "seconds",
        "a client that acknowledges nothing (no ACKs, no keepalive answers) for this long is gone",
        positive=True,
        group="limits",
    ),
)

_UNITS = (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10))


def parse_size(setting: str, text: str) -> int:
    """`text` as a number of bytes: a whole number, or one with KiB, MiB or GiB (`64MiB`, `1.5 GiB`)."""
    number = text.strip()
    factor = 1
    for unit, size in _UNITS:
        if number.lower().endswith(unit.lower()):
            number, factor = number[: -len(unit)].strip(), size
            break
    try:
        value = float(number) * factor if factor > 1 else int(number)
    except ValueError:
        raise ConfigError(setting, f"{text!r} is not a size (bytes, or with KiB, MiB or GiB)") from None
    if not float(value).is_integer():
        raise ConfigError(setting, f"{text!r} is not a whole number of bytes")
    return int(value)


def describe(setting: Setting, value: Any) -> str:
    """A value as --help and the README show it: sizes in KiB/MiB, seconds with their unit, lists joined."""
    if value is None or (setting.kind == "switch" and value is False):
        return "off"
    if setting.kind == "switch":
        return "on"
    if setting.kind in ("patterns", "ips"):
        return ", ".join(value) if value else setting.empty
    if setting.kind == "bytes":
        for unit, size in _UNITS:
            if value >= size and value % size == 0:
                return f"{value // size} {unit}"
        return f"{value} B"
    if setting.kind == "seconds":
        return f"{value:g} s"
    return str(value)


def markdown_table(defaults: Any) -> str:
    """The README's table of settings, from SETTINGS and the defaults (an EndpointConfig)."""
    rows = ["| rosparam | option | default | meaning |", "|---|---|---|---|"]
    for setting in SETTINGS:
        fallback = f" (fallback `{setting.fallback_param}`)" if setting.fallback_param else ""
        default = describe(setting, getattr(defaults, setting.name))
        meaning = re.sub(r"(?<![\w`])((?:--|__|~)[\w-]+)", r"`\1`", setting.help)  # options, commands, params
        rows.append(f"| `{setting.param}`{fallback} | `{setting.option}` | {default} | {meaning} |")
    return "\n".join(rows)


_KIND_NAMES = {bool: "true or false", int: "a whole number", float: "a number", str: "a string"}


def _as(setting: str, value: Any, kind: type) -> Any:
    """`value` as `kind` where that is unambiguous; ConfigError names the setting."""
    if isinstance(value, kind) and not (isinstance(value, bool) and kind is not bool):
        return value
    text = value.strip().lower() if isinstance(value, str) else None
    if kind is bool and text in ("true", "false"):
        return text == "true"
    if kind is str and isinstance(value, (int, float)) and not isinstance(value, bool):
        return str(value)  # e.g. a token written as digits in YAML
    if kind is int and isinstance(value, float) and value.is_integer():
        return int(value)
    if kind in (int, float) and text is not None:
        try:
            return kind(text)
        except ValueError:
            pass
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    raise ConfigError(setting, f"{value!r} is not {_KIND_NAMES[kind]}")


def _items(setting: str, value: Any) -> tuple[str, ...]:
    """A list setting: a YAML list, or one string of items separated by commas or spaces (a launch file's arg)."""
    if isinstance(value, str):
        return tuple(part for part in value.replace(",", " ").split() if part)
    if isinstance(value, (list, tuple)):
        return tuple(_as(setting, part, str) for part in value)
    raise ConfigError(setting, f"{value!r} is not a list of patterns")


def _check_seconds(setting: str, value: object, zero_allowed: bool) -> None:
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not number or not (0 <= value < math.inf) or (value == 0 and not zero_allowed):  # type: ignore[operator]
        kind = "a number of seconds of at least 0" if zero_allowed else "a positive number of seconds"
        raise ConfigError(setting, f"must be {kind}, got {value!r}")


def _check_whole(setting: str, value: object, lowest: int, highest: int | None) -> None:
    in_range = value >= lowest and (highest is None or value <= highest) if isinstance(value, int) else False
    if isinstance(value, bool) or not in_range:
        allowed = f"from {lowest} to {highest}" if highest is not None else f"of at least {lowest}"
        raise ConfigError(setting, f"must be a whole number {allowed}, got {value!r}")
