"""The engine's physics as a rospy node: same topics, same switches, no TCP endpoint in between.

`python -m sim.physics_node --robot panda [--mode ...] [--no-auto-simulate] ...` takes the same options as
`python -m sim.engine` (except host/port/csv). The stepping logic is `sim.engine.EngineStandIn`; only the
transport differs: rospy topics instead of the endpoint's TCP connection.
"""

from __future__ import annotations

import logging
import signal
import sys
from collections.abc import Callable

import rospy

from sim.engine.stand_in import EngineStandIn, argument_parser, options_from_args
from sim.entry import EXIT_BAD_INPUT, EXIT_OK, fail, without_ros_arguments
from sim.errors import SimError
from sim.robots import robot_from_args
from sim.wire.rosnode import init_node

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


def main(argv: list[str] | None = None) -> int:
    args = argument_parser().parse_args(without_ros_arguments(sys.argv[1:] if argv is None else argv))
    try:
        robot = robot_from_args(args)
        options = options_from_args(args)
    except (SimError, ValueError) as error:
        return fail("sim.physics_node", error, EXIT_BAD_INPUT)
    init_node(f"{robot.name}_physics")
    _log_to_screen()
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


if __name__ == "__main__":
    sys.exit(main())
