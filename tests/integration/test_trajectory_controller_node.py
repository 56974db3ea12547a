"""The physics node as a real arm's driver: a ros_control trajectory controller on wall time, driven by actionlib's own
SimpleActionClient and a plain publisher, with a real roscore. Result codes and the achieved joint states checked."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sim.robots import load_robot
from tests.integration.sim_helpers import start_physics_node
from tests.rosenv import ManagedProcess, wait_for

pytestmark = pytest.mark.lane("alone", on=("project",))

PANDA = load_robot("panda")
NS = "/panda/position_joint_trajectory_controller"
JOINT_STATES = "/franka_state_controller/joint_states"  # where franka_ros publishes them
JOINT = 0  # panda_joint1 moves; the others hold home


class Arm:
    """The test's view of the arm: every joint state heard, and the controller's action, command and services."""

    def __init__(self, rospy: Any) -> None:
        import actionlib
        from sensor_msgs.msg import JointState
        from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

        from sim.wire.control_types import control_types

        self.rospy = rospy
        self.types = control_types()
        self.states: list[Any] = []
        self.controller_states: list[Any] = []
        self._lock = threading.Lock()
        self._subscribers = [
            rospy.Subscriber(JOINT_STATES, JointState, self._on_state),
            rospy.Subscriber(f"{NS}/state", self.types.controller_state, self.controller_states.append),
        ]
        self.command = rospy.Publisher(f"{NS}/command", JointTrajectory, queue_size=1)
        self.JointTrajectory = JointTrajectory
        self.JointTrajectoryPoint = JointTrajectoryPoint
        self.clients = [
            actionlib.SimpleActionClient(f"{NS}/follow_joint_trajectory", self.types.action) for _ in range(2)
        ]

    def _on_state(self, message: Any) -> None:
        with self._lock:
            self.states.append(message)

    def latest(self) -> Any:
        wait_for(lambda: self.states, 15, "a joint state")
        with self._lock:
            return self.states[-1]

    def position(self) -> float:
        return float(self.latest().position[JOINT])

    def moving_past(self, position: float, rising: bool) -> None:
        wait_for(
            lambda: (self.position() > position) if rising else (self.position() < position),
            20,
            f"joint past {position}",
        )

    def trajectory(self, offsets: list[float], duration: float, names: tuple[str, ...] = PANDA.joint_names) -> Any:
        """A rest-to-rest quintic of joint 1 through `offsets` from home, every point with positions, velocities and
        accelerations (as the runner sends an approach); stamp zero."""
        message = self.JointTrajectory()
        message.joint_names = list(names)
        for k, offset in enumerate(offsets, start=1):
            target = self.JointTrajectoryPoint()
            positions = np.array(PANDA.home, dtype=float)[: len(names)]
            positions[JOINT] += offset
            target.positions = positions.tolist()
            target.velocities = [0.0] * len(names)
            target.accelerations = [0.0] * len(names)
            target.time_from_start = self.rospy.Duration.from_sec(duration * k / len(offsets))
            message.points.append(target)
        return message

    def goal(self, trajectory: Any, stamp: Any = None) -> Any:
        goal = self.types.goal()
        goal.trajectory = trajectory
        if stamp is not None:
            goal.trajectory.header.stamp = stamp
        return goal

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()
        self.command.unregister()
        for client in self.clients:
            client.stop_tracking_goal()


@pytest.fixture
def arm(roscore, ros_node, tmp_path: Path) -> Iterator[tuple[ManagedProcess, Arm]]:
    node = start_physics_node(
        roscore,
        tmp_path,
        "panda",
        "--mode",
        "physics",
        "--trajectory-controller",
        NS,
        "--joint-states-topic",
        JOINT_STATES,
        "--joint-states-rate",
        "30",
    )
    arm = Arm(ros_node)
    try:
        for client in arm.clients:
            assert client.wait_for_server(ros_node.Duration(20)), "the action server"
        yield node, arm
    finally:
        arm.close()
        node.stop()


def test_goals_replacement_command_cancel_and_wrong_joints_through_actionlib(arm: tuple[ManagedProcess, Arm]) -> None:
    from actionlib_msgs.msg import GoalStatus

    node, arm_ = arm
    rospy, first, second = arm_.rospy, arm_.clients[0], arm_.clients[1]
    home = PANDA.home[JOINT]
    Result = arm_.types.result

    # Wrong joints: rejected with INVALID_JOINTS, nothing moves.
    wrong = arm_.trajectory([0.2], 1.0, names=("panda_joint1", "panda_joint2", "gripper"))
    first.send_goal(arm_.goal(wrong))
    assert first.wait_for_result(rospy.Duration(20))
    assert first.get_state() == GoalStatus.REJECTED
    assert first.get_result().error_code == Result.INVALID_JOINTS

    # All points in the past: rejected with INVALID_GOAL.
    first.send_goal(arm_.goal(arm_.trajectory([0.2], 1.0), stamp=rospy.Time.now() - rospy.Duration(30)))
    assert first.wait_for_result(rospy.Duration(20))
    assert first.get_state() == GoalStatus.REJECTED and first.get_result().error_code == Result.INVALID_GOAL
    assert abs(arm_.position() - home) < 1e-3

    # A goal, replaced mid-motion by another: the first is preempted, the second succeeds where it says.
    first.send_goal(arm_.goal(arm_.trajectory([0.15, 0.3], 3.0)))
    arm_.moving_past(home + 0.05, rising=True)
    second.send_goal(arm_.goal(arm_.trajectory([0.1], 1.5)))
    assert first.wait_for_result(rospy.Duration(20)) and first.get_state() == GoalStatus.PREEMPTED
    assert second.wait_for_result(rospy.Duration(30))
    assert second.get_state() == GoalStatus.SUCCEEDED and second.get_result().error_code == Result.SUCCESSFUL
    assert abs(arm_.position() - (home + 0.1)) < 5e-3
    assert max(abs(s.position[JOINT] - home) for s in arm_.states) < 0.3  # never reached the first goal's end

    # A message on the command topic during a goal cancels the goal; the arm follows the message.
    first.send_goal(arm_.goal(arm_.trajectory([0.4], 3.0)))
    arm_.moving_past(home + 0.15, rising=True)
    arm_.command.publish(arm_.trajectory([0.2], 1.0))
    assert first.wait_for_result(rospy.Duration(20)) and first.get_state() == GoalStatus.PREEMPTED
    wait_for(lambda: abs(arm_.position() - (home + 0.2)) < 5e-3, 20, "the command's end")

    # Cancel: stop_trajectory_duration 0 holds the measured position at once; the arm comes to rest short of the goal.
    first.send_goal(arm_.goal(arm_.trajectory([-0.3], 3.0)))
    arm_.moving_past(home + 0.1, rising=False)
    first.cancel_goal()
    assert first.wait_for_result(rospy.Duration(20)) and first.get_state() == GoalStatus.PREEMPTED
    wait_for(lambda: abs(arm_.latest().velocity[JOINT]) < 1e-3, 20, "the arm at rest")
    rest = arm_.position()
    assert home - 0.3 + 0.05 < rest < home + 0.1

    # The state topic and query_state say where the controller wants the arm: where it rests, all seven joints.
    query = rospy.ServiceProxy(f"{NS}/query_state", arm_.types.query_state)
    answer = query(arm_.types.query_state_request(time=rospy.Time.now()))
    assert tuple(answer.name) == PANDA.joint_names and abs(answer.position[JOINT] - rest) < 1e-3
    assert arm_.controller_states and tuple(arm_.controller_states[-1].joint_names) == PANDA.joint_names
    assert node.process.poll() is None
