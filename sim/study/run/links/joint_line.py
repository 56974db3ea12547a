"""A move to a path's start as a geometry to brake along: the straight line in joint space that the move's quintic
follows (sim.control.scenarios.approach), parametrised by its length in joint space (rad). Pure.

It answers what sim.study.safety.braking's `brake` asks of a path (project, joints, world, length), so a move is
stopped like an approach: along its own line, continuous in position, velocity and acceleration, at MOVE_DECELERATION
and MOVE_JERK (along the line's parameter, the norm of the joints' motion: every joint decelerates at most that). A
move has no Cartesian path of its own to plan on: its world positions are unknown (NaN).

Its speed and separation monitoring (sim.study.safety.separation) takes the move's own samples as the plan: their
planned distances to the hand over their travel along the line, which its braking's deceleration and jerk are along
(`travel`).
"""

from __future__ import annotations

import numpy as np

from sim.study.run.errors import RunError
from sim.study.safety.braking import PathState
from sim.study.safety.separation import PlannedTravel

__all__ = ["MOVE_DECELERATION", "MOVE_JERK", "JointLine"]

MOVE_DECELERATION = 1.0  # rad/s² along the line: well within every supported arm's joint limits (Panda: ≥ 7.5)
MOVE_JERK = 20.0  # rad/s³ along the line (Panda: ≥ 3750)


class JointLine:
    def __init__(self, start: np.ndarray, end: np.ndarray) -> None:
        self.start = np.asarray(start, dtype=float)
        delta = np.asarray(end, dtype=float) - self.start
        self.length = float(np.linalg.norm(delta))
        if self.length <= 1e-9:
            raise RunError("a move of no length has nothing to brake along")
        self.direction = delta / self.length

    @property
    def dof(self) -> int:
        return len(self.start)

    def joints(self, s: np.ndarray | float, derivative: int = 0) -> np.ndarray:
        along = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        if derivative == 0:
            return np.asarray(self.start + np.multiply.outer(along, self.direction))
        if derivative == 1:
            return np.broadcast_to(self.direction, (*along.shape, self.dof)).copy()
        return np.zeros((*along.shape, self.dof))

    def world(self, s: np.ndarray | float) -> np.ndarray:
        return np.full((*np.shape(s), 3), np.nan)

    def project(self, positions: np.ndarray, velocities: np.ndarray, accelerations: np.ndarray) -> PathState:
        """The line's state that best explains a joint state (least squares along the line)."""
        s = float(np.clip((np.asarray(positions, dtype=float) - self.start) @ self.direction, 0.0, self.length))
        return PathState(s, float(velocities @ self.direction), float(accelerations @ self.direction))

    def travel(self, positions: np.ndarray, velocities: np.ndarray, dt: float, distances: np.ndarray) -> PlannedTravel:
        """The move's samples (every `dt` s from its start, at rest) as the separation monitor's plan: their planned
        `distances` to the hand (m) over their travel along the line (rad) and its speed (rad/s), the units of the
        move's braking (MOVE_DECELERATION, MOVE_JERK)."""
        q, qd = np.asarray(positions, dtype=float), np.asarray(velocities, dtype=float)
        along = np.maximum.accumulate(np.clip((q - self.start) @ self.direction, 0.0, self.length))  # rounding only
        return PlannedTravel(np.arange(len(q)) * dt, np.asarray(distances, dtype=float), along, qd @ self.direction)
