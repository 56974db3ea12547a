"""The commander as a trajectory controller's client (a real arm's interface): its schedule goes to a ros_control
joint_trajectory_controller as follow_joint_trajectory goals, window by window (sim.control.horizon), on wall time.
A rospy and actionlib node part.

No /clock and no stream: the controller runs on the wall clock, so every window is stamped with the wall time of
the schedule's sample 0, and each new goal replaces the one before (which ends PREEMPTED) without a seam. The joint
states come from the driver's topic at its own rate; the achieved joints are read at the schedule's times from them
(sim.control.horizon.hermite_at). actionlib's ActionClient, each goal followed through its handle (SimpleActionClient
loses a result that comes back before send_goal has returned).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.control.controller_node import ControllerError
from sim.control.horizon import achieved_at, windows
from sim.control.run_log import RunResult
from sim.control.scenarios import Schedule
from sim.processes import writes_to
from sim.robots import RobotSpec
from sim.wire.contract import MessageError, positions_by_name

__all__ = ["ControllerLink", "TrajectoryClient", "wait_for_action_server"]

SETTLE_S = 0.3  # s after the last sample is due that the joint states are still read
RESULT_TIMEOUT_S = 10.0  # s after that for the last goal's result (the controller's goal time comes first)


def wait_for_action_server(client: Any, action: str, timeout: float) -> bool:
    """actionlib's `client.wait_for_server`, then until the server's node writes its result, feedback and status to
    us (False after `timeout` s). actionlib checks our subscribers' side only; rospy's publisher answers a new
    subscriber's header before it takes the connection, so a result published meanwhile is lost and its goal never
    ends: a goal rejected at once right after wait_for_server did so on a loaded machine (ros/actionlib#180 closed
    the wider gap, not this one). Only the publisher knows when it writes to us (sim.processes.writes_to)."""
    import rosgraph
    import rospy

    deadline = time.monotonic() + timeout
    if not client.wait_for_server(rospy.Duration.from_sec(timeout)):
        return False
    me = rospy.get_name()
    server = client.last_status_msg._connection_header["callerid"]
    uri = rosgraph.Master(me).lookupNode(server)
    topics = [f"{rospy.resolve_name(action)}/{name}" for name in ("result", "feedback", "status")]
    while time.monotonic() < deadline:
        if all(writes_to(uri, topic, me) for topic in topics):
            return True
        time.sleep(0.01)
    return False


@dataclass(frozen=True)
class ControllerLink:
    """Which controller, and how the schedule goes to it."""

    namespace: str  # e.g. /panda/position_joint_trajectory_controller
    joint_states_topic: str
    horizon: float = 1.0  # s of schedule per goal
    resend: float = 0.25  # s between goals
    lead: float = 0.1  # s a goal goes out before its first sample is due


class TrajectoryClient:
    """The joint states heard and the controller's action; `run` sends a schedule and reads back what was achieved."""

    def __init__(self, robot: RobotSpec, link: ControllerLink, stop: threading.Event) -> None:
        import actionlib
        import rospy
        from sensor_msgs.msg import JointState
        from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

        from sim.wire.control_types import control_types

        self.rospy = rospy
        self.robot = robot
        self.link = link
        self.stop = stop
        self.types = control_types()
        self._trajectory, self._point = JointTrajectory, JointTrajectoryPoint
        self._states: list[tuple[float, np.ndarray, np.ndarray]] = []  # (stamp, positions, velocities)
        self._error: str | None = None
        self._lock = threading.Lock()
        self._sub = rospy.Subscriber(link.joint_states_topic, JointState, self._on_state, queue_size=1000)
        self._action = rospy.resolve_name(f"{link.namespace.rstrip('/')}/follow_joint_trajectory")
        self._client = actionlib.ActionClient(self._action, self.types.action)
        self._handles: list[Any] = []

    def _on_state(self, message: Any) -> None:
        try:
            positions = positions_by_name(message.name, message.position, self.robot.joint_names)
            velocities = (
                positions_by_name(message.name, message.velocity, self.robot.joint_names)
                if len(message.velocity) == len(message.name)
                else np.full(self.robot.dof, np.nan)
            )
        except MessageError as error:
            with self._lock:
                self._error = str(error)
            return
        with self._lock:
            self._states.append((message.header.stamp.to_sec(), positions, velocities))

    def wait(self, timeout: float) -> np.ndarray:
        """The robot's joint positions once the action server is up and a joint state has come (ControllerError
        after `timeout` s)."""
        deadline = time.monotonic() + timeout
        if not wait_for_action_server(self._client, self._action, timeout):
            raise ControllerError(
                f"no action server {self.link.namespace}/follow_joint_trajectory within {timeout:g} s"
            )
        while not self.stop.is_set() and time.monotonic() < deadline:
            with self._lock:
                if self._error is not None:
                    raise ControllerError(f"{self.link.joint_states_topic}: {self._error}")
                if self._states:
                    return self._states[-1][1].copy()
            self.stop.wait(0.02)
        raise ControllerError(f"no joint state on {self.link.joint_states_topic} within {timeout:g} s")

    def run(self, schedule: Schedule, dt: float) -> RunResult:
        """Send `schedule` (sample 0: where the robot is) window by window; the achieved joints at its times."""
        steps = len(schedule.positions) - 1
        link = self.link
        horizon, period, lead = (max(1, round(value / dt)) for value in (link.horizon, link.resend, link.lead))
        plan = windows(steps, dt, horizon, period, lead)
        started = time.monotonic()
        zero = time.time() - plan[0].send_at  # sample 0's wall time: the first window goes out now
        failure: str | None = None
        sent = 0
        for window in plan:
            delay = zero + window.send_at - time.time()
            if (delay > 0 and self.stop.wait(delay)) or self.stop.is_set():
                break
            failure = self._refused()
            if failure is not None:
                break
            self._send(schedule, window.indices, zero, dt)
            sent += 1
        complete = sent == len(plan) and failure is None
        if complete:
            self.stop.wait(max(0.0, zero + steps * dt + SETTLE_S - time.time()))
            failure = self._last_result()
        times = np.arange(1, steps + 1) * dt
        with self._lock:
            states = list(self._states)
        dof = self.robot.dof
        achieved = achieved_at(
            np.array([s[0] for s in states]) - zero,
            np.array([s[1] for s in states]).reshape(-1, dof),
            np.array([s[2] for s in states]).reshape(-1, dof),
            times,
        )
        known = np.all(np.isfinite(achieved), axis=1)
        return RunResult(
            times,
            np.arange(1, steps + 1),
            schedule.positions[1:],
            achieved,
            np.where(known, times, np.nan),
            time.monotonic() - started,
            0,
            complete and failure is None,
            failure if not self.stop.is_set() else None,
        )

    def _send(self, schedule: Schedule, indices: range, zero: float, dt: float) -> None:
        message = self._trajectory()
        message.header.stamp = self.rospy.Time.from_sec(zero)
        message.joint_names = list(self.robot.joint_names)
        for i in indices:
            point = self._point()
            point.positions = [float(v) for v in schedule.positions[i]]
            point.velocities = [float(v) for v in schedule.velocities[i]]
            point.time_from_start = self.rospy.Duration.from_sec(i * dt)
            message.points.append(point)
        goal = self.types.goal()
        goal.trajectory = message
        self._handles = self._handles[-3:] + [self._client.send_goal(goal)]  # actionlib tracks a goal while it lives

    def _refused(self) -> str | None:
        """Why the controller refused a goal of ours, if it did."""
        from actionlib import CommState
        from actionlib_msgs.msg import GoalStatus

        for handle in self._handles:
            if handle.get_comm_state() == CommState.DONE and handle.get_goal_status() == GoalStatus.REJECTED:
                result = handle.get_result()
                code, text = (result.error_code, result.error_string) if result is not None else ("?", "")
                return f"{self.link.namespace} rejected a goal: error code {code} {text}".rstrip()
        return None

    def _last_result(self) -> str | None:
        """None once the last goal has SUCCEEDED; otherwise what became of it."""
        from actionlib import CommState
        from actionlib_msgs.msg import GoalStatus

        if not self._handles:
            return "no goal was sent"
        handle = self._handles[-1]
        deadline = time.monotonic() + RESULT_TIMEOUT_S
        while handle.get_comm_state() != CommState.DONE:
            if self.stop.is_set():
                return None
            if time.monotonic() > deadline:
                return f"{self.link.namespace}: no result for the last goal within {RESULT_TIMEOUT_S:g} s"
            self.stop.wait(0.01)
        refused = self._refused()
        if refused is not None:
            return refused
        status = handle.get_goal_status()
        if status == GoalStatus.SUCCEEDED:
            return None
        result = handle.get_result()
        code, text = (result.error_code, result.error_string) if result is not None else ("?", "")
        return f"{self.link.namespace}: the last goal ended with status {status}, error code {code} {text}".rstrip()

    def close(self) -> None:
        self._sub.unregister()
        self._handles.clear()
        client = self._client
        for endpoint in (client.pub_goal, client.pub_cancel, client.status_sub, client.result_sub, client.feedback_sub):
            endpoint.unregister()
