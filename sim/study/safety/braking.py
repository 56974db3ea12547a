"""The stop on a press for a trajectory controller: one replacement trajectory that brakes along the planned path,
from the controller's current desired state, continuous in position, velocity and acceleration. Pure logic.

The stream (sim.study.run.stop) decelerates at once at a constant rate: its acceleration jumps, which a streamed
point-by-point command gets away with on the stand-in but which a real arm's controller would pass on as a jerk
(libfranka aborts a motion on such a discontinuity). Here the path's acceleration goes from the desired state's to
−deceleration at the braking jerk, holds, and comes back to 0 as the speed reaches 0 (the S-curve of a jerk-limited
stop). When the speed is too low for the deceleration to be reached, the peak is lower; when the plan is already
decelerating harder than the jerk allows to undo before the speed reaches 0, the jerk is raised just enough (and the
limits check says whether the robot allows it).

The joint positions are the plan's at the same arc length: q(s) is a C² cubic spline of the planned joint positions
over the arc length, so q̇ = q'·ṡ, q̈ = q''·ṡ² + q'·s̈ and the jerk q⃛ = q'''·ṡ³ + 3·q''·ṡ·s̈ + q'·s⃛ are bounded and
the first two continuous. Knots closer than KNOT_SPACING along the path are thinned out: near the path's ends, where
the samples bunch up, IK's tolerance would otherwise become a large q'''.

The desired joint state is put on the path by projection: the arc length whose planned joints are nearest, and the
path speed and acceleration that explain the desired joint velocity and acceleration best (least squares along the
path's tangent q'). A stop never goes past the plan's end: where braking would rest beyond it, the plan itself comes
to rest sooner (it ends at the stand-off at rest), and `brake` returns None: leave the plan running.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.interpolate import CubicSpline

from sim.study.design.paths import ApproachPath
from sim.study.safety.errors import SafetyError

__all__ = [
    "STOP_DECELERATION",
    "STOP_JERK",
    "KNOT_SPACING",
    "arc_length",
    "PathState",
    "PathGeometry",
    "BrakingPath",
    "Braking",
    "braking_phases",
    "brake",
]

STOP_DECELERATION = 1.0  # m/s² along the path: what a press may ask of the end effector
STOP_JERK = 20.0  # m/s³ along the path: how fast the deceleration builds up (0 to 1 m/s² in 50 ms)
KNOT_SPACING = 0.002  # m: the joint spline's knots along the path, at least this far apart


def arc_length(path: ApproachPath) -> np.ndarray:
    """The planned arc length at each sample of `path` (cumulative distance between samples)."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path.positions, axis=0), axis=1))])


@dataclass(frozen=True)
class PathState:
    arc: float  # m along the path
    speed: float  # m/s
    acceleration: float  # m/s²


class PathGeometry:
    """The planned path as functions of arc length: the joint positions q(s) (a C² spline) and the world positions."""

    def __init__(self, path: ApproachPath, joint_positions: np.ndarray) -> None:
        joints = np.asarray(joint_positions, dtype=float)
        if joints.ndim != 2 or joints.shape[0] != len(path.times):
            raise SafetyError(f"{joints.shape[0] if joints.ndim else 0} joint samples for a path of {len(path.times)}")
        arc = arc_length(path)
        if arc[-1] <= KNOT_SPACING:
            raise SafetyError(f"a path of {arc[-1]:.4f} m has no length to brake along")
        keep = [0]
        for k in range(1, len(arc) - 1):
            if arc[k] - arc[keep[-1]] >= KNOT_SPACING and arc[-1] - arc[k] >= KNOT_SPACING:
                keep.append(k)
        keep.append(len(arc) - 1)
        self.length = float(arc[-1])
        self.knots = arc[keep]
        self._q = CubicSpline(self.knots, joints[keep], bc_type="natural")
        self._x = CubicSpline(self.knots, path.positions[keep], bc_type="natural")
        self._dense = np.linspace(0.0, self.length, 2001)
        self._dense_q = self._q(self._dense)

    @property
    def dof(self) -> int:
        return int(self._dense_q.shape[1])

    def joints(self, s: np.ndarray | float, derivative: int = 0) -> np.ndarray:
        return np.asarray(self._q(np.clip(s, 0.0, self.length), derivative))

    def world(self, s: np.ndarray | float) -> np.ndarray:
        return np.asarray(self._x(np.clip(s, 0.0, self.length)))

    def joint_state(self, state: PathState) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint positions, velocities and accelerations of a path state (q, q'·ṡ, q''·ṡ² + q'·s̈)."""
        tangent, curvature = self.joints(state.arc, 1), self.joints(state.arc, 2)
        return (
            self.joints(state.arc),
            tangent * state.speed,
            curvature * state.speed**2 + tangent * state.acceleration,
        )

    def project(self, positions: np.ndarray, velocities: np.ndarray, accelerations: np.ndarray) -> PathState:
        """The path state that best explains a joint state (see the module's doc)."""
        nearest = int(np.argmin(np.linalg.norm(self._dense_q - positions, axis=1)))
        s = float(self._dense[nearest])
        for _ in range(5):  # Newton on |q(s) − positions|² along the tangent
            tangent = self.joints(s, 1)
            curvature = self.joints(s, 2)
            offset = self.joints(s) - positions
            slope = float(tangent @ offset)
            bend = float(tangent @ tangent + curvature @ offset)
            if bend <= 0:
                break
            s = float(np.clip(s - slope / bend, 0.0, self.length))
        tangent = self.joints(s, 1)
        norm = float(tangent @ tangent)
        speed = float(tangent @ velocities) / norm
        acceleration = float(tangent @ (accelerations - self.joints(s, 2) * speed**2)) / norm
        return PathState(s, speed, acceleration)


class BrakingPath(Protocol):
    """What `brake` asks of a path to brake along (PathGeometry; a move's line in joint space): its length, its joint
    positions and their derivatives by its parameter, its world positions, and the projection of a joint state."""

    length: float

    def joints(self, s: np.ndarray | float, derivative: int = 0) -> np.ndarray: ...

    def world(self, s: np.ndarray | float) -> np.ndarray: ...

    def project(self, positions: np.ndarray, velocities: np.ndarray, accelerations: np.ndarray) -> PathState: ...


def braking_phases(speed: float, acceleration: float, deceleration: float, jerk: float) -> list[tuple[float, float]]:
    """(duration, jerk) of each phase of a path stop from `speed` ≥ 0 and `acceleration` to rest with zero
    acceleration: the acceleration ramps at ±jerk to −peak (peak ≤ deceleration), holds, then ramps back to 0."""
    if not (deceleration > 0 and jerk > 0 and math.isfinite(deceleration) and math.isfinite(jerk)):
        raise SafetyError(f"the deceleration and jerk must be > 0, got {deceleration!r} and {jerk!r}")
    v0, a0 = max(speed, 0.0), acceleration
    if v0 <= 1e-9 and a0 <= 0:
        return []  # at rest on the path already, and not about to move
    if a0 < 0 and jerk * v0 < 0.5 * a0**2:
        # Decelerating so hard that ramping back at `jerk` would reverse: ramp back faster, straight to rest.
        steeper = 0.5 * a0**2 / v0
        return [(-a0 / steeper, steeper)]
    peak = math.sqrt(jerk * v0 + 0.5 * a0**2)  # the peak that reaches rest with no hold
    hold = 0.0
    if peak > deceleration:
        peak = deceleration
        # speed left after the ramp to −peak and the ramp back, taken off at −peak
        ramp_in = (a0**2 - peak**2) / (2 * jerk) if a0 > -peak else (peak**2 - a0**2) / (2 * jerk)
        hold = max((v0 + ramp_in - peak**2 / (2 * jerk)) / peak, 0.0)
    ramp_in_time = abs(a0 + peak) / jerk
    phases = [(ramp_in_time, -jerk if a0 > -peak else jerk), (hold, 0.0), (peak / jerk, jerk)]
    return [(duration, j) for duration, j in phases if duration > 0]


def _integrate(state: PathState, phases: list[tuple[float, float]], times: np.ndarray) -> np.ndarray:
    """(s, ṡ, s̈, s⃛) at `times` (from 0) of the piecewise-constant-jerk motion from `state`; held after the end."""
    out = np.zeros((len(times), 4))
    s, v, a = state.arc, state.speed, state.acceleration
    start = 0.0
    remaining = np.ones(len(times), dtype=bool)
    for duration, j in phases:
        inside = remaining & (times < start + duration)
        tau = times[inside] - start
        out[inside] = np.column_stack(
            [
                s + v * tau + a * tau**2 / 2 + j * tau**3 / 6,
                v + a * tau + j * tau**2 / 2,
                a + j * tau,
                np.full_like(tau, j),
            ]
        )
        remaining &= ~inside
        d = duration
        s, v, a = s + v * d + a * d**2 / 2 + j * d**3 / 6, v + a * d + j * d**2 / 2, a + j * d
        start += duration
    out[remaining] = [s, 0.0, 0.0, 0.0]
    return out


@dataclass(frozen=True)
class Braking:
    """The stop as samples from the desired state (t = 0) to rest, for a trajectory controller's replacement."""

    times: np.ndarray  # (M,) s from the desired state's time, 0 first
    arc: np.ndarray  # (M,) m along the path
    path_speed: np.ndarray  # (M,) m/s
    path_acceleration: np.ndarray  # (M,) m/s²
    path_jerk: np.ndarray  # (M,) m/s³
    positions: np.ndarray  # (M, dof)
    velocities: np.ndarray  # (M, dof)
    accelerations: np.ndarray  # (M, dof)
    jerks: np.ndarray  # (M, dof)
    world_positions: np.ndarray  # (M, 3)
    start: PathState

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    @property
    def distance(self) -> float:
        return float(self.arc[-1] - self.start.arc)


def brake(
    geometry: BrakingPath,
    positions: np.ndarray,
    velocities: np.ndarray,
    accelerations: np.ndarray,
    dt: float,
    deceleration: float = STOP_DECELERATION,
    jerk: float = STOP_JERK,
) -> Braking | None:
    """The stop from the controller's desired joint state, sampled every `dt` (the last sample at rest); None when
    the plan rests before braking would (leave it running)."""
    if not (math.isfinite(dt) and dt > 0):
        raise SafetyError(f"the braking's sample step must be > 0 s, got {dt!r}")
    state = geometry.project(
        np.asarray(positions, dtype=float), np.asarray(velocities, dtype=float), np.asarray(accelerations, dtype=float)
    )
    phases = braking_phases(state.speed, state.acceleration, deceleration, jerk)
    duration = sum(d for d, _ in phases)
    times = np.arange(int(math.ceil(duration / dt - 1e-9)) + 1) * dt
    path = _integrate(state, phases, times)
    if path[-1, 0] > geometry.length + 1e-9:
        return None
    q1, q2, q3 = (geometry.joints(path[:, 0], k) for k in (1, 2, 3))
    s_dot, s_ddot, s_dddot = path[:, 1:2], path[:, 2:3], path[:, 3:4]
    return Braking(
        times=times,
        arc=path[:, 0],
        path_speed=path[:, 1],
        path_acceleration=path[:, 2],
        path_jerk=path[:, 3],
        positions=geometry.joints(path[:, 0]),
        velocities=q1 * s_dot,
        accelerations=q2 * s_dot**2 + q1 * s_ddot,
        jerks=q3 * s_dot**3 + 3 * q2 * s_dot * s_ddot + q1 * s_dddot,
        world_positions=geometry.world(path[:, 0]),
        start=state,
    )
