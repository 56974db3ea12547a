"""The physics node as a real arm's driver shows itself under ROS 1: a ros_control joint trajectory controller, on wall
time. rospy and actionlib; the semantics are sim.engine.trajectory_controller's.

Under its namespace `<ns>` (e.g. /panda/position_joint_trajectory_controller) it offers what the arms' drivers offer:
- `<ns>/follow_joint_trajectory`: the control_msgs/FollowJointTrajectory action (actionlib's ActionServer);
- `<ns>/command`: trajectory_msgs/JointTrajectory, which cancels the active goal;
- `<ns>/state`: control_msgs/JointTrajectoryControllerState (desired, actual, error);
- `<ns>/query_state`: control_msgs/QueryTrajectoryState, the desired state at a time;
and publishes sensor_msgs/JointState on the joint-states topic at the driver's rate. Each physics step of dt ends on
the wall clock (the time rospy stamps with when no /clock runs); the step's target is the controller's desired state
at its end, with its velocity as feed-forward, as the engine's stream does.

Why the physics node and not the engine stand-in: actionlib's server is a rospy library, and the stand-in knows ROS
only through the endpoint, as Unity does; a real arm's driver is itself a ROS node on the robot's side.

Locks: actionlib calls the goal and cancel callbacks holding its own lock, and a goal handle's methods take it. So the
one order is actionlib's lock, then the controller's: the stepping loop and the command topic collect the goals that
ended under the controller's lock and tell their handles after releasing it; the goal callback, which holds
actionlib's lock already, accepts its goal under the controller's, so the loop never ends a goal not yet accepted.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import actionlib
import numpy as np
import rospy
from sensor_msgs.msg import JointState as JointStateMsg
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from sim.engine.physics import PhysicsWorld
from sim.engine.trajectory_controller import (
    Ending,
    GoalEvent,
    GoalTolerances,
    JointState,
    JointTolerance,
    Point,
    TrajectoryController,
    TrajectoryMessage,
)
from sim.robots import RobotSpec
from sim.wire.control_types import control_types

__all__ = ["TrajectoryServerOptions", "TrajectoryServer", "trajectory_from_message"]

log = logging.getLogger(__name__)

MAX_LATENESS_S = 1.0  # a step this late (a stalled machine) re-anchors the steps on now instead of catching up


@dataclass(frozen=True)
class TrajectoryServerOptions:
    namespace: str  # the controller's, e.g. /panda/position_joint_trajectory_controller
    joint_states_topic: str
    joint_states_rate: float = 50.0  # Hz, at most one per physics step
    stop_trajectory_duration: float = 0.0  # s; 0 holds the measured position at once (franka's default)
    goal_time: float = 0.5  # s after the last point a goal may take to be within its tolerance (franka's config)


def trajectory_from_message(message: Any) -> TrajectoryMessage:
    """A trajectory_msgs/JointTrajectory (rospy's class or a generated one) as the controller reads it."""
    return TrajectoryMessage(
        message.header.stamp.to_sec(),
        tuple(message.joint_names),
        tuple(
            Point(
                point.time_from_start.to_sec(),
                tuple(point.positions),
                tuple(point.velocities),
                tuple(point.accelerations),
            )
            for point in message.points
        ),
    )


def _tolerances(goal: Any) -> GoalTolerances:
    def joints(given: Iterable[Any]) -> tuple[JointTolerance, ...]:
        return tuple(JointTolerance(item.name, item.position, item.velocity) for item in given)

    return GoalTolerances(joints(goal.path_tolerance), joints(goal.goal_tolerance), goal.goal_time_tolerance.to_sec())


def _point(positions: np.ndarray, velocities: np.ndarray, accelerations: np.ndarray | None = None) -> Any:
    point = JointTrajectoryPoint()
    point.positions = positions.tolist()
    point.velocities = velocities.tolist()
    if accelerations is not None:
        point.accelerations = accelerations.tolist()
    return point


class TrajectoryServer:
    """The controller's ROS interface around one physics world; `run` steps it on the wall clock."""

    def __init__(self, robot: RobotSpec, world: PhysicsWorld, options: TrajectoryServerOptions) -> None:
        if not (math.isfinite(options.joint_states_rate) and options.joint_states_rate > 0):
            raise ValueError(f"the joint-states rate must be > 0 Hz, got {options.joint_states_rate}")
        self.robot = robot
        self.world = world
        self.options = options
        self.types = control_types()
        state = world.state()
        self.controller = TrajectoryController(
            robot.joint_names,
            state.positions,
            stop_trajectory_duration=options.stop_trajectory_duration,
            goal_time=options.goal_time,
        )
        self.steps = 0
        self._measured = JointState(state.positions.copy(), state.velocities.copy(), np.zeros(robot.dof))
        self._efforts = np.zeros(robot.dof)
        self._handles: dict[str, Any] = {}  # the goal handles not yet ended, by goal id
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._seq = 0
        ns = options.namespace.rstrip("/")
        self._joint_states = rospy.Publisher(options.joint_states_topic, JointStateMsg, queue_size=100)
        self._state = rospy.Publisher(f"{ns}/state", self.types.controller_state, queue_size=10)
        self._command = rospy.Subscriber(f"{ns}/command", JointTrajectory, self._on_command, queue_size=10)
        self._query = rospy.Service(f"{ns}/query_state", self.types.query_state, self._on_query)
        self._server = actionlib.ActionServer(
            f"{ns}/follow_joint_trajectory", self.types.action, self._on_goal, self._on_cancel, auto_start=False
        )
        self._server.start()

    # --- rospy's threads ---------------------------------------------------------------------------------------
    def _on_command(self, message: Any) -> None:
        with self._lock:
            verdict = self.controller.on_command(trajectory_from_message(message), time.time(), self._measured)
            ended = self._take_handles(verdict.ended)
        if not verdict.accepted:
            log.warning("%s/command: trajectory ignored: %s", self.options.namespace, verdict.text)
        self._tell(ended)

    def _on_goal(self, handle: Any) -> None:
        goal = handle.get_goal()
        goal_id = handle.get_goal_id().id
        # actionlib holds its lock here already, so telling handles under ours keeps the one order (actionlib's,
        # then ours); and the stepping loop cannot end the goal before it has been accepted.
        with self._lock:
            verdict = self.controller.on_goal(
                goal_id, trajectory_from_message(goal.trajectory), _tolerances(goal), time.time(), self._measured
            )
            self._tell(self._take_handles(verdict.ended))
            if verdict.accepted:
                handle.set_accepted()
                self._handles[goal_id] = handle
        if not verdict.accepted:
            log.warning("goal %s rejected: %s", goal_id, verdict.text)
            result = self.types.result(error_code=int(verdict.code), error_string=verdict.text)
            handle.set_rejected(result, verdict.text)

    def _on_cancel(self, handle: Any) -> None:
        with self._lock:
            ended = self._take_handles(self.controller.on_cancel(handle.get_goal_id().id, time.time(), self._measured))
        self._tell(ended)

    def _on_query(self, request: Any) -> Any:
        with self._lock:
            desired = self.controller.desired_at(request.time.to_sec())
        return self.types.query_state_response(
            name=list(self.robot.joint_names),
            position=desired.positions.tolist(),
            velocity=desired.velocities.tolist(),
            acceleration=desired.accelerations.tolist(),
        )

    # --- goal handles ------------------------------------------------------------------------------------------
    def _take_handles(self, events: tuple[GoalEvent, ...]) -> list[tuple[Any, GoalEvent]]:
        """The handles of the goals `events` end, removed (under the lock: each goal ends once)."""
        return [(self._handles.pop(event.goal_id), event) for event in events if event.goal_id in self._handles]

    def _tell(self, ended: list[tuple[Any, GoalEvent]]) -> None:
        for handle, event in ended:
            result = self.types.result(error_code=int(event.code), error_string=event.text)
            if event.ending is Ending.SUCCEEDED:
                handle.set_succeeded(result, event.text)
            elif event.ending is Ending.ABORTED:
                log.warning("goal %s aborted: %s", event.goal_id, event.text)
                handle.set_aborted(result, event.text)
            else:
                handle.set_canceled(result, event.text)

    # --- the steps ---------------------------------------------------------------------------------------------
    def run(self, duration_s: float | None = None) -> None:
        """Step the physics every dt of wall time until `stop()` (or for `duration_s`)."""
        dt = self.world.dt
        publish_every = 1.0 / self.options.joint_states_rate
        started = anchor = time.time()
        k = 0
        next_publish = anchor
        while not self._stop.is_set() and (duration_s is None or time.time() - started < duration_s):
            k += 1
            step_end = anchor + k * dt
            delay = step_end - time.time()
            if delay > 0 and self._stop.wait(delay):
                return
            if time.time() - step_end > MAX_LATENESS_S:
                log.warning("the steps fell %.3f s behind the wall clock: resumed from now", time.time() - step_end)
                anchor, k = time.time(), 0
                continue
            with self._lock:
                update = self.controller.update(step_end, self._measured)
                ended = self._take_handles(update.ended)
                active = self._handles.get(self.controller.active_goal or "")
            self.world.set_targets(update.desired.positions, update.desired.velocities)
            sample = self.world.step()
            self.steps += 1
            measured = JointState(sample.positions.copy(), sample.velocities.copy(), np.zeros(self.robot.dof))
            with self._lock:
                self._measured = measured
            self._tell(ended)
            if step_end >= next_publish - 1e-9:
                next_publish = max(next_publish + publish_every, step_end + 0.5 * publish_every)
                self._publish(step_end, update.desired, measured, sample.efforts, active)

    def _publish(
        self, stamp: float, desired: JointState, measured: JointState, efforts: np.ndarray, active: Any
    ) -> None:
        ros_stamp = rospy.Time.from_sec(stamp)
        self._seq += 1
        joint_state = JointStateMsg()
        joint_state.header.seq = self._seq
        joint_state.header.stamp = ros_stamp
        joint_state.name = list(self.robot.joint_names)
        joint_state.position = measured.positions.tolist()
        joint_state.velocity = measured.velocities.tolist()
        joint_state.effort = np.asarray(efforts, dtype=float).tolist()
        self._joint_states.publish(joint_state)
        state = self.types.controller_state()
        state.header.stamp = ros_stamp
        state.joint_names = list(self.robot.joint_names)
        state.desired = _point(desired.positions, desired.velocities, desired.accelerations)
        state.actual = _point(measured.positions, measured.velocities)
        state.error = _point(desired.positions - measured.positions, desired.velocities - measured.velocities)
        self._state.publish(state)
        if active is not None:
            feedback = self.types.feedback(
                header=state.header,
                joint_names=state.joint_names,
                desired=state.desired,
                actual=state.actual,
                error=state.error,
            )
            active.publish_feedback(feedback)

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        self.stop()
        self._command.unregister()
        self._query.shutdown()
        self._joint_states.unregister()
        self._state.unregister()
