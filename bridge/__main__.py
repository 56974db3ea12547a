"""`python -m bridge`: the ROS-TCP endpoint node.

Settings come from private rosparams (~tcp_ip, ~tcp_port, ...; the original endpoint's /ROS_IP and /ROS_TCP_PORT
are honoured as fallbacks) and are overridden by the command line. `--tcp-port 0` picks a free port, which is
printed and stored in ~actual_port.
"""

from __future__ import annotations

import argparse
import gc
import logging
import signal
import sys
import threading
from dataclasses import dataclass
from typing import Any

from bridge.config import ConfigError, EndpointConfig
from bridge.memory import keep_large_buffers
from bridge.protocol import DEFAULT_MAX_PAYLOAD_BYTES
from bridge.server import Endpoint

__all__ = ["build_config", "GIL_SWITCH_INTERVAL_S", "main"]

log = logging.getLogger("bridge")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m bridge", description=__doc__.splitlines()[0])
    parser.add_argument("--tcp-ip", help="address to bind (default 127.0.0.1; 0.0.0.0 only when asked)")
    parser.add_argument("--tcp-port", type=int, help="port to listen on (default 10000; 0 = any free port)")
    parser.add_argument(
        "--websocket-port",
        type=int,
        help="also serve WebSocket clients (browsers, Unity WebGL) on this port, one frame per binary message "
        "(default off; 0 = any free port; needs python3-wsproto)",
    )
    parser.add_argument(
        "--websocket-origin",
        action="append",
        metavar="PATTERN",
        help="a web page allowed to open a WebSocket, by its origin (fnmatch, e.g. http://localhost:8000; "
        "repeatable; '*' = any page). By default no page is: an upgrade whose Origin matches none gets HTTP 403, "
        "one without an Origin (not a browser) is served",
    )
    parser.add_argument(
        "--trusted-proxy",
        action="append",
        metavar="ADDRESS",
        help="a proxy whose X-Forwarded-For is believed for WebSocket clients (repeatable; default 127.0.0.1, the "
        "VR page's server on this machine)",
    )
    parser.add_argument("--node-name", default="ros_tcp_endpoint")
    parser.add_argument(
        "--max-payload-bytes", type=int, help=f"largest accepted payload (default {DEFAULT_MAX_PAYLOAD_BYTES})"
    )
    parser.add_argument("--queue-frames", type=int, help="per-client outgoing queue length (default 1024)")
    parser.add_argument("--auth-token", help="shared secret; clients must send __auth first (default off)")
    parser.add_argument("--allow", action="append", metavar="PATTERN", help="only bridge topics matching (repeatable)")
    parser.add_argument("--deny", action="append", metavar="PATTERN", help="never bridge topics matching (repeatable)")
    parser.add_argument("--service-timeout", type=float, help="seconds to wait for a service answer (default 10)")
    parser.add_argument(
        "--publisher-grace",
        type=float,
        help="seconds a publisher stays advertised after its last client left (default 10)",
    )
    parser.add_argument("--no-validate", action="store_true", help="publish client payloads without checking them")
    parser.add_argument(
        "--latest-only",
        action="append",
        metavar="PATTERN",
        help="a client behind on matching topics gets only their newest message (repeatable)",
    )
    parser.add_argument(
        "--latest-only-bytes",
        type=int,
        metavar="N",
        help="the same for any topic whose messages are N bytes or more "
        f"(default {EndpointConfig().latest_only_bytes}; 0 = off)",
    )
    parser.add_argument(
        "--echo-own-publications",
        action="store_true",
        help="send a client its own messages back on topics it also subscribes to (default off)",
    )
    parser.add_argument(
        "--wait",
        action="store_true",
        help="wait for the ROS master before starting (what Unity's tutorial launch files pass)",
    )
    limits = parser.add_argument_group("limits", "what no client, nor all of them together, may exceed")
    defaults = EndpointConfig()
    for setting, option, text in _LIMITS:
        default = getattr(defaults, setting)
        limits.add_argument(option, type=type(default), metavar="N", help=f"{text} (default {default:g})")
    return parser


# Limits given as one number each: (EndpointConfig field, option, what it bounds); the rosparam is the option's
# name with underscores, e.g. ~max_clients.
_LIMITS = (
    ("max_clients", "--max-clients", "clients connected at once"),
    ("max_clients_per_address", "--max-clients-per-address", "clients connected at once from one address"),
    (
        "max_registrations_per_client",
        "--max-registrations-per-client",
        "topics published and subscribed and services, per client",
    ),
    ("max_registrations", "--max-registrations", "topics and services bridged for all clients together"),
    (
        "max_partial_frame_bytes",
        "--max-partial-frame-bytes",
        "bytes of frames not yet complete, all clients together (up to 1 MiB per client is not counted)",
    ),
    ("frame_timeout_s", "--frame-timeout", "seconds a frame may take to arrive once begun"),
    ("auth_timeout_s", "--auth-timeout", "seconds a client has to send __auth (with --auth-token)"),
    (
        "dead_peer_timeout_s",
        "--dead-peer-timeout",
        "seconds without ACKs or keepalive answers after which a client counts as gone",
    ),
)


@dataclass(frozen=True)
class _Source:
    """Where one setting can be given: a command-line option, a private rosparam, maybe the original endpoint's
    global rosparam as a fallback."""

    option: str
    param: str
    fallback_param: str | None = None

    def __str__(self) -> str:
        fallback = f" ({self.fallback_param})" if self.fallback_param else ""
        return f"{self.option} / {self.param}{fallback}"


# EndpointConfig field -> where it is given (the options themselves are declared in _parser)
_SOURCES = {
    "tcp_ip": _Source("--tcp-ip", "~tcp_ip", "/ROS_IP"),
    "tcp_port": _Source("--tcp-port", "~tcp_port", "/ROS_TCP_PORT"),
    "websocket_port": _Source("--websocket-port", "~websocket_port"),
    "websocket_origins": _Source("--websocket-origin", "~websocket_origins"),
    "trusted_proxies": _Source("--trusted-proxy", "~trusted_proxies"),
    "max_payload_bytes": _Source("--max-payload-bytes", "~max_payload_bytes"),
    "client_queue_frames": _Source("--queue-frames", "~queue_frames"),
    "auth_token": _Source("--auth-token", "~auth_token"),
    "allow_topics": _Source("--allow", "~allow_topics"),
    "deny_topics": _Source("--deny", "~deny_topics"),
    "service_timeout_s": _Source("--service-timeout", "~service_timeout"),
    "publisher_grace_s": _Source("--publisher-grace", "~publisher_grace"),
    "validate_payloads": _Source("--no-validate", "~validate_payloads"),
    "latest_only_topics": _Source("--latest-only", "~latest_only_topics"),
    "latest_only_bytes": _Source("--latest-only-bytes", "~latest_only_bytes"),
    "echo_own_publications": _Source("--echo-own-publications", "~echo_own_publications"),
    **{setting: _Source(option, "~" + option[2:].replace("-", "_")) for setting, option, _ in _LIMITS},
}


def _given(setting: str, cli_value: Any, ros: Any) -> Any:
    """The command line's value, else the rosparam's, else the fallback rosparam's; None where none is set."""
    if cli_value is not None:
        return cli_value
    source = _SOURCES[setting]
    value = ros.get_param(source.param, None)
    if value is None and source.fallback_param is not None:
        value = ros.get_param(source.fallback_param, None)
    return value


_KIND_NAMES = {bool: "true or false", int: "a whole number", float: "a number", str: "a string"}


def _typed(setting: str, value: Any, kind: type) -> Any:
    """`value` (an option, or a rosparam, which may hold any YAML type) as `kind`; ConfigError names the setting."""
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


def _patterns(setting: str, value: Any) -> tuple[str, ...]:
    """A list setting: a YAML list, or one string of items separated by commas or spaces (a launch file's arg)."""
    if value is None:
        return ()
    if isinstance(value, str):
        return tuple(part for part in value.replace(",", " ").split() if part)
    if isinstance(value, (list, tuple)):
        return tuple(_typed(setting, part, str) for part in value)
    raise ConfigError(setting, f"{value!r} is not a list of patterns")


def build_config(args: argparse.Namespace, ros: Any) -> EndpointConfig:
    """The endpoint's settings: command line over private rosparams over defaults; ConfigError names a bad one."""
    defaults = EndpointConfig()

    def read(setting: str, cli_value: Any, kind: type) -> Any:
        value = _given(setting, cli_value, ros)
        return getattr(defaults, setting) if value is None else _typed(setting, value, kind)

    token = _given("auth_token", args.auth_token, ros)
    if token is not None:
        token = _typed("auth_token", token, str) or None  # an empty token (the launch file's default) = off
    proxies = _given("trusted_proxies", args.trusted_proxy, ros)  # an empty list trusts none
    limits = {
        setting: read(setting, getattr(args, option[2:].replace("-", "_")), type(getattr(defaults, setting)))
        for setting, option, _ in _LIMITS
    }
    return EndpointConfig(
        **limits,
        tcp_ip=read("tcp_ip", args.tcp_ip, str),
        tcp_port=read("tcp_port", args.tcp_port, int),
        websocket_port=read("websocket_port", args.websocket_port, int),
        websocket_origins=_patterns("websocket_origins", _given("websocket_origins", args.websocket_origin, ros)),
        trusted_proxies=defaults.trusted_proxies if proxies is None else _patterns("trusted_proxies", proxies),
        max_payload_bytes=read("max_payload_bytes", args.max_payload_bytes, int),
        client_queue_frames=read("client_queue_frames", args.queue_frames, int),
        auth_token=token,
        allow_topics=_patterns("allow_topics", _given("allow_topics", args.allow, ros)),
        deny_topics=_patterns("deny_topics", _given("deny_topics", args.deny, ros)),
        service_timeout_s=read("service_timeout_s", args.service_timeout, float),
        publisher_grace_s=read("publisher_grace_s", args.publisher_grace, float),
        validate_payloads=not args.no_validate and read("validate_payloads", None, bool),
        latest_only_topics=_patterns("latest_only_topics", _given("latest_only_topics", args.latest_only, ros)),
        latest_only_bytes=read("latest_only_bytes", args.latest_only_bytes, int),
        echo_own_publications=args.echo_own_publications or read("echo_own_publications", None, bool),
    )


def _missing_websocket_library(config: EndpointConfig) -> str | None:
    """What to install, in one line, when WebSocket clients are asked for and wsproto cannot be imported."""
    if config.websocket_port is None:
        return None
    try:
        import bridge.websocket  # noqa: F401  (wsproto, through it)
    except ImportError as error:
        return (
            f"{_SOURCES['websocket_port']} needs the WebSocket library wsproto, which this Python cannot import "
            f"({error}): install python3-wsproto (sudo apt install python3-wsproto, or rosdep install "
            "ros_tcp_endpoint)"
        )
    return None


def _log_to_screen() -> None:
    # init_node points the root logger at the node's log file only; keep that, and also show ours on screen.
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("[%(levelname)s] [%(name)s] %(message)s"))
    logger = logging.getLogger("bridge")
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)


# How long a busy thread may hold the GIL while another waits for it (CPython's default is 5 ms). The endpoint's
# threads mostly hand bytes to each other; with 5 ms, one flooding client's reader makes every pump, writer and
# rospy thread wait up to 5 ms per hand-off: publisher queues overflow and 1 kHz round trips get 5-10 ms spikes.
GIL_SWITCH_INTERVAL_S = 0.0005


def main(argv: list[str] | None = None) -> int:
    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)
    keep_large_buffers()

    # bridge.ros_graph (rospy) is imported here, not at module level, so `--help` works without a ROS install.
    from bridge.ros_graph import RosGraph

    # Arguments we do not know are ignored with a warning, never an exit: launch files written for other endpoints
    # pass their own. A known option with a bad value is still an error (exit 2).
    args, unknown = _parser().parse_known_args(RosGraph.strip_remappings(argv if argv is not None else sys.argv)[1:])
    ros = RosGraph()
    if args.wait:
        ros.wait_for_master()
    ros.init_node(args.node_name)
    _log_to_screen()
    if unknown:
        log.warning("ignoring argument(s) the endpoint does not know: %s", " ".join(unknown))
    try:
        config = build_config(args, ros)
    except ConfigError as error:
        print(
            f"python -m bridge: bad setting {_SOURCES.get(error.setting, error.setting)}: {error.problem}",
            file=sys.stderr,
        )
        ros.shutdown("bad setting")
        return 2
    missing = _missing_websocket_library(config)
    if missing is not None:
        print(f"python -m bridge: {missing}", file=sys.stderr)
        ros.shutdown("no WebSocket library")
        return 2
    endpoint = Endpoint(ros, config)
    try:
        port = endpoint.start()
    except OSError as error:
        log.error("cannot listen on %s:%d: %s", config.tcp_ip, config.tcp_port, error)
        ros.shutdown("bind failed")
        return 1
    actual = {"~actual_port": port}
    if endpoint.websocket_port is not None:
        actual["~actual_websocket_port"] = endpoint.websocket_port

    def store_actual_ports() -> None:
        for name, value in actual.items():
            ros.set_param(name, value)

    store_actual_ports()
    ros.master.on_new_master(store_actual_ports)  # a new master's parameters are empty
    # What start-up made (modules, rospy's node and threads) lives as long as the process: take it out of the
    # cyclic GC's view, so a full collection scans only what was made since. Measured: a full collection over
    # the start-up objects froze every endpoint thread for 20-30 ms, the worst case of 1 kHz round trips.
    gc.collect()
    gc.freeze()
    print(f"ROS-TCP endpoint v0.7.0 listening on {config.tcp_ip}:{port}", flush=True)
    if endpoint.websocket_port is not None:
        print(f"WebSocket clients: ws://{config.tcp_ip}:{endpoint.websocket_port}/", flush=True)

    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    while not stop.wait(0.5):
        if ros.is_shutdown():  # e.g. rosnode kill, or the master asked us to go
            break
    endpoint.stop()
    ros.shutdown("endpoint stopped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
