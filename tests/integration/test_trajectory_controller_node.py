"""The physics node as a real arm's driver: a ros_control trajectory controller on wall time, driven by actionlib's own
ActionClient and a plain publisher, with a real roscore. Result codes and the achieved joint states checked.

The client is actionlib's ActionClient, each goal followed through its own handle: SimpleActionClient drops a
result that comes back before its send_goal has returned (it logs "a goal handle that we're not tracking" and waits
for ever), which a controller that rejects at once, as ros_control's does, makes happen now and then."""

from __future__ import annotations

import os
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sim.control.trajectory_client import wait_for_action_server
from sim.robots import load_robot
from tests.integration.sim_helpers import start_physics_node
from tests.rosenv import PYTHON, REPO, ManagedProcess, wait_for

pytestmark = pytest.mark.lane("realtime", on=("project",))

PANDA = load_robot("panda")
NS = "/panda/position_joint_trajectory_controller"
JOINT_STATES = "/franka_state_controller/joint_states"  # where franka_ros publishes them
JOINT = 0  # panda_joint1 moves; the others hold home


class Arm:
    """The test's view of the arm: every joint state heard, and the controller's action, command and services."""

    def __init__(self, rospy: Any) -> None:
        import actionlib
        from sensor_msgs.msg import JointState
        from trajectory_msgs.msg import JointTrajectory

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
        self.client = actionlib.ActionClient(f"{NS}/follow_joint_trajectory", self.types.action)
        self.handles: list[Any] = []

    def _on_state(self, message: Any) -> None:
        with self._lock:
            self.states.append(message)

    def latest(self) -> Any:
        wait_for(lambda: self.states, 15, "a joint state")
        with self._lock:
            return self.states[-1]

    def position(self) -> float:
        return float(self.latest().position[JOINT])

    def settled(self, window: int = 15) -> float:
        """The joint's position once it has rested for `window` joint states (half a second at 30 Hz): a single
        state slower than a threshold may be the turning point of an overshoot."""

        def resting() -> bool:
            with self._lock:
                recent = [s.position[JOINT] for s in self.states[-window:]]
                speeds = [abs(s.velocity[JOINT]) for s in self.states[-window:]]
            return len(recent) == window and max(recent) - min(recent) < 1e-4 and max(speeds) < 1e-3

        wait_for(resting, 20, "the arm at rest")
        return self.position()

    def moving_past(self, position: float, rising: bool) -> None:
        wait_for(
            lambda: (self.position() > position) if rising else (self.position() < position),
            20,
            f"joint past {position}",
        )

    def trajectory(self, offsets: list[float], duration: float, names: tuple[str, ...] = PANDA.joint_names) -> Any:
        """A rest-to-rest quintic of joint 1 through `offsets` from home, every point with positions, velocities and
        accelerations (as the runner sends an approach); stamp zero."""
        from sim.wire.control_types import joint_trajectory

        positions = np.tile(np.array(PANDA.home, dtype=float)[: len(names)], (len(offsets), 1))
        positions[:, JOINT] += offsets
        times = duration * np.arange(1, len(offsets) + 1) / len(offsets)
        zeros = np.zeros_like(positions)
        return joint_trajectory(names, times, positions, zeros, zeros)

    def send(self, trajectory: Any, stamp: Any = None) -> Any:
        """The goal's handle, once the goal is sent."""
        goal = self.types.goal()
        goal.trajectory = trajectory
        if stamp is not None:
            goal.trajectory.header.stamp = stamp
        handle = self.client.send_goal(goal)
        self.handles.append(handle)
        return handle

    def outcome(self, handle: Any) -> tuple[int, int]:
        """(the goal's final status, its result's error code), once the server has ended it."""
        from actionlib import CommState

        wait_for(lambda: handle.get_comm_state() == CommState.DONE, 30, "the goal's result")
        return handle.get_goal_status(), handle.get_result().error_code

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()
        self.command.unregister()
        self.handles.clear()  # actionlib tracks a goal while its handle lives
        client = self.client
        for endpoint in (client.pub_goal, client.pub_cancel, client.status_sub, client.result_sub, client.feedback_sub):
            endpoint.unregister()


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
        # Until the server writes its result to us: a goal rejected at once could lose its result otherwise.
        assert wait_for_action_server(arm.client, f"{NS}/follow_joint_trajectory", 20), "the action server"
        yield node, arm
    finally:
        arm.close()
        node.stop()


def test_goals_replacement_command_cancel_and_wrong_joints_through_actionlib(arm: tuple[ManagedProcess, Arm]) -> None:
    from actionlib_msgs.msg import GoalStatus

    node, arm_ = arm
    rospy = arm_.rospy
    home = PANDA.home[JOINT]
    Result = arm_.types.result

    # Wrong joints: rejected with INVALID_JOINTS, nothing moves.
    wrong = arm_.trajectory([0.2], 1.0, names=("panda_joint1", "panda_joint2", "gripper"))
    assert arm_.outcome(arm_.send(wrong)) == (GoalStatus.REJECTED, Result.INVALID_JOINTS)

    # All points in the past: rejected with INVALID_GOAL.
    past = arm_.send(arm_.trajectory([0.2], 1.0), stamp=rospy.Time.now() - rospy.Duration(30))
    assert arm_.outcome(past) == (GoalStatus.REJECTED, Result.INVALID_GOAL)
    assert abs(arm_.position() - home) < 1e-3

    # A goal, replaced mid-motion by another: the first is preempted, the second succeeds where it says.
    first = arm_.send(arm_.trajectory([0.15, 0.3], 3.0))
    arm_.moving_past(home + 0.05, rising=True)
    second = arm_.send(arm_.trajectory([0.1], 1.5))
    assert arm_.outcome(first)[0] == GoalStatus.PREEMPTED
    assert arm_.outcome(second) == (GoalStatus.SUCCEEDED, Result.SUCCESSFUL)
    assert abs(arm_.settled() - (home + 0.1)) < 1e-3
    assert max(abs(s.position[JOINT] - home) for s in arm_.states) < 0.3  # never reached the first goal's end

    # A message on the command topic during a goal cancels the goal; the arm follows the message.
    third = arm_.send(arm_.trajectory([0.4], 3.0))
    arm_.moving_past(home + 0.15, rising=True)
    arm_.command.publish(arm_.trajectory([0.2], 1.0))
    assert arm_.outcome(third)[0] == GoalStatus.PREEMPTED
    assert abs(arm_.settled() - (home + 0.2)) < 1e-3

    # Cancel: stop_trajectory_duration 0 holds the measured position at once; the arm comes to rest short of the goal.
    fourth = arm_.send(arm_.trajectory([-0.3], 3.0))
    arm_.moving_past(home + 0.1, rising=False)
    fourth.cancel()
    assert arm_.outcome(fourth)[0] == GoalStatus.PREEMPTED
    rest = arm_.settled()
    assert home - 0.3 + 0.05 < rest < home + 0.1, rest

    # The state topic and query_state say where the controller wants the arm: where it rests, all seven joints.
    query = rospy.ServiceProxy(f"{NS}/query_state", arm_.types.query_state)
    answer = query(arm_.types.query_state_request(time=rospy.Time.now()))
    assert tuple(answer.name) == PANDA.joint_names and abs(answer.position[JOINT] - rest) < 1e-3
    assert arm_.controller_states and tuple(arm_.controller_states[-1].joint_names) == PANDA.joint_names
    assert node.process.poll() is None


def points(
    arm: Arm, times: np.ndarray, positions: np.ndarray, velocities: np.ndarray, accelerations: np.ndarray
) -> Any:
    """A JointTrajectory of the Panda through these samples (time_from_start, then the three per joint)."""
    from sim.wire.control_types import joint_trajectory

    return joint_trajectory(PANDA.joint_names, times, positions, velocities, accelerations)


def test_a_press_as_a_braking_replacement_stops_the_approach_smoothly_short_of_its_end(
    arm: tuple[ManagedProcess, Arm],
) -> None:
    """What the runner will do on a press: the approach as one goal, then braking along its path from the
    controller's desired state (query_state, a little ahead), sent as a replacement stamped with that time."""
    from actionlib_msgs.msg import GoalStatus

    from sim.study.safety.braking import PathGeometry, PathState, arc_length, brake
    from tests.unit.sim.study.safety.plans import panda_plan

    _, arm_ = arm
    rospy = arm_.rospy
    path, joints = panda_plan("diagonal", 0.3)  # 2.5 s: room for a test process slowed by a loaded machine
    geometry = PathGeometry(path, joints)
    arc, accelerations = arc_length(path), np.gradient(path.speeds, path.dt)
    planned = [geometry.joint_state(PathState(arc[k], path.speeds[k], accelerations[k])) for k in range(len(arc))]
    q, v, a = (np.array([state[i] for state in planned]) for i in range(3))

    start = arm_.send(points(arm_, np.array([2.0]), q[:1], np.zeros((1, 7)), np.zeros((1, 7))))
    assert arm_.outcome(start)[0] == GoalStatus.SUCCEEDED
    # The approach starts at a stamp ahead and the press brakes at a known time into it, so the test plans the stop
    # from the desired state then (query_state answers for a future time) before the arm gets there: the
    # replacement must arrive before its stamp, or the controller bridges from where its desired state has gone
    # meanwhile (the runner's look-ahead, likewise). Reacting to the arm's motion instead made that a race with
    # the test process's own speed.
    begins = rospy.Time.now() + rospy.Duration.from_sec(0.5)
    approach = arm_.send(points(arm_, path.times[1:], q[1:], v[1:], a[1:]), stamp=begins)
    wait_for(lambda: approach.get_goal_status() == GoalStatus.ACTIVE, 20, "the approach accepted")
    at = begins + rospy.Duration.from_sec(0.8)  # the plan's fast part
    query = rospy.ServiceProxy(f"{NS}/query_state", arm_.types.query_state)
    desired = query(arm_.types.query_state_request(time=at))
    stop = brake(geometry, *(np.array(x) for x in (desired.position, desired.velocity, desired.acceleration)), 0.01)
    assert stop is not None and stop.start.speed > 0.1 and stop.arc[-1] < geometry.length - 0.05
    braking = arm_.send(
        points(arm_, stop.times[1:], stop.positions[1:], stop.velocities[1:], stop.accelerations[1:]), stamp=at
    )
    late = (rospy.Time.now() - at).to_sec()
    assert late < 0, f"the replacement went out {late:.3f} s after its stamp: the test process stalled for > 1.3 s"
    assert arm_.outcome(approach)[0] == GoalStatus.PREEMPTED
    assert arm_.outcome(braking) == (GoalStatus.SUCCEEDED, arm_.types.result.SUCCESSFUL)

    def resting() -> bool:
        recent = arm_.states[-15:]
        return len(recent) == 15 and max(np.abs(s.velocity).max() for s in recent) < 1e-3

    wait_for(resting, 20, "the arm at rest")
    np.testing.assert_allclose(arm_.latest().position, stop.positions[-1], atol=1e-3)  # where braking rests
    # No step in the achieved velocity around the replacement: its changes between joint states stay within the
    # Panda's acceleration limits.
    around = [s for s in arm_.states if s.header.stamp.to_sec() >= at.to_sec() - 1.0]
    stamps = np.array([s.header.stamp.to_sec() for s in around])
    velocities = np.array([s.velocity for s in around])
    achieved = np.abs(np.diff(velocities, axis=0)) / np.diff(stamps)[:, None]
    assert np.all(achieved <= np.array([15, 7.5, 10, 12.5, 15, 20, 20])), achieved.max(axis=0)


@pytest.mark.lane("beside", on=("project",))
def test_a_trajectory_controller_in_lockstep_is_one_line_and_exit_2(tmp_path: Path) -> None:
    done = subprocess.run(
        [PYTHON, "-m", "sim.physics_node", "--robot", "panda", "--trajectory-controller", NS, "--no-auto-simulate"],
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(REPO), "ROS_MASTER_URI": "http://127.0.0.1:9/"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    lines = [line for line in done.stderr.splitlines() if not line.startswith("pybullet build time:")]
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert lines[0].startswith("sim.physics_node: error: --trajectory-controller runs on wall time"), lines
