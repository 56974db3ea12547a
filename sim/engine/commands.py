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

__all__ = ["Target", "CommandBuffer", "command_is_due"]


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

    def wait_for_stamp(
        self, stamp: float, timeout: float, received_after: int = -1, tolerance: float = STAMP_TOLERANCE_S
    ) -> bool:
        """Block until a command stamped >= `stamp` is stored, the `received_after`-th or later (or `timeout`
        passes). A count skips a stale command, e.g. one stamped late in a run before /clock restarted at 0."""
        with self._changed:
            return self._changed.wait_for(
                lambda: self.received > received_after and self._stamp is not None and self._stamp >= stamp - tolerance,
                timeout,
            )

    def target_at(self, t: float) -> Target:
        with self._lock:
            if self._stamp is None:
                return Target(self._positions.copy(), self._velocities.copy())
            ahead = float(np.clip(t - self._stamp, -self.max_extrapolation_s, self.max_extrapolation_s))
            if abs(ahead) <= self.stamp_tolerance_s:
                ahead = 0.0  # stamped for t: ROS stamps are whole ns, so "exactly t" arrives as t ± 1 ns
            return Target(self._positions + self._velocities * ahead, self._velocities.copy())


def command_is_due(
    newest_stamp: float | None, step_end: float, dt: float, streaming: bool, first_after_anchor: bool
) -> bool:
    """Whether a clock-driven step ending at `step_end` should wait (briefly) for a command stamped at its end.

    A lockstep controller publishes each step's command before the step's /clock tick, but on two topics, over two
    connections: the tick can win the race. So the step waits when its command is not here yet and either
    - this is the first step after the grid was (re)anchored: a lockstep controller's first command is on its way,
      and it is what tells the engine that the controller streams per step; or
    - the controller `streaming` (a command stamped at a step's end has arrived before) sent the previous
      step's command, and so will send this one.
    A controller that stamps its commands with its current time (one step behind) never counts as streaming, so
    it costs one wait after an anchor and none after."""
    if newest_stamp is not None and abs(newest_stamp - step_end) < STAMP_TOLERANCE_S:
        return False
    if first_after_anchor:
        return True
    return streaming and newest_stamp is not None and abs(newest_stamp - (step_end - dt)) < STAMP_TOLERANCE_S
