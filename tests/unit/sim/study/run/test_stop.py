"""sim.study.run.stop: a press stops the robot along its path within the stated deceleration, never ahead of the plan
and never jumping; the distances at the press and at rest follow."""

from __future__ import annotations

import numpy as np
import pytest

from sim.study.design.paths import ON_TOP, approach_path
from sim.study.design.scene import load_scene
from sim.study.errors import StudyError
from sim.study.run.stop import STOP_DECELERATION, arc_length, stop_motion

SCENE = load_scene()
PATH = approach_path(SCENE, "straight", ON_TOP, peak_speed=0.3, dt=0.01)
JOINTS = np.column_stack([np.linspace(0.0, 1.0, len(PATH.times)), np.linspace(0.5, -0.5, len(PATH.times))])


def test_a_press_at_full_speed_brakes_within_the_limit_along_the_path():
    press = PATH.duration / 2  # the peak of the minimum-jerk profile
    stopped = stop_motion(PATH, JOINTS, press)
    assert stopped.braking_distance == pytest.approx(0.3**2 / (2 * STOP_DECELERATION), rel=0.01)
    assert stopped.rest_time == pytest.approx(press + 0.3 / STOP_DECELERATION, rel=0.01)
    speeds = np.diff(stopped.arc) / PATH.dt
    after = stopped.times[1:] > press + PATH.dt
    assert np.all(np.diff(speeds[after]) <= 1e-12)  # slowing down only, once braking
    assert np.abs(np.diff(speeds)).max() / PATH.dt <= STOP_DECELERATION * 1.05 + 1e-9  # no jumps in speed either
    planned = np.interp(stopped.times, PATH.times, arc_length(PATH))
    assert np.all(stopped.arc <= planned + 1e-12)  # never ahead of the plan
    # on the path: every stopped position is the path's at that arc length, so the hand is farther than planned
    assert SCENE.hand.distance(stopped.positions[-1]) > ON_TOP + 0.1


def test_joint_positions_are_the_planned_ones_at_the_same_arc_length():
    stopped = stop_motion(PATH, JOINTS, PATH.duration / 3)
    expected = np.interp(stopped.arc, arc_length(PATH), JOINTS[:, 0])
    np.testing.assert_allclose(stopped.joint_positions[:, 0], expected)
    planned_step = np.abs(np.diff(JOINTS, axis=0)).max()
    assert np.abs(np.diff(stopped.joint_positions, axis=0)).max() <= planned_step * 1.0001


def test_a_press_late_in_the_plan_rests_where_the_plan_ends_and_one_at_rest_stops_at_once():
    late = stop_motion(PATH, JOINTS, PATH.duration - 0.02)
    assert late.rest_arc == pytest.approx(arc_length(PATH)[-1], abs=1e-5)  # nearly at rest already
    after_end = stop_motion(PATH, JOINTS, PATH.duration + 5.0)
    assert after_end.rest_arc == pytest.approx(arc_length(PATH)[-1]) and after_end.press_time == PATH.duration
    at_start = stop_motion(PATH, JOINTS, 0.0)
    assert at_start.rest_arc == 0.0 and at_start.braking_distance == 0.0


@pytest.mark.parametrize(
    "press, deceleration, message",
    [
        (-1.0, 1.0, "press time must be >= 0"),
        (float("nan"), 1.0, "press time"),
        (1.0, 0.0, "deceleration must be > 0"),
    ],
)
def test_bad_stop_inputs_are_named(press, deceleration, message):
    with pytest.raises(StudyError, match=message):
        stop_motion(PATH, JOINTS, press, deceleration)
