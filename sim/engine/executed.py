"""What a ros_control trajectory controller executes, from what it was sent: pure logic, no ROS, no I/O.

Every goal and cancel a controller heard, with its arrival (wall time, s), replayed through ros_control's semantics
(sim.engine.trajectory_controller, the stand-in's own) with the arm on its desired state, sampled every `step` s as a
real arm's controller runs (1 kHz). A bridge the controller makes from a late replacement, or a hold's step, shows
in the executed accelerations and jerks; the goals as sent do not show them. The benches and the tests replay with it.

    events = [Heard(arrival, "goal", goal_id, trajectory_from_message(m.goal.trajectory)), Heard(t, "cancel", id)]
    extremes = executed_extremes(events, joint_names, start, until, acceleration_limits, jerk_limits, since=t)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.engine.trajectory_controller import GoalTolerances, JointState, TrajectoryController, TrajectoryMessage

__all__ = ["Heard", "Executed", "executed_extremes"]

STEP = 0.001  # s: a real arm's controller updates at 1 kHz


@dataclass(frozen=True)
class Heard:
    """A goal (its trajectory) or a cancel, as the controller heard it at `arrival`."""

    arrival: float
    kind: str  # "goal" or "cancel"
    goal_id: str
    trajectory: TrajectoryMessage | None = None  # a goal's


@dataclass(frozen=True)
class Executed:
    """The largest executed acceleration and jerk, each as a fraction of its joint's limit, which joint (1-based),
    when (s after the first event), and one line saying so."""

    acceleration: float
    acceleration_joint: int
    acceleration_at: float
    jerk: float
    jerk_joint: int
    jerk_at: float

    def describe(self) -> str:
        return (
            f"acceleration {self.acceleration:.0%} of joint {self.acceleration_joint}'s limit at "
            f"{self.acceleration_at:.3f} s, jerk {self.jerk:.0%} of joint {self.jerk_joint}'s at {self.jerk_at:.3f} s"
        )


def executed_extremes(
    events: Sequence[Heard],
    joint_names: Sequence[str],
    start: np.ndarray,
    until: float,
    acceleration_limits: Sequence[float],
    jerk_limits: Sequence[float],
    stop_trajectory_duration: float = 0.0,
    step: float = STEP,
    since: float = -np.inf,
) -> Executed:
    """The executed motion from the first event to `until`, the arm resting at `start` before it; its extremes from
    wall time `since` on (what came before is replayed, not counted). ValueError when nothing was heard (nothing to
    replay) or nothing is left to count."""
    events = sorted(events, key=lambda event: event.arrival)
    if not events:
        raise ValueError("no goal reached the controller")
    dof = len(joint_names)
    controller = TrajectoryController(joint_names, start, stop_trajectory_duration=stop_trajectory_duration)
    times = np.arange(events[0].arrival, max(until, events[0].arrival + 2 * step), step)
    accelerations = np.zeros((len(times), dof))
    velocities = np.zeros((len(times), dof))
    k = 0
    for index, now in enumerate(times):
        while k < len(events) and events[k].arrival <= now:
            event = events[k]
            desired = controller.desired_at(event.arrival)
            actual = JointState(desired.positions, desired.velocities, np.zeros(dof))
            if event.kind == "goal" and event.trajectory is not None:
                controller.on_goal(event.goal_id, event.trajectory, GoalTolerances(), event.arrival, actual)
            elif event.kind == "cancel":
                controller.on_cancel(event.goal_id, event.arrival, actual)
            k += 1
        desired = controller.desired_at(now)
        controller.update(now, JointState(desired.positions, desired.velocities, np.zeros(dof)))
        accelerations[index] = desired.accelerations
        velocities[index] = desired.velocities
    counted = times >= since
    if counted.sum() < 2:
        raise ValueError("fewer than two samples from `since` to `until`")
    # A step in the desired velocity (a hold from the measured state) has no acceleration of its own in the desired
    # state: the velocity's change over a step shows it, and the larger of the two is what the arm is asked for.
    stepped = np.vstack([accelerations[:1], np.diff(velocities, axis=0) / step])
    accelerations = np.where(np.abs(stepped) > np.abs(accelerations), stepped, accelerations)
    jerks = np.diff(accelerations, axis=0) / step  # the jerk into each sample from the one before
    acceleration = np.abs(accelerations[counted]) / np.asarray(acceleration_limits, dtype=float)
    jerk = np.abs(jerks[counted[1:]]) / np.asarray(jerk_limits, dtype=float)
    worst_a = np.unravel_index(int(np.argmax(acceleration)), acceleration.shape)
    worst_j = np.unravel_index(int(np.argmax(jerk)), jerk.shape)
    return Executed(
        float(acceleration[worst_a]),
        int(worst_a[1]) + 1,
        float(times[counted][worst_a[0]] - times[0]),
        float(jerk[worst_j]),
        int(worst_j[1]) + 1,
        float(times[1:][counted[1:]][worst_j[0]] - times[0]),
    )
