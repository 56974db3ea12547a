"""What the engine drives toward at the end of each step. Pure logic, no I/O.

Rule: the target for a step ending at time t is the newest command, extrapolated along its velocity from its
stamp to t (at most `max_extrapolation_s`, so a controller that stops does not send the robot drifting away).
Joints a command does not name keep their previous target. With the commander's lockstep stream the command for
a step is stamped exactly at the step's end, and the extrapolation term is zero.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from sim.wire.contract import STAMP_TOLERANCE_S
from sim.wire.rosmsgs import TrajectoryCommand

__all__ = ["Target", "CommandBuffer"]


@dataclass(frozen=True)
class Target:
    positions: np.ndarray
    velocities: np.ndarray


class CommandBuffer:
    """Thread-safe: the TCP reader stores commands, the stepping loop reads targets."""

    def __init__(
        self,
        initial_positions: np.ndarray,
        max_extrapolation_s: float = 0.1,
        stamp_tolerance_s: float = STAMP_TOLERANCE_S,
    ) -> None:
        self._positions = np.array(initial_positions, dtype=float)
        self._velocities = np.zeros_like(self._positions)
        self._stamp: float | None = None
        self.max_extrapolation_s = max_extrapolation_s
        self.stamp_tolerance_s = stamp_tolerance_s  # a command this close to t is the command for t (no extrapolation)
        self.received = 0
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)

    def store(self, command: TrajectoryCommand) -> None:
        with self._changed:
            named = np.isfinite(command.positions)
            self._positions[named] = command.positions[named]
            velocities = np.zeros_like(self._positions)
            if command.velocities is not None:
                given = np.isfinite(command.velocities)
                velocities[given] = command.velocities[given]
            self._velocities = np.where(named, velocities, 0.0)
            self._stamp = command.stamp_s if command.stamp_s > 0 else None
            self.received += 1
            self._changed.notify_all()

    @property
    def newest_stamp(self) -> float | None:
        with self._lock:
            return self._stamp

    def wait_for_stamp(self, stamp: float, timeout: float, tolerance: float = STAMP_TOLERANCE_S) -> bool:
        """Block until a command stamped >= `stamp` is stored (or `timeout` passes)."""
        with self._changed:
            return self._changed.wait_for(lambda: self._stamp is not None and self._stamp >= stamp - tolerance, timeout)

    def target_at(self, t: float) -> Target:
        with self._lock:
            if self._stamp is None:
                return Target(self._positions.copy(), self._velocities.copy())
            ahead = float(np.clip(t - self._stamp, -self.max_extrapolation_s, self.max_extrapolation_s))
            if abs(ahead) <= self.stamp_tolerance_s:
                ahead = 0.0  # stamped for t: ROS stamps are whole ns, so "exactly t" arrives as t ± 1 ns
            return Target(self._positions + self._velocities * ahead, self._velocities.copy())
