"""Stopping on the participant's press, streamed: along the path, decelerating at a stated limit, never jumping in
position or speed. Pure logic; the runner streams what it returns to the stand-in. For a trajectory controller the
stop is sim.study.safety.braking's instead, which is also continuous in acceleration (the same path, deceleration
and arc length, from there).

A planned approach follows its path with the minimum-jerk arc length s(t). Pressed at t_p (arc length s_p, speed
v_p), the robot brakes at STOP_DECELERATION: s(t) = s_p + v_p·τ − ½·a·τ², τ = t − t_p, until it rests after
v_p / a, having gone v_p² / (2a) further. It never gets ahead of the plan, whose own end decelerates to rest too:
where the plan is behind the braking curve, the plan is followed. Joint positions come from the planned ones at the
same arc length (the geometry is the path's, only the timing changes), so no new IK is needed.

The distances the analysis uses are the end effector's to the hand at the press and at rest, from the joint states
(FK), and the thesis's estimate: the distance the plan would have at the press time (its extrapolation from time).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.study.design.paths import ApproachPath
from sim.study.run.errors import RunError
from sim.study.safety.braking import STOP_DECELERATION, arc_length

__all__ = ["STOP_DECELERATION", "StoppedMotion", "arc_length", "stop_motion"]


@dataclass(frozen=True)
class StoppedMotion:
    times: np.ndarray  # (M,) s, the path's grid k·dt up to rest
    arc: np.ndarray  # (M,) m along the path
    positions: np.ndarray  # (M, 3) world
    joint_positions: np.ndarray  # (M, dof)
    press_time: float
    rest_time: float  # when the speed reaches 0 (the last sample is the first grid time at or after it)
    press_arc: float
    rest_arc: float

    @property
    def braking_distance(self) -> float:
        return self.rest_arc - self.press_arc


def stop_motion(
    path: ApproachPath, joint_positions: np.ndarray, press_time: float, deceleration: float = STOP_DECELERATION
) -> StoppedMotion:
    """The motion after a press at `press_time` (s from the path's start), on the path's time grid."""
    if not (math.isfinite(press_time) and press_time >= 0.0):
        raise RunError(f"the press time must be >= 0 s, got {press_time!r}")
    if not (math.isfinite(deceleration) and deceleration > 0.0):
        raise RunError(f"the stop deceleration must be > 0 m/s², got {deceleration!r}")
    joint_positions = np.asarray(joint_positions, dtype=float)
    if joint_positions.shape[0] != len(path.times):
        raise RunError(f"{joint_positions.shape[0]} joint samples for a path of {len(path.times)}")
    planned = arc_length(path)
    press_time = min(press_time, path.duration)
    press_arc = float(np.interp(press_time, path.times, planned))
    press_speed = float(np.interp(press_time, path.times, path.speeds))
    braking = press_speed / deceleration
    rest_time = min(press_time + braking, path.duration)
    steps = int(math.ceil(rest_time / path.dt - 1e-9))
    times = np.arange(steps + 1) * path.dt
    tau = np.clip(times - press_time, 0.0, braking)
    braked = press_arc + press_speed * tau - 0.5 * deceleration * tau**2
    arc = np.minimum(np.interp(times, path.times, planned), np.where(times <= press_time, np.inf, braked))
    rest_arc = float(min(press_arc + press_speed * braking - 0.5 * deceleration * braking**2, planned[-1]))
    arc[-1] = min(arc[-1], rest_arc)
    positions = np.array([np.interp(arc, planned, path.positions[:, axis]) for axis in range(3)]).T
    joints = np.array([np.interp(arc, planned, joint_positions[:, j]) for j in range(joint_positions.shape[1])]).T
    return StoppedMotion(times, arc, positions, joints, press_time, rest_time, press_arc, float(arc[-1]))
