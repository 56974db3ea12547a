"""Piecewise polynomial trajectories through waypoints, like Simulink's Polynomial Trajectory block. Pure numpy.

Between consecutive waypoints (t_k, p_k) → (t_k+1, p_k+1) a cubic matches positions and velocities, a quintic
also matches accelerations (always zero at the waypoints here). `spline_coefficients` is the one segment rule, for
any boundary states (the trajectory controller's segments use it too). Velocities at the waypoints are zero unless
given. Works for any dimension: joint space (n joints) or Cartesian (x, y, z). Outside [t0, tN] the trajectory
holds its first / last waypoint with zero velocity and acceleration.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.errors import SimError

__all__ = [
    "ORDERS",
    "TrajectoryError",
    "TrajectorySample",
    "PolynomialTrajectory",
    "spline_coefficients",
    "evaluate_spline",
]

ORDERS = ("cubic", "quintic")


class TrajectoryError(SimError, ValueError):
    """Invalid times, waypoints, velocities or order."""


@dataclass(frozen=True)
class TrajectorySample:
    positions: np.ndarray  # (dim,) for a scalar t, (len(t), dim) for an array of t
    velocities: np.ndarray
    accelerations: np.ndarray


def spline_coefficients(
    p0: np.ndarray,
    v0: np.ndarray,
    a0: np.ndarray,
    p1: np.ndarray,
    v1: np.ndarray,
    a1: np.ndarray,
    h: np.ndarray | float,
    order: str,
) -> np.ndarray:
    """Coefficients c[k] of p(s) = Σ c[k] s^k, s from 0 to h, that join (p0, v0, a0) to (p1, v1, a1): "linear"
    uses the positions alone, "cubic" the velocities too, "quintic" the accelerations too (unused orders are 0).
    Shapes broadcast: states (..., dim) and h (...) or a float give (..., 6, dim)."""
    p0, v0, a0, p1, v1, a1 = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (p0, v0, a0, p1, v1, a1)))
    h = np.asarray(h, dtype=float)[..., None] if np.ndim(h) else float(h)
    dp = p1 - p0
    coeffs = np.zeros(p0.shape[:-1] + (6, p0.shape[-1]))
    coeffs[..., 0, :] = p0
    if order == "linear":
        coeffs[..., 1, :] = dp / h
    elif order == "cubic":
        coeffs[..., 1, :] = v0
        coeffs[..., 2, :] = (3.0 * dp - (2.0 * v0 + v1) * h) / h**2
        coeffs[..., 3, :] = (-2.0 * dp + (v0 + v1) * h) / h**3
    elif order == "quintic":
        coeffs[..., 1, :] = v0
        coeffs[..., 2, :] = 0.5 * a0
        coeffs[..., 3, :] = (20.0 * dp - (8.0 * v1 + 12.0 * v0) * h - (3.0 * a0 - a1) * h**2) / (2.0 * h**3)
        coeffs[..., 4, :] = (-30.0 * dp + (14.0 * v1 + 16.0 * v0) * h + (3.0 * a0 - 2.0 * a1) * h**2) / (2.0 * h**4)
        coeffs[..., 5, :] = (12.0 * dp - 6.0 * (v1 + v0) * h + (a1 - a0) * h**2) / (2.0 * h**5)
    else:
        raise TrajectoryError(f"order must be linear, cubic or quintic, got {order!r}")
    return coeffs


def evaluate_spline(coeffs: np.ndarray, s: np.ndarray | float) -> TrajectorySample:
    """Position, velocity and acceleration of the polynomial(s) `coeffs` (..., 6, dim) at s (broadcast as (..., 1))."""
    c = [coeffs[..., k, :] for k in range(6)]
    s = np.asarray(s, dtype=float)
    pos = ((((c[5] * s + c[4]) * s + c[3]) * s + c[2]) * s + c[1]) * s + c[0]
    vel = (((5.0 * c[5] * s + 4.0 * c[4]) * s + 3.0 * c[3]) * s + 2.0 * c[2]) * s + c[1]
    acc = ((20.0 * c[5] * s + 12.0 * c[4]) * s + 6.0 * c[3]) * s + 2.0 * c[2]
    return TrajectorySample(pos, vel, acc)


def _segment_coefficients(
    p0: np.ndarray, p1: np.ndarray, v0: np.ndarray, v1: np.ndarray, h: np.ndarray, order: str
) -> np.ndarray:
    """Coefficients of each segment, shape (segments, 6, dim): accelerations zero at the waypoints."""
    zero = np.zeros_like(p0)
    return spline_coefficients(p0, v0, zero, p1, v1, zero, h, order)


class PolynomialTrajectory:
    """Piecewise cubic or quintic polynomial through `waypoints` (N, dim) at `times` (N,)."""

    def __init__(
        self,
        times: Sequence[float] | np.ndarray,
        waypoints: Sequence[Sequence[float]] | np.ndarray,
        order: str = "quintic",
        velocities: Sequence[Sequence[float]] | np.ndarray | None = None,
    ) -> None:
        times_arr = np.asarray(times, dtype=float)
        points = np.asarray(waypoints, dtype=float)
        if order not in ORDERS:
            raise TrajectoryError(f"order must be one of {ORDERS}, got {order!r}")
        if times_arr.ndim != 1 or times_arr.size < 2:
            raise TrajectoryError(f"times must be a 1-D sequence of at least 2 values, got shape {times_arr.shape}")
        if not np.all(np.isfinite(times_arr)):
            raise TrajectoryError(f"times must be finite, got {times_arr}")
        steps = np.diff(times_arr)
        if np.any(steps <= 0.0):
            bad = int(np.argmax(steps <= 0.0))
            raise TrajectoryError(
                f"times must be strictly increasing: times[{bad}]={times_arr[bad]} >= "
                f"times[{bad + 1}]={times_arr[bad + 1]}"
            )
        if points.ndim == 1:  # a 1-D trajectory given as a flat list
            points = points[:, None]
        if points.ndim != 2 or points.shape[0] != times_arr.size:
            raise TrajectoryError(
                f"waypoints must have shape ({times_arr.size}, dim) to match times, got shape {np.shape(waypoints)}"
            )
        if not np.all(np.isfinite(points)):
            raise TrajectoryError("waypoints must be finite")
        if velocities is None:
            vel = np.zeros_like(points)
        else:
            vel = np.asarray(velocities, dtype=float)
            if vel.ndim == 1 and points.shape[1] == 1:
                vel = vel[:, None]
            if vel.shape != points.shape:
                raise TrajectoryError(f"velocities must have shape {points.shape} like waypoints, got {vel.shape}")
            if not np.all(np.isfinite(vel)):
                raise TrajectoryError("velocities must be finite")

        self._times = times_arr
        self._points = points
        self._order = order
        self._coeffs = _segment_coefficients(points[:-1], points[1:], vel[:-1], vel[1:], steps, order)

    @property
    def start_time(self) -> float:
        return float(self._times[0])

    @property
    def end_time(self) -> float:
        return float(self._times[-1])

    @property
    def dim(self) -> int:
        return int(self._points.shape[1])

    @property
    def order(self) -> str:
        return self._order

    @property
    def times(self) -> np.ndarray:
        return self._times.copy()

    @property
    def waypoints(self) -> np.ndarray:
        return self._points.copy()

    def sample(self, t: float | Sequence[float] | np.ndarray) -> TrajectorySample:
        """Positions, velocities and accelerations at time(s) t (vectorised over t)."""
        t_arr = np.asarray(t, dtype=float)
        scalar = t_arr.ndim == 0
        t_flat = t_arr.reshape(-1)
        # Segment k covers [t_k, t_k+1); the last segment also owns t_N.
        segment = np.clip(np.searchsorted(self._times, t_flat, side="right") - 1, 0, len(self._times) - 2)
        s = (t_flat - self._times[segment])[:, None]
        at = evaluate_spline(self._coeffs[segment], s)  # (m, 6, dim) at (m, 1)
        pos, vel, acc = at.positions, at.velocities, at.accelerations

        # Hold the end points outside the time span.
        before = t_flat < self._times[0]
        after = t_flat > self._times[-1]
        pos[before] = self._points[0]
        pos[t_flat >= self._times[-1]] = self._points[-1]  # exactly, not up to rounding of the last segment
        outside = before | after
        vel[outside] = 0.0
        acc[outside] = 0.0
        if scalar:
            return TrajectorySample(pos[0], vel[0], acc[0])
        return TrajectorySample(pos, vel, acc)
