"""The controller's ROS side: the node that drives a robot, simulated or real, whose subclasses are the commander and
the study runner (rospy nodes). In the thesis, Simulink played this part.

Publishes the joint command (`<prefix>/arm_controller/command`, trajectory_msgs/JointTrajectory with ONE point of
positions and velocities, stamped with the time the target is for) and `/clock`; listens to `<prefix>/joint_states`.
In lockstep the engine steps once per /clock value and answers with a joint state of that stamp, which
`state_or_fail` waits for. `wait_for_partner` finds the engine (a node publishing the joint states and subscribing
the command) and waits until every link to it, and to nodes such as a rosbag recorder, is connected.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from sim.errors import SimError
from sim.processes import writes_to
from sim.robots import RobotSpec
from sim.wire.contract import STAMP_TOLERANCE_S, MessageError, positions_by_name

__all__ = ["ControllerError", "ReceivedJointState", "StateListener", "ControllerNode", "unwritten_subscribers"]

# How long close() waits for queued messages to reach slow subscribers (e.g. a rosbag recorder on a loaded machine).
DRAIN_TIMEOUT_S = 5.0


class ControllerError(SimError, RuntimeError):
    """A ROS-side failure: no partner, a joint state that does not arrive, a malformed joint state."""


@dataclass
class ReceivedJointState:
    """A joint state as received: its stamp and the positions in the robot's joint order."""

    stamp: float
    positions: np.ndarray


class StateListener:
    """Latest joint state of the robot (in the robot's joint order), with a wait for a stamp."""

    def __init__(self, robot: RobotSpec) -> None:
        self.robot = robot
        self.latest: ReceivedJointState | None = None
        self.received = 0
        self.error: str | None = None
        self._changed = threading.Condition()

    def callback(self, message: Any) -> None:
        try:
            positions = positions_by_name(message.name, message.position, self.robot.joint_names)
        except MessageError as error:
            with self._changed:
                self.error = str(error)
                self._changed.notify_all()
            return
        with self._changed:
            self.latest = ReceivedJointState(message.header.stamp.to_sec(), positions)
            self.received += 1
            self._changed.notify_all()

    def wait_for_stamp(self, stamp: float, timeout: float, stop: threading.Event) -> ReceivedJointState | None:
        """The latest state once its stamp is >= `stamp` (None after `timeout` s or when stopped)."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                if self.error is not None:
                    raise ControllerError(f"{self.robot.joint_states_topic}: {self.error}")
                if self.latest is not None and self.latest.stamp >= stamp - STAMP_TOLERANCE_S:
                    return self.latest
                remaining = deadline - time.monotonic()
                if remaining <= 0 or stop.is_set():
                    return None
                self._changed.wait(min(remaining, 0.2))

    def wake(self) -> None:
        with self._changed:
            self._changed.notify_all()


def unwritten_subscribers(publisher: Any) -> list[str]:
    """The subscribers (caller ids) to which `publisher` still holds messages that it has not written.

    A rospy publisher made with a queue_size writes to each subscriber from a thread of its own, and unregistering
    drops what that thread has not written yet: the last commands of a run never reached a busy recorder. rospy
    offers no flush, so this reads its queued connection: everything is written once the queue is empty and the
    thread is back waiting for more (it waits only after writing all that it took)."""
    behind = []
    for connection in publisher.impl.connections:
        available = getattr(connection, "_cond_data_available", None)
        if available is None:  # an unqueued connection: publish() itself wrote the message
            continue
        with available:
            if connection.done:  # closed: nothing more can be written
                continue
            if connection._queue or not available._waiters:
                behind.append(connection.endpoint_id)
    return behind


class ControllerNode:
    """The command and /clock publishers, the joint-state subscriber, and the waits on them. `stop` (set by a
    signal handler) ends every wait."""

    def __init__(self, robot: RobotSpec, stop: threading.Event) -> None:
        import rospy
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import JointState
        from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

        self.rospy = rospy
        self._clock_type, self._trajectory_type, self._point_type = Clock, JointTrajectory, JointTrajectoryPoint
        self.robot = robot
        self.stop = stop
        self.states = StateListener(robot)
        self._last_clock = -float("inf")
        self.command_pub = rospy.Publisher(robot.command_topic, JointTrajectory, queue_size=100)
        self.clock_pub = rospy.Publisher("/clock", Clock, queue_size=100)
        self.state_sub = rospy.Subscriber(
            robot.joint_states_topic, JointState, self.states.callback, tcp_nodelay=True, queue_size=100
        )
        # Further publishers whose links to the partner (where it subscribes) and to --wait-for nodes must be up
        # before the run starts, e.g. the commander's goal pose.
        self.watched_publishers: list[tuple[str, Any]] = [
            (robot.command_topic, self.command_pub),
            ("/clock", self.clock_pub),
        ]

    def ros_time(self, seconds: float) -> Any:
        return self.rospy.Time.from_sec(round(seconds, 9))

    def publish_command(self, stamp: float, positions: np.ndarray, velocities: np.ndarray) -> None:
        message = self._trajectory_type()
        message.header.stamp = self.ros_time(stamp)
        message.joint_names = list(self.robot.joint_names)
        point = self._point_type()
        point.positions = [float(v) for v in positions]
        point.velocities = [float(v) for v in velocities]
        message.points = [point]
        self.command_pub.publish(message)

    def publish_clock(self, seconds: float) -> None:
        if seconds <= self._last_clock:
            raise ControllerError(f"/clock must increase strictly: {seconds} after {self._last_clock}")
        self._last_clock = seconds
        self.clock_pub.publish(self._clock_type(clock=self.ros_time(seconds)))

    def wait_for_partner(self, timeout: float, wait_for: Sequence[str] = ()) -> str:
        """Name of a node that publishes joint_states and subscribes our command topic, once every link of ours
        to it is connected, and so is every link to the nodes named in `wait_for`. Polls the master (bounded by
        `timeout`)."""
        import rosgraph

        master = rosgraph.Master(self.rospy.get_name())
        me = self.rospy.get_name()
        deadline = time.monotonic() + timeout
        status = "no node publishes it yet"
        while not self.stop.is_set():
            publishers, subscribers, _ = master.getSystemState()
            pubs = {topic: set(nodes) for topic, nodes in publishers}
            subs = {topic: set(nodes) for topic, nodes in subscribers}
            partners = sorted(
                (pubs.get(self.robot.joint_states_topic, set()) & subs.get(self.robot.command_topic, set())) - {me}
            )
            for partner in partners:
                links = {
                    self.robot.joint_states_topic: writes_to(
                        master.lookupNode(partner), self.robot.joint_states_topic, me
                    )
                }
                for topic, publisher in self.watched_publishers:
                    if partner in subs.get(topic, set()):
                        links[topic] = publisher.impl.has_connection(partner)
                for node in wait_for:
                    node = node if node.startswith("/") else "/" + node
                    if not any(node in nodes for nodes in subs.values()):
                        links[f"{node} (not registered)"] = False
                    for topic, publisher in self.watched_publishers:
                        if node in subs.get(topic, set()):
                            links[f"{topic} -> {node}"] = publisher.impl.has_connection(node)
                if all(links.values()):
                    return partner
                status = f"{partner} found, waiting for {[t for t, ok in links.items() if not ok]}"
            if time.monotonic() > deadline:
                raise ControllerError(
                    f"no engine after {timeout:g} s: needs a node publishing {self.robot.joint_states_topic} and "
                    f"subscribing {self.robot.command_topic} ({status}); start e.g. "
                    f"`python -m sim.physics_node --robot {self.robot.name} --no-auto-simulate`"
                )
            self.stop.wait(0.05)
        raise ControllerError("interrupted while waiting for the engine")

    def state_or_fail(self, stamp: float, timeout: float, dt: float) -> ReceivedJointState:
        """The joint state stamped >= `stamp`, waited for at most `timeout` s."""
        state = self.states.wait_for_stamp(stamp, timeout, self.stop)
        if state is None:
            if self.stop.is_set():
                raise ControllerError("interrupted")
            last = "none received" if self.states.latest is None else f"latest stamped {self.states.latest.stamp:.6f} s"
            raise ControllerError(
                f"no {self.robot.joint_states_topic} message stamped >= {stamp:.6f} s within {timeout:g} s "
                f"({last}); is the engine stepping on /clock (--no-auto-simulate) with dt {dt:g} s?"
            )
        return state

    def close(self) -> None:
        self.states.wake()
        deadline = time.monotonic() + DRAIN_TIMEOUT_S
        for topic, publisher in self.watched_publishers:
            while (behind := unwritten_subscribers(publisher)) and time.monotonic() < deadline:
                time.sleep(0.005)
            if behind:
                self.rospy.logwarn("%s: messages to %s were not written within %g s", topic, behind, DRAIN_TIMEOUT_S)
        for _, publisher in self.watched_publishers:
            publisher.unregister()
        self.state_sub.unregister()
