"""What a ros_control joint trajectory controller does with what it is sent, as pure logic: no ROS, no clock, no I/O.

The semantics are those of ros_controllers' joint_trajectory_controller (ROS 1, noetic-devel), the controller the
arms' drivers run (docs/trajectory_controller.md lists them). The caller passes the time in (wall time, in s) with
the measured joint state; the controller answers with the desired state and with what became of its goal.

- A message's start is its stamp, or the next update (`now`) when the stamp is zero. Each point is due at the start
  plus its time_from_start; points due at or before `now` are dropped. A message with no point left (all in the past,
  or a lone point with time_from_start 0 and stamp zero) is refused and the current motion carries on; so is one
  with a point due before its start (a negative time_from_start).
- Replacement: the current trajectory is kept up to max(now, start); from there one segment bridges from its desired
  state to the first point left, then the message's points follow. A first point due exactly at a start in the
  future gets a bridge of no length: the desired state steps to it there.
- Each segment's polynomial follows what both its ends give: positions only, linear; velocities too, cubic;
  accelerations too, quintic (the current desired state gives all three).
- A message with no points means "hold"; so does cancelling the active goal. Holding starts from the measured state:
  with stop_trajectory_duration 0 the desired position jumps to the measured one; otherwise a quintic from the
  measured position and velocity comes to zero velocity after that time T, at p + 5/8·v·T (the midpoint of the
  quintic from (p, v) to (p, -v) over 2T, as ros_controllers builds it).
- A valid message on the `command` topic cancels the active goal. A new goal cancels the one before.
- Joint names: a message must name exactly the controller's joints, in any order (INVALID_JOINTS otherwise).
- Tolerances (position and velocity per joint): 0 takes the controller's default, a negative value means none. A
  path violation aborts the goal but the trajectory carries on. After the last point, the goal succeeds once every
  joint is within the goal tolerance and its velocity error within the stopped-velocity tolerance; it aborts when
  the goal time tolerance has passed first: with 0, at the first update after the last point. A goal's time
  tolerance of 0 takes the controller's default, a negative one means 0.

One concern, and a long one: every rule above acts on the one trajectory and the one goal in force, so a cut would part
a rule's halves (a replacement's bridge and the goal it ends, a hold and the cancel that asks it).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from sim.errors import SimError
from sim.geometry.trajectory import evaluate_spline, spline_coefficients

__all__ = [
    "ControllerError",
    "ErrorCode",
    "Ending",
    "JointState",
    "Point",
    "TrajectoryMessage",
    "JointTolerance",
    "GoalTolerances",
    "GoalEvent",
    "Verdict",
    "Update",
    "TrajectoryController",
]


class ControllerError(SimError, ValueError):
    """A controller setting that cannot work (no joints, a negative duration or tolerance)."""


class ErrorCode(enum.IntEnum):
    """control_msgs/FollowJointTrajectoryResult's codes."""

    SUCCESSFUL = 0
    INVALID_GOAL = -1
    INVALID_JOINTS = -2
    OLD_HEADER_TIMESTAMP = -3
    PATH_TOLERANCE_VIOLATED = -4
    GOAL_TOLERANCE_VIOLATED = -5


class Ending(enum.Enum):
    """How a goal ended, as actionlib's goal handle is told."""

    SUCCEEDED = "succeeded"
    ABORTED = "aborted"
    CANCELED = "canceled"  # cancelled by its client, or preempted by a newer goal or a command message


@dataclass(frozen=True)
class JointState:
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray

    @staticmethod
    def at_rest(positions: Sequence[float] | np.ndarray) -> JointState:
        p = np.array(positions, dtype=float)
        return JointState(p, np.zeros_like(p), np.zeros_like(p))


@dataclass(frozen=True)
class Point:
    """A trajectory point as the message gives it: velocities and accelerations may be empty (not given)."""

    time_from_start: float
    positions: Sequence[float]
    velocities: Sequence[float] = ()
    accelerations: Sequence[float] = ()


@dataclass(frozen=True)
class TrajectoryMessage:
    """trajectory_msgs/JointTrajectory: stamp in s (0: start at the next update), joint names, points."""

    stamp: float
    joint_names: Sequence[str]
    points: Sequence[Point]


@dataclass(frozen=True)
class JointTolerance:
    """control_msgs/JointTolerance: 0 takes the default, a negative value means no bound."""

    name: str
    position: float = 0.0
    velocity: float = 0.0


@dataclass(frozen=True)
class GoalTolerances:
    path: Sequence[JointTolerance] = ()
    goal: Sequence[JointTolerance] = ()
    goal_time: float = 0.0  # s after the last point; 0 takes the controller's default, < 0 means 0


@dataclass(frozen=True)
class GoalEvent:
    goal_id: str
    ending: Ending
    code: ErrorCode
    text: str


@dataclass(frozen=True)
class Verdict:
    """What became of a message: accepted or refused (with the code and why), and the goal it ended, if any."""

    accepted: bool
    code: ErrorCode = ErrorCode.SUCCESSFUL
    text: str = ""
    ended: tuple[GoalEvent, ...] = ()


@dataclass(frozen=True)
class Update:
    desired: JointState
    ended: tuple[GoalEvent, ...] = ()


@dataclass(frozen=True)
class _Segment:
    start: float
    end: float
    coeffs: np.ndarray  # (6, n), in s - start

    def sample(self, t: float) -> JointState:
        at = evaluate_spline(self.coeffs, min(max(t, self.start), self.end) - self.start)
        return JointState(at.positions, at.velocities, at.accelerations)


@dataclass(frozen=True)
class _Trajectory:
    """Segments back to back in time; before the first and after the last, the ends held at rest."""

    segments: tuple[_Segment, ...]
    rest: np.ndarray  # where it holds when there are no segments

    def sample(self, t: float) -> JointState:
        if not self.segments:
            return JointState.at_rest(self.rest)
        if t < self.segments[0].start:
            return self.segments[0].sample(t)
        for segment in self.segments:
            if t < segment.end:
                return segment.sample(t)
        return JointState.at_rest(self.segments[-1].sample(self.segments[-1].end).positions)

    @property
    def end_time(self) -> float:
        return self.segments[-1].end if self.segments else -math.inf

    def until(self, t: float) -> tuple[_Segment, ...]:
        """The segments before `t`, the one holding `t` cut there."""
        kept = []
        for segment in self.segments:
            if segment.start >= t:
                break
            kept.append(segment if segment.end <= t else _Segment(segment.start, t, segment.coeffs))
        return tuple(kept)


def _constant(positions: np.ndarray) -> np.ndarray:
    coeffs = np.zeros((6, len(positions)))
    coeffs[0] = positions
    return coeffs


def _segment(start: float, end: float, a: JointState, b: JointState, order: str) -> _Segment:
    return _Segment(
        start,
        end,
        spline_coefficients(
            a.positions, a.velocities, a.accelerations, b.positions, b.velocities, b.accelerations, end - start, order
        ),
    )


@dataclass
class _Goal:
    goal_id: str
    path_position: np.ndarray
    path_velocity: np.ndarray
    goal_position: np.ndarray
    goal_velocity: np.ndarray
    goal_time: float
    end_time: float


@dataclass(frozen=True)
class _Parsed:
    """A message's points reordered to the controller's joints: what each gives, and their absolute times."""

    times: np.ndarray
    states: list[JointState]
    orders: list[int] = field(default_factory=list)  # 1 positions, 3 with velocities, 5 with accelerations


_ORDER_NAMES = {1: "linear", 3: "cubic", 5: "quintic"}


class TrajectoryController:
    """One controller's trajectory and active goal. Not thread-safe: the caller serialises the calls."""

    def __init__(
        self,
        joint_names: Sequence[str],
        positions: Sequence[float] | np.ndarray,
        *,
        stop_trajectory_duration: float = 0.0,
        path_tolerance: Mapping[str, float] | None = None,
        goal_tolerance: Mapping[str, float] | None = None,
        stopped_velocity_tolerance: float = 0.01,
        goal_time: float = 0.0,
    ) -> None:
        self.joint_names = tuple(joint_names)
        if not self.joint_names or len(set(self.joint_names)) != len(self.joint_names):
            raise ControllerError(f"the controller needs distinct joint names, got {list(self.joint_names)}")
        start = np.array(positions, dtype=float)
        if start.shape != (len(self.joint_names),) or not np.all(np.isfinite(start)):
            raise ControllerError(f"{len(self.joint_names)} finite start positions needed, got {list(start)}")
        for name, value in (
            ("stop_trajectory_duration", stop_trajectory_duration),
            ("stopped_velocity_tolerance", stopped_velocity_tolerance),
            ("goal_time", goal_time),
        ):
            if not (math.isfinite(value) and value >= 0.0):
                raise ControllerError(f"{name} must be >= 0, got {value!r}")
        self.stop_trajectory_duration = stop_trajectory_duration
        self.stopped_velocity_tolerance = stopped_velocity_tolerance
        self.goal_time = goal_time
        self._default_path = self._per_joint(path_tolerance or {}, "path tolerance")
        self._default_goal = self._per_joint(goal_tolerance or {}, "goal tolerance")
        self._trajectory = _Trajectory((), start)
        self._goal: _Goal | None = None

    def _per_joint(self, values: Mapping[str, float], what: str) -> np.ndarray:
        unknown = set(values) - set(self.joint_names)
        if unknown:
            raise ControllerError(f"{what} for joints the controller does not have: {sorted(unknown)}")
        bounds = np.array([values.get(name, 0.0) for name in self.joint_names], dtype=float)
        if np.any(~np.isfinite(bounds) | (bounds < 0)):
            raise ControllerError(f"{what} must be >= 0 per joint (0: none), got {dict(values)}")
        return np.where(bounds > 0, bounds, np.inf)

    # --- what the controller is sent ---------------------------------------------------------------------------
    @property
    def active_goal(self) -> str | None:
        return None if self._goal is None else self._goal.goal_id

    def on_command(self, message: TrajectoryMessage, now: float, actual: JointState) -> Verdict:
        """A message on the `command` topic: a new trajectory (or hold), which cancels the active goal."""
        if not message.points:
            self._hold(now, actual)
            return Verdict(True, text="empty trajectory: holding", ended=self._end_goal(Ending.CANCELED))
        refused = self._check_joints(message) or self._replace(message, now)
        if refused is not None:
            return refused
        return Verdict(True, ended=self._end_goal(Ending.CANCELED, "preempted by a command message"))

    def on_goal(
        self, goal_id: str, message: TrajectoryMessage, tolerances: GoalTolerances, now: float, actual: JointState
    ) -> Verdict:
        """A follow_joint_trajectory goal: refused with INVALID_JOINTS or INVALID_GOAL, or accepted (the active goal,
        if any, is cancelled)."""
        refused = self._check_joints(message)
        if refused is not None:
            return refused
        try:
            goal = self._goal_bounds(goal_id, tolerances)
        except ControllerError as error:
            return Verdict(False, ErrorCode.INVALID_GOAL, str(error))
        if message.points:
            refused = self._replace(message, now)
            if refused is not None:
                return refused
        else:
            self._hold(now, actual)
        ended = self._end_goal(Ending.CANCELED, f"preempted by goal {goal_id}")
        goal.end_time = self._trajectory.end_time if message.points else now
        self._goal = goal
        return Verdict(True, ended=ended)

    def on_cancel(self, goal_id: str, now: float, actual: JointState) -> tuple[GoalEvent, ...]:
        """A client cancels `goal_id`: if it is the active goal, hold and end it cancelled."""
        if self._goal is None or self._goal.goal_id != goal_id:
            return ()
        self._hold(now, actual)
        return self._end_goal(Ending.CANCELED, "cancelled by its client")

    # --- each update -------------------------------------------------------------------------------------------
    def update(self, now: float, actual: JointState) -> Update:
        """The desired state at `now`, and the goal's end if the measured state ends it."""
        desired = self._trajectory.sample(now)
        goal = self._goal
        if goal is None:
            return Update(desired)
        error = actual.positions - desired.positions
        if now < goal.end_time:
            over = np.abs(error) > goal.path_position
            over |= np.abs(actual.velocities - desired.velocities) > goal.path_velocity
            if np.any(over):
                text = self._violations("path", over, error)
                return Update(desired, self._end_goal(Ending.ABORTED, text, ErrorCode.PATH_TOLERANCE_VIOLATED))
            return Update(desired)
        outside = np.abs(error) > goal.goal_position
        outside |= np.abs(actual.velocities - desired.velocities) > goal.goal_velocity
        if not np.any(outside):
            return Update(desired, self._end_goal(Ending.SUCCEEDED, "", ErrorCode.SUCCESSFUL))
        if now >= goal.end_time + goal.goal_time:  # ros_controllers: no time left, even with a tolerance of 0
            text = self._violations("goal", outside, error)
            return Update(desired, self._end_goal(Ending.ABORTED, text, ErrorCode.GOAL_TOLERANCE_VIOLATED))
        return Update(desired)

    def desired_at(self, t: float) -> JointState:
        """The desired state at time `t` (query_state)."""
        return self._trajectory.sample(t)

    # --- inside ------------------------------------------------------------------------------------------------
    def _check_joints(self, message: TrajectoryMessage) -> Verdict | None:
        names = list(message.joint_names)
        if sorted(names) != sorted(self.joint_names) or len(set(names)) != len(names):
            return Verdict(
                False,
                ErrorCode.INVALID_JOINTS,
                f"the trajectory's joints {names} are not the controller's {list(self.joint_names)}",
            )
        return None

    def _parse(self, message: TrajectoryMessage) -> _Parsed | Verdict:
        order = [list(message.joint_names).index(name) for name in self.joint_names]
        n = len(order)
        start = message.stamp
        times, states, orders = [], [], []
        previous = -math.inf
        for k, point in enumerate(message.points):
            if not (math.isfinite(point.time_from_start) and point.time_from_start > previous):
                return Verdict(False, ErrorCode.INVALID_GOAL, f"point {k}: time_from_start must increase")
            previous = point.time_from_start
            if len(point.positions) != n:
                return Verdict(
                    False, ErrorCode.INVALID_GOAL, f"point {k} has {len(point.positions)} positions, not {n}"
                )
            given = 1
            p = np.array(point.positions, dtype=float)[order]
            v = np.zeros(n)
            a = np.zeros(n)
            if len(point.velocities) == n:
                given, v = 3, np.array(point.velocities, dtype=float)[order]
                if len(point.accelerations) == n:
                    given, a = 5, np.array(point.accelerations, dtype=float)[order]
            elif point.velocities:
                return Verdict(False, ErrorCode.INVALID_GOAL, f"point {k} has {len(point.velocities)} velocities")
            if not (np.all(np.isfinite(p)) and np.all(np.isfinite(v)) and np.all(np.isfinite(a))):
                return Verdict(False, ErrorCode.INVALID_GOAL, f"point {k} has a value that is not finite")
            times.append(start + point.time_from_start)
            states.append(JointState(p, v, a))
            orders.append(given)
        return _Parsed(np.array(times), states, orders)

    def _replace(self, message: TrajectoryMessage, now: float) -> Verdict | None:
        start = message.stamp if message.stamp > 0 else now
        parsed = self._parse(TrajectoryMessage(start, message.joint_names, message.points))
        if isinstance(parsed, Verdict):
            return parsed
        future = [k for k, t in enumerate(parsed.times) if t > now]
        if not future:
            return Verdict(
                False,
                ErrorCode.INVALID_GOAL,
                f"every point of the trajectory is due at or before {now:.3f} s: none is left to follow",
            )
        join = max(now, start)
        if parsed.times[future[0]] < join:
            return Verdict(
                False, ErrorCode.INVALID_GOAL, f"point {future[0]} is due before the trajectory's start {join:.3f} s"
            )
        segments = list(self._trajectory.until(join))
        previous, previous_time, previous_order = self._trajectory.sample(join), join, 5
        for k in future:
            if parsed.times[k] == previous_time:  # due at a future start: a bridge of no length, a step
                segments.append(_Segment(join, join, _constant(previous.positions)))
            else:
                order = _ORDER_NAMES[min(previous_order, parsed.orders[k])]
                segments.append(_segment(previous_time, parsed.times[k], previous, parsed.states[k], order))
            previous, previous_time, previous_order = parsed.states[k], parsed.times[k], parsed.orders[k]
        self._trajectory = _Trajectory(tuple(s for s in segments if s.end > now - 1.0), previous.positions)
        return None

    def _hold(self, now: float, actual: JointState) -> None:
        duration = self.stop_trajectory_duration
        if duration <= 0:
            self._trajectory = _Trajectory((), actual.positions.copy())
            return
        # ros_controllers' stop: the quintic from (p, v, 0) to (p, -v, 0) over 2T is symmetric, so at T its velocity
        # is zero; the stop is the quintic from (p, v, 0) to that midpoint's state over T.
        here = JointState(actual.positions, actual.velocities, np.zeros_like(actual.positions))
        mirrored = JointState(actual.positions, -actual.velocities, np.zeros_like(actual.positions))
        midpoint = _segment(now, now + 2.0 * duration, here, mirrored, "quintic").sample(now + duration)
        stop = _segment(now, now + duration, here, midpoint, "quintic")
        self._trajectory = _Trajectory((stop,), midpoint.positions)

    def _goal_bounds(self, goal_id: str, tolerances: GoalTolerances) -> _Goal:
        def bounds(default: np.ndarray, given: Sequence[JointTolerance], attribute: str) -> np.ndarray:
            result = default.copy()
            for tolerance in given:
                if tolerance.name not in self.joint_names:
                    raise ControllerError(f"a tolerance names {tolerance.name!r}, not a joint of the controller")
                value = getattr(tolerance, attribute)
                if value > 0:
                    result[self.joint_names.index(tolerance.name)] = value
                elif value < 0:
                    result[self.joint_names.index(tolerance.name)] = np.inf
            return result

        unbounded = np.full(len(self.joint_names), np.inf)
        stopped = np.full(len(self.joint_names), self.stopped_velocity_tolerance or np.inf)
        return _Goal(
            goal_id,
            bounds(self._default_path, tolerances.path, "position"),
            bounds(unbounded, tolerances.path, "velocity"),
            bounds(self._default_goal, tolerances.goal, "position"),
            bounds(stopped, tolerances.goal, "velocity"),
            tolerances.goal_time if tolerances.goal_time > 0 else (0.0 if tolerances.goal_time < 0 else self.goal_time),
            math.inf,
        )

    def _violations(self, kind: str, over: np.ndarray, error: np.ndarray) -> str:
        return f"{kind} tolerance violated: " + ", ".join(
            f"{self.joint_names[j]} off by {error[j]:+.4f}" for j in np.flatnonzero(over)
        )

    def _end_goal(
        self, ending: Ending, text: str = "", code: ErrorCode = ErrorCode.SUCCESSFUL
    ) -> tuple[GoalEvent, ...]:
        if self._goal is None:
            return ()
        event = GoalEvent(self._goal.goal_id, ending, code, text)
        self._goal = None
        return (event,)
