"""What the controller streams: an optional approach from where the robot is to the motion's start, then the
motion (`Schedule`). Pure logic."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.control.scenarios.defaults import APPROACH_MIN_S, APPROACH_SPEED_FRACTION
from sim.control.scenarios.motion import Motion, checked_vector, sample_times, sample_trajectory
from sim.geometry.trajectory import PolynomialTrajectory
from sim.robots import RobotSpec

__all__ = ["approach", "Schedule", "build_schedule"]


def approach(
    robot: RobotSpec, q_from: np.ndarray, q_to: np.ndarray, dt: float, min_time: float = APPROACH_MIN_S
) -> tuple[np.ndarray, np.ndarray]:
    """A quintic from rest at q_from to rest at q_to, sampled at dt (first sample q_from, last q_to).

    Its length is at least `min_time` and long enough that no joint exceeds APPROACH_SPEED_FRACTION of its
    velocity limit (a quintic peaks at 1.875·Δ/T). Returns (positions, velocities), each (M+1, n).
    """
    q_from = checked_vector(q_from, robot.dof, "approach start")
    q_to = checked_vector(q_to, robot.dof, "approach end")
    needed = float(np.max(1.875 * np.abs(q_to - q_from) / (APPROACH_SPEED_FRACTION * robot.max_velocity)))
    duration = max(min_time, needed)
    times = sample_times(duration, dt)
    traj = PolynomialTrajectory([0.0, times[-1]], np.array([q_from, q_to]), order="quintic")
    return sample_trajectory(traj, times)


@dataclass
class Schedule:
    """What the commander streams: an optional approach from the robot's current state, then the motion.

    Sample i is for the end of step i (sample 0 = where the robot is at the start). `motion_index[i]` is the
    index of the motion sample, or -1 during the approach.
    """

    positions: np.ndarray  # (M, n)
    velocities: np.ndarray  # (M, n)
    motion_index: np.ndarray  # (M,) int

    @property
    def approach_steps(self) -> int:
        """Index of the motion's first sample in the schedule (= approach length in steps)."""
        return int(np.argmax(self.motion_index >= 0))


def build_schedule(
    motion: Motion, q_start: np.ndarray | None = None, approach_min_s: float = APPROACH_MIN_S
) -> Schedule:
    """The motion, preceded by a quintic approach from `q_start` to its first sample if they differ by more than
    1e-4 (rad or m) and the approach is enabled (`approach_min_s` > 0, `q_start` given)."""
    index = np.arange(len(motion.times))
    if q_start is None or approach_min_s <= 0:
        return Schedule(motion.positions, motion.velocities, index)
    q_start = checked_vector(q_start, motion.robot.dof, "start state")
    if np.max(np.abs(q_start - motion.positions[0])) <= 1e-4:
        return Schedule(motion.positions, motion.velocities, index)
    positions, velocities = approach(motion.robot, q_start, motion.positions[0], motion.dt, approach_min_s)
    return Schedule(
        np.concatenate([positions[:-1], motion.positions]),
        np.concatenate([velocities[:-1], motion.velocities]),
        np.concatenate([np.full(len(positions) - 1, -1), index]),
    )
