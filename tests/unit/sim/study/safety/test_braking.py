"""sim.study.safety.braking: the stop as one replacement trajectory, from the controller's desired state, along the
path, continuous in position, velocity and acceleration, within the Panda's limits at every press time."""

from __future__ import annotations

import numpy as np
import pytest

from sim.study.safety.braking import (
    STOP_DECELERATION,
    STOP_JERK,
    PathGeometry,
    PathState,
    arc_length,
    brake,
    braking_phases,
)
from sim.study.safety.errors import SafetyError
from sim.study.safety.limits import limits_for, motion_refusals
from tests.unit.sim.study.safety.plans import PANDA, panda_plan

DT = 0.004  # the replacement's sample step


def end_state(start: PathState, phases: list[tuple[float, float]]) -> tuple[float, float, float]:
    s, v, a = start.arc, start.speed, start.acceleration
    for d, j in phases:
        s, v, a = s + v * d + a * d**2 / 2 + j * d**3 / 6, v + a * d + j * d**2 / 2, a + j * d
    return s, v, a


@pytest.mark.parametrize(
    "speed, acceleration, peak",
    [(0.5, 0.0, STOP_DECELERATION), (0.5, 0.8, STOP_DECELERATION), (0.01, 0.0, np.sqrt(STOP_JERK * 0.01))],
)
def test_the_phases_reach_rest_with_no_acceleration_and_no_more_than_the_deceleration(speed, acceleration, peak):
    phases = braking_phases(speed, acceleration, STOP_DECELERATION, STOP_JERK)
    _, v, a = end_state(PathState(0.0, speed, acceleration), phases)
    assert v == pytest.approx(0.0, abs=1e-12) and a == pytest.approx(0.0, abs=1e-12)
    assert all(abs(j) == pytest.approx(STOP_JERK) or j == 0 for _, j in phases)
    lowest = acceleration - STOP_JERK * phases[0][0]
    assert lowest == pytest.approx(-peak)


def test_a_plan_decelerating_harder_than_the_jerk_can_undo_gets_a_steeper_ramp_and_never_reverses() -> None:
    (phase,) = braking_phases(0.01, -2.0, STOP_DECELERATION, STOP_JERK)
    _, v, a = end_state(PathState(0.0, 0.01, -2.0), [phase])
    assert phase[1] == pytest.approx(200.0) and v == pytest.approx(0.0, abs=1e-12) and a == pytest.approx(0.0)
    assert braking_phases(0.0, -0.5, STOP_DECELERATION, STOP_JERK) == []  # at rest: nothing to do
    with pytest.raises(SafetyError, match="deceleration and jerk must be > 0"):
        braking_phases(0.5, 0.0, 0.0, STOP_JERK)


@pytest.mark.parametrize("name, speed", [("diagonal", 0.5), ("vertical", 0.5), ("lateral_arc", 0.3)])
def test_braking_at_every_press_time_is_smooth_on_the_path_and_within_the_pandas_limits(name, speed) -> None:
    path, joints = panda_plan(name, speed)
    geometry = PathGeometry(path, joints)
    limits = limits_for(PANDA)
    arc, path_acceleration = arc_length(path), np.gradient(path.speeds, path.dt)
    braked = 0
    for k in range(1, len(path.times) - 1):  # every press time of the plan
        desired = geometry.joint_state(PathState(arc[k], path.speeds[k], path_acceleration[k]))
        stop = brake(geometry, *desired, DT)
        assert stop is not None, f"press at {path.times[k]:.2f} s"
        braked += 1
        # It starts from the desired state: the controller's bridge to it is nothing.
        np.testing.assert_allclose(stop.positions[0], desired[0], atol=1e-9)
        np.testing.assert_allclose(stop.velocities[0], desired[1], atol=1e-9)
        np.testing.assert_allclose(stop.accelerations[0], desired[2], atol=1e-6)
        # Continuous in acceleration (bounded jerk between samples), forward along the path only, to rest on it.
        assert np.abs(np.diff(stop.accelerations, axis=0)).max() <= 1.5 * np.abs(stop.jerks).max() * DT + 1e-9
        assert stop.path_speed.min() >= -1e-12 and np.all(np.diff(stop.arc) >= -1e-12)
        assert stop.path_speed[-1] == pytest.approx(0.0, abs=1e-9) and stop.path_acceleration[-1] == 0.0
        np.testing.assert_allclose(stop.velocities[-1], 0.0, atol=1e-9)
        assert stop.arc[-1] <= geometry.length + 1e-9
        assert stop.path_acceleration.min() >= min(-STOP_DECELERATION, stop.start.acceleration) - 1e-9
        # Never beyond the robot's acceleration or jerk limit (the full published ones, no margin).
        exact = (stop.velocities, stop.accelerations, stop.jerks)
        assert motion_refusals("braking", stop.times, stop.positions, limits, 1.0, derivatives=exact) == []
    assert braked == len(path.times) - 2


def test_a_path_without_length_or_a_bad_step_is_named() -> None:
    path, joints = panda_plan("diagonal", 0.5)
    with pytest.raises(SafetyError, match="joint samples for a path of"):
        PathGeometry(path, joints[:-1])
    geometry = PathGeometry(path, joints)
    with pytest.raises(SafetyError, match="sample step must be > 0"):
        brake(geometry, joints[5], np.zeros(7), np.zeros(7), 0.0)
