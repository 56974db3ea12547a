"""What the trajectory-controller link sends and measures, without ROS: an approach as one goal's points (positions,
velocities, accelerations, their times from the start), the path the arm was commanded along (the approach, then
from a replacement's start the braking), the tracking error against it, and when the achieved speed first fell after
a press. Pure."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.study.run.errors import RunError

__all__ = ["GoalPoints", "goal_points", "CommandedPath", "speed_fell", "GOAL_STATUS"]

# actionlib_msgs/GoalStatus's codes, by name for the records
GOAL_STATUS = {
    0: "PENDING",
    1: "ACTIVE",
    2: "PREEMPTED",
    3: "SUCCEEDED",
    4: "ABORTED",
    5: "REJECTED",
    6: "PREEMPTING",
    7: "RECALLING",
    8: "RECALLED",
    9: "LOST",
}


@dataclass(frozen=True)
class GoalPoints:
    """A trajectory's points after its start: `times` s from the start (all > 0), and per point the joints'."""

    times: np.ndarray  # (M,)
    positions: np.ndarray  # (M, dof)
    velocities: np.ndarray  # (M, dof)
    accelerations: np.ndarray  # (M, dof)

    @property
    def duration(self) -> float:
        return float(self.times[-1])


def goal_points(positions: np.ndarray, velocities: np.ndarray, dt: float, speed_scale: float = 1.0) -> GoalPoints:
    """Samples every `dt` from the first (the start, at rest: not sent, as a controller drops a point at its start)
    as a goal's points, the accelerations from the velocities. `speed_scale` < 1 (the rehearsal) slows the motion down
    along the same path: times / scale, velocities · scale, accelerations · scale²."""
    q = np.asarray(positions, dtype=float)
    v = np.asarray(velocities, dtype=float)
    if q.ndim != 2 or q.shape != v.shape or len(q) < 2:
        raise RunError(f"a goal needs at least 2 samples of positions and velocities alike, got {q.shape}, {v.shape}")
    if not (math.isfinite(dt) and dt > 0 and math.isfinite(speed_scale) and 0 < speed_scale <= 1):
        raise RunError(f"a goal's step must be > 0 s and its speed scale in (0, 1], got {dt!r} and {speed_scale!r}")
    a = np.gradient(v, dt, axis=0)
    a[0] = a[-1] = 0.0  # rest to rest
    times = np.arange(len(q)) * dt / speed_scale
    return GoalPoints(times[1:], q[1:], v[1:] * speed_scale, a[1:] * speed_scale**2)


@dataclass
class CommandedPath:
    """What the arm was commanded along, on the link's clock: segments of (start, times from it, positions,
    velocities, accelerations), each in force from its start on (a replacement keeps the trajectory before its own
    start). Its state at a time is what the controller's desired state is then, as far as the link knows: the stop
    brakes from it where the controller cannot be asked."""

    segments: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)

    def add(
        self,
        start: float,
        times: np.ndarray,
        positions: np.ndarray,
        velocities: np.ndarray | None = None,
        accelerations: np.ndarray | None = None,
    ) -> None:
        """A trajectory starting at `start` (its samples at `times`, 0 its first, from its start); velocities and
        accelerations zero where not given (a hold)."""
        q = np.asarray(positions, dtype=float)
        qd = np.zeros_like(q) if velocities is None else np.asarray(velocities, dtype=float)
        qdd = np.zeros_like(q) if accelerations is None else np.asarray(accelerations, dtype=float)
        self.segments.append((float(start), np.asarray(times, dtype=float), q, qd, qdd))

    def discard_last(self) -> None:
        """Forget the last segment: the controller refused it, so the arm was never commanded along it."""
        if not self.segments:
            raise RunError("nothing was commanded")
        self.segments.pop()

    def _segment(self, when: float) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        if not self.segments:
            raise RunError("nothing was commanded")
        chosen = self.segments[0]
        for segment in self.segments:
            if segment[0] <= when:
                chosen = segment
        return chosen

    def at(self, when: float) -> np.ndarray:
        """The commanded joint positions at `when` (before the first segment: its first sample; after the last
        sample of a segment: held there)."""
        start, times, positions, _, _ = self._segment(when)
        return _interpolate(when - start, times, positions)

    def state(self, when: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The commanded positions, velocities and accelerations at `when`, linear between samples; held at rest
        after the last."""
        start, times, positions, velocities, accelerations = self._segment(when)
        t = when - start
        q = _interpolate(t, times, positions)
        if t >= times[-1]:  # held at the last sample
            return q, np.zeros_like(q), np.zeros_like(q)
        return q, _interpolate(t, times, velocities), _interpolate(t, times, accelerations)

    def possible(self, when: float, last_unsure: bool = False) -> list[np.ndarray]:
        """The commanded positions at `when`; `last_unsure`: the controller has not yet said whether it took the last
        segment (a stop on its way), so with it and without it."""
        positions = [self.at(when)]
        if last_unsure and len(self.segments) > 1:
            last = self.segments.pop()
            try:
                positions.append(self.at(when))
            finally:
                self.segments.append(last)
        return positions

    def error(self, when: float, achieved: np.ndarray, last_unsure: bool = False) -> float:
        """rad: the largest joint error of `achieved` against the commanded positions at `when` (the smaller of the
        two possible ones, `last_unsure`)."""
        achieved = np.asarray(achieved, dtype=float)
        return min(float(np.max(np.abs(achieved - q))) for q in self.possible(when, last_unsure))


def _interpolate(t: float, times: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.array([np.interp(t, times, values[:, j]) for j in range(values.shape[1])])


def speed_fell(stamps: np.ndarray, speeds: np.ndarray, press: float, fall: float = 0.01, floor: float = 1e-3) -> float:
    """s from `press` to the first achieved state stamped after it whose joint speed (the norm of the joints'
    velocities) is below that of the last state at or before it by more than `fall` of it (at least `floor` rad/s);
    NaN when none is (the arm was at rest, or never slowed)."""
    t = np.asarray(stamps, dtype=float)
    v = np.asarray(speeds, dtype=float)
    before = np.flatnonzero(t <= press)
    if len(before) == 0:
        return math.nan
    reference = v[before[-1]]
    drop = max(fall * reference, floor)
    for k in range(before[-1] + 1, len(t)):
        if v[k] < reference - drop:
            return float(t[k] - press)
    return math.nan
