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
from typing import Any

from bridge.protocol import DEFAULT_MAX_PAYLOAD_BYTES
from bridge.server import Endpoint, EndpointConfig

log = logging.getLogger("bridge")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m bridge", description=__doc__.splitlines()[0])
    parser.add_argument("--tcp-ip", help="address to bind (default 127.0.0.1; 0.0.0.0 only when asked)")
    parser.add_argument("--tcp-port", type=int, help="port to listen on (default 10000; 0 = any free port)")
    parser.add_argument("--node-name", default="ros_tcp_endpoint")
    parser.add_argument("--max-payload-bytes", type=int, help=f"largest accepted payload (default {DEFAULT_MAX_PAYLOAD_BYTES})")
    parser.add_argument("--queue-frames", type=int, help="per-client outgoing queue length (default 1024)")
    parser.add_argument("--auth-token", help="shared secret; clients must send __auth first (default off)")
    parser.add_argument("--allow", action="append", metavar="PATTERN", help="only bridge topics matching (repeatable)")
    parser.add_argument("--deny", action="append", metavar="PATTERN", help="never bridge topics matching (repeatable)")
    parser.add_argument("--service-timeout", type=float, help="seconds to wait for a service answer (default 10)")
    parser.add_argument("--no-validate", action="store_true", help="publish client payloads without checking them")
    return parser


def _setting(cli_value: Any, ros: Any, param: str, fallback_param: str | None, default: Any) -> Any:
    if cli_value is not None:
        return cli_value
    value = ros.get_param(param, None)
    if value is None and fallback_param is not None:
        value = ros.get_param(fallback_param, None)
    return default if value is None else value


def _patterns(value: Any) -> tuple[str, ...]:
    if value is None:
        return ()
    if isinstance(value, str):
        return tuple(part for part in value.replace(",", " ").split() if part)
    return tuple(str(part) for part in value)


def build_config(args: argparse.Namespace, ros: Any) -> EndpointConfig:
    defaults = EndpointConfig()
    return EndpointConfig(
        tcp_ip=str(_setting(args.tcp_ip, ros, "~tcp_ip", "/ROS_IP", defaults.tcp_ip)),
        tcp_port=int(_setting(args.tcp_port, ros, "~tcp_port", "/ROS_TCP_PORT", defaults.tcp_port)),
        max_payload_bytes=int(_setting(args.max_payload_bytes, ros, "~max_payload_bytes", None, defaults.max_payload_bytes)),
        client_queue_frames=int(_setting(args.queue_frames, ros, "~queue_frames", None, defaults.client_queue_frames)),
        auth_token=_setting(args.auth_token, ros, "~auth_token", None, None) or None,
        allow_topics=_patterns(_setting(args.allow, ros, "~allow_topics", None, None)),
        deny_topics=_patterns(_setting(args.deny, ros, "~deny_topics", None, None)),
        service_timeout_s=float(_setting(args.service_timeout, ros, "~service_timeout", None, defaults.service_timeout_s)),
        validate_payloads=not args.no_validate and bool(ros.get_param("~validate_payloads", True)),
    )


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

    # bridge.ros (rospy) is imported here, not at module level, so `--help` works without a ROS install.
    from bridge.ros import RosGraph

    args = _parser().parse_args(RosGraph.strip_remappings(argv if argv is not None else sys.argv)[1:])
    ros = RosGraph()
    ros.init_node(args.node_name)
    _log_to_screen()
    config = build_config(args, ros)
    endpoint = Endpoint(ros, config)
    try:
        port = endpoint.start()
    except OSError as error:
        log.error("cannot listen on %s:%d: %s", config.tcp_ip, config.tcp_port, error)
        ros.shutdown("bind failed")
        return 1
    ros.set_param("~actual_port", port)
    # What start-up made (modules, rospy's node and threads) lives as long as the process: take it out of the
    # cyclic GC's view, so a full collection scans only what was made since. Measured: a full collection over
    # the start-up objects froze every endpoint thread for 20-30 ms, the worst case of 1 kHz round trips.
    gc.collect()
    gc.freeze()
    print(f"ROS-TCP endpoint v0.7.0 listening on {config.tcp_ip}:{port}", flush=True)

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
