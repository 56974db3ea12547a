"""The engine's physics as a rospy node: same topics, same switches, no TCP endpoint in between.

`python -m sim.physics_node --robot panda [--mode ...] [--no-auto-simulate] ...` takes the same options as
`python -m sim.engine` (except host/port/csv). The stepping logic is `sim.engine.EngineStandIn`; only the
transport differs: rospy topics instead of the endpoint's TCP connection.

With `--trajectory-controller NS` the node is a real arm's driver instead: a ros_control joint trajectory
controller under NS on wall time (sim.engine.trajectory_server), joint states at `--joint-states-rate` on
`--joint-states-topic`, and no stream on the command topic or /clock.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

import rospy

from sim.engine.stand_in import EngineOptions, EngineStandIn, argument_parser, make_world, options_from_args
from sim.entry import EXIT_BAD_INPUT, EXIT_OK, fail, without_ros_arguments
from sim.errors import SimError
from sim.robots import RobotSpec, robot_from_args
from sim.wire.rosnode import init_node

if TYPE_CHECKING:
    from sim.engine.trajectory_server import TrajectoryServerOptions

__all__ = ["RospyTransport", "main"]

log = logging.getLogger(__name__)


def _message_class(ros1_name: str) -> type:
    package, type_name = ros1_name.split("/")
    module = __import__(f"{package}.msg", fromlist=[type_name])
    return getattr(module, type_name)


class RospyTransport:
    """The subset of bridge.client.TcpClient's interface the engine uses, on plain rospy topics.

    Incoming messages reach the engine as raw ROS 1 bytes (rospy.AnyMsg), exactly as through the endpoint.
    """

    def __init__(self) -> None:
        self._publishers: dict[str, tuple[rospy.Publisher, type]] = {}
        self._subscribers: list[rospy.Subscriber] = []

    def subscribe(self, topic: str, message_name: str, callback: Callable[[bytes], None]) -> None:
        self._subscribers.append(
            rospy.Subscriber(topic, rospy.AnyMsg, lambda msg: callback(msg._buff), tcp_nodelay=True)
        )

    def register_publisher(self, topic: str, message_name: str, queue_size: int = 10, latch: bool = False) -> None:
        cls = _message_class(message_name)
        self._publishers[topic] = (rospy.Publisher(topic, cls, queue_size=queue_size, latch=latch), cls)

    def publish(self, topic: str, payload: bytes) -> None:
        publisher, cls = self._publishers[topic]
        publisher.publish(cls().deserialize(payload))

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()
        for publisher, _ in self._publishers.values():
            publisher.unregister()


def _log_to_screen() -> None:
    # init_node points the root logger at the node's log file only, which would hide the engine's errors (a
    # rejected command, a clock jump) from the console; keep the file and show the sim's messages on stderr too.
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("[%(levelname)s] [%(name)s] %(message)s"))
    logger = logging.getLogger("sim")
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)


def node_argument_parser() -> argparse.ArgumentParser:
    parser = argument_parser()
    parser.prog = "python -m sim.physics_node"
    group = parser.add_argument_group("as a real arm's driver: a ros_control joint trajectory controller on wall time")
    group.add_argument(
        "--trajectory-controller",
        metavar="NS",
        help="offer NS/follow_joint_trajectory, NS/command, NS/state and NS/query_state instead of the stream",
    )
    group.add_argument("--joint-states-topic", help="where the driver publishes joint states (default: the robot's)")
    group.add_argument(
        "--joint-states-rate", type=float, default=50.0, help="Hz, at most one per physics step (default 50)"
    )
    group.add_argument(
        "--stop-trajectory-duration",
        type=float,
        default=0.0,
        help="s a cancel takes to come to rest; 0 holds the measured position at once (default, as franka's)",
    )
    group.add_argument(
        "--goal-time",
        type=float,
        default=0.5,
        help="s after its last point a goal may take to settle; 0: none, it aborts at once (default 0.5, as franka's)",
    )
    return parser


def _server_options(args: argparse.Namespace, robot: RobotSpec, options: EngineOptions) -> TrajectoryServerOptions:
    from sim.engine.trajectory_server import TrajectoryServerOptions  # actionlib: only for a trajectory controller

    if not options.auto_simulate:
        raise SimError("--trajectory-controller runs on wall time: --no-auto-simulate does not go with it")
    if not (args.joint_states_rate > 0 and args.stop_trajectory_duration >= 0 and args.goal_time >= 0):
        raise SimError(
            f"--joint-states-rate must be > 0, --stop-trajectory-duration and --goal-time >= 0; got "
            f"{args.joint_states_rate}, {args.stop_trajectory_duration} and {args.goal_time}"
        )
    return TrajectoryServerOptions(
        namespace=args.trajectory_controller,
        joint_states_topic=args.joint_states_topic or robot.joint_states_topic,
        joint_states_rate=args.joint_states_rate,
        stop_trajectory_duration=args.stop_trajectory_duration,
        goal_time=args.goal_time,
    )


def main(argv: list[str] | None = None) -> int:
    args = node_argument_parser().parse_args(without_ros_arguments(sys.argv[1:] if argv is None else argv))
    try:
        robot = robot_from_args(args)
        options = options_from_args(args)
        server_options = _server_options(args, robot, options) if args.trajectory_controller else None
    except (SimError, ValueError) as error:
        return fail("sim.physics_node", error, EXIT_BAD_INPUT)
    init_node(f"{robot.name}_physics")
    _log_to_screen()
    if server_options is not None:
        return _run_trajectory_controller(robot, options, server_options, args.duration)
    transport = RospyTransport()
    engine = EngineStandIn(robot, transport, options)  # type: ignore[arg-type]
    engine.attach()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: engine.stop())
    mode = "auto-simulate" if options.auto_simulate else "/clock-driven"
    print(f"physics node: {robot.name} in {options.mode.value} mode, {mode}, dt {options.dt} s", flush=True)
    try:
        engine.run(args.duration)
    finally:
        transport.close()
        engine.close()
        rospy.signal_shutdown("physics node stopped")
        print(f"physics node: stopped after {engine.steps} steps", flush=True)
    return EXIT_OK


def _run_trajectory_controller(
    robot: RobotSpec, options: EngineOptions, server_options: TrajectoryServerOptions, duration: float | None
) -> int:
    from sim.engine.trajectory_server import TrajectoryServer

    world = make_world(robot, options)
    server = TrajectoryServer(robot, world, server_options)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: server.stop())
    print(
        f"physics node: {robot.name} in {options.mode.value} mode, trajectory controller "
        f"{server_options.namespace} on wall time, joint states on {server_options.joint_states_topic} at "
        f"{server_options.joint_states_rate:g} Hz, dt {options.dt} s",
        flush=True,
    )
    try:
        server.run(duration)
    finally:
        server.close()
        world.close()
        rospy.signal_shutdown("physics node stopped")
        print(f"physics node: stopped after {server.steps} steps", flush=True)
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
