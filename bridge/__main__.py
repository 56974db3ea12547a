"""`python -m bridge`: the ROS-TCP endpoint node.

Settings come from private rosparams (~tcp_ip, ~tcp_port, ...; the original endpoint's /ROS_IP and /ROS_TCP_PORT
are honoured as fallbacks) and are overridden by the command line. `--tcp-port 0` picks a free port, which is
printed and stored in ~actual_port.
"""

from __future__ import annotations

import argparse
import gc
import logging
import os
import signal
import sys
import threading
from typing import Any, Mapping

from bridge.config import ConfigError, EndpointConfig
from bridge.memory import keep_large_buffers
from bridge.ros.reachability import findings, summary
from bridge.server import Endpoint
from bridge.settings import SETTINGS, describe

__all__ = ["build_config", "GIL_SWITCH_INTERVAL_S", "main"]

log = logging.getLogger("bridge")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m bridge", description=__doc__.splitlines()[0])
    parser.add_argument("--node-name", default="ros_tcp_endpoint", help="the node's name (default %(default)s)")
    parser.add_argument(
        "--wait",
        action="store_true",
        help="wait for the ROS master before starting (what Unity's tutorial launch files pass)",
    )
    groups = {
        "settings": parser.add_argument_group("settings", "each also a private rosparam, named after the option"),
        "limits": parser.add_argument_group("limits", "what no client, nor all of them together, may exceed"),
    }
    defaults = EndpointConfig()
    for setting in SETTINGS:
        group = groups[setting.group]
        default = getattr(defaults, setting.name)
        shown = f"{setting.help} (rosparam {setting.param}; default {describe(setting, default)})"
        if setting.kind == "switch":  # the option sets the opposite of the default
            group.add_argument(setting.option, dest=setting.name, action="store_const", const=not default, help=shown)
        elif setting.kind in ("patterns", "ips"):
            group.add_argument(setting.option, dest=setting.name, action="append", metavar=setting.metavar, help=shown)
        else:
            group.add_argument(setting.option, dest=setting.name, metavar=setting.metavar, help=shown)
    return parser


_SOURCES = {setting.name: setting for setting in SETTINGS}


def build_config(args: argparse.Namespace, ros: Any, environ: Mapping[str, str] = os.environ) -> EndpointConfig:
    """The endpoint's settings: command line over the environment (for the settings read from it) over private
    rosparams (over the original endpoint's global ones) over defaults; ConfigError names a bad one."""
    given = {}
    for setting in SETTINGS:
        value = getattr(args, setting.name)
        if value is None and setting.env is not None:
            value = environ.get(setting.env)
        if value is None:
            value = ros.get_param(setting.param, None)
        if value is None and setting.fallback_param is not None:
            value = ros.get_param(setting.fallback_param, None)
        if value is not None:
            given[setting.name] = setting.parse(value)
    return EndpointConfig(**given)


def _missing_websocket_library(config: EndpointConfig) -> str | None:
    """What to install, in one line, when WebSocket clients are asked for and wsproto cannot be imported."""
    if config.websocket_port is None:
        return None
    try:
        import bridge.protocol.websocket  # noqa: F401  (wsproto, through it)
    except ImportError as error:
        return (
            f"{_SOURCES['websocket_port'].source()} needs the WebSocket library wsproto, which this Python cannot "
            f"import ({error}): install python3-wsproto (sudo apt install python3-wsproto, or rosdep install "
            "ros_tcp_endpoint)"
        )
    return None


def _source(setting: str) -> str:
    return _SOURCES[setting].source() if setting in _SOURCES else setting


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

    # bridge.ros.graph (rospy) is imported here, not at module level, so `--help` works without a ROS install.
    from bridge.ros.graph import RosGraph
    from bridge.ros.network import gather_facts, master_problem, port_problem

    # Arguments we do not know are ignored with a warning, never an exit: launch files written for other endpoints
    # pass their own. A known option with a bad value is still an error (exit 2).
    args, unknown = _parser().parse_known_args(RosGraph.strip_remappings(argv if argv is not None else sys.argv)[1:])
    ros = RosGraph()
    if args.wait:
        ros.wait_for_master()
    else:
        # rospy would wait for an absent master without a word, in the first parameter look-up. A silent one may
        # be a starved machine's: said, and then waited for as before.
        problem = master_problem()
        if problem is not None:
            print(f"python -m bridge: {problem.line}", file=sys.stderr, flush=True)
            if problem.certain:
                return 2
    ros.init_node(args.node_name)
    _log_to_screen()
    if unknown:
        log.warning("ignoring argument(s) the endpoint does not know: %s", " ".join(unknown))
    try:
        config = build_config(args, ros)
    except ConfigError as error:
        print(
            f"python -m bridge: bad setting {_source(error.setting)}: {error.problem}",
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
        print(f"python -m bridge: {port_problem(error, config.tcp_ip, config.tcp_port)}", file=sys.stderr)
        ros.shutdown("bind failed")
        return 2
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
    facts = gather_facts(config.tcp_ip, port)
    for line in summary(facts):
        print(line, flush=True)
    for finding in findings(facts):
        log.warning("%s", finding)

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
