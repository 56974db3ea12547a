"""The trajectory-controller link's pure parts: the --link option and presets, an approach as a goal's points, the
commanded path and its tracking error, and when the achieved speed fell after a press."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.study.run.errors import RunError
from sim.study.run.links.base import ApproachOutcome
from sim.study.run.links.goals import CommandedPath, goal_points, speed_fell
from sim.study.run.links.specs import PRESETS, link_specs


def test_links_are_chosen_per_condition_by_preset_or_namespace() -> None:
    chosen = link_specs(["reality=franka_ros", "vr=stream"], ["vr", "reality"])
    assert list(chosen) == ["reality"]
    assert chosen["reality"].namespace == "/position_joint_trajectory_controller"
    assert chosen["reality"].joint_states_topic == "/franka_state_controller/joint_states"
    assert PRESETS["ur_robot_driver"].namespace == "/scaled_pos_joint_traj_controller"
    given = link_specs(["reality=/iiwa/ctl/,/iiwa/joint_states"], ["vr", "reality"], floor=0.05)
    assert (given["reality"].namespace, given["reality"].floor, given["reality"].label) == (
        "/iiwa/ctl",
        0.05,
        "/iiwa/ctl",
    )


@pytest.mark.parametrize(
    ("given", "problem"),
    [
        (["reality=franka"], "neither stream, a preset"),
        (["lab=franka_ros"], "a condition of vr, reality once"),
        (["reality=stream", "reality=franka_ros"], "once"),
        (["reality=ctl,joint_states"], "absolute ROS name"),
    ],
)
def test_a_link_that_names_nothing_known_is_refused(given: list[str], problem: str) -> None:
    with pytest.raises(RunError, match=problem):
        link_specs(given, ["vr", "reality"])


def test_an_approach_goes_as_points_after_its_start_and_a_rehearsal_slows_it_along_the_same_path() -> None:
    t = np.linspace(0.0, 1.0, 11)
    q = np.column_stack([t**2, -t])
    v = np.column_stack([2 * t, -np.ones_like(t)])
    points = goal_points(q, v, 0.1)
    assert np.allclose(points.times, t[1:]) and np.allclose(points.positions, q[1:])
    assert np.allclose(points.accelerations[1:-1, 0], 2.0) and np.allclose(points.accelerations[-1], 0.0)
    slow = goal_points(q, v, 0.1, speed_scale=0.5)
    assert np.allclose(slow.times, 2 * t[1:]) and np.allclose(slow.positions, q[1:])
    assert np.allclose(slow.velocities, v[1:] / 2) and np.allclose(slow.accelerations, points.accelerations / 4)


def test_a_replacement_is_in_force_from_its_start_and_the_tracking_error_is_against_it() -> None:
    path = CommandedPath()
    path.add(10.0, np.array([0.0, 1.0]), np.array([[0.0, 0.0], [1.0, 2.0]]))
    assert np.allclose(path.at(10.5), [0.5, 1.0]) and np.allclose(path.at(9.0), [0.0, 0.0])
    path.add(10.5, np.array([0.0, 1.0]), np.array([[0.5, 1.0], [0.6, 1.0]]))
    assert np.allclose(path.at(11.0), [0.55, 1.0]) and np.allclose(path.at(20.0), [0.6, 1.0])
    assert path.error(11.0, np.array([0.55, 0.9])) == pytest.approx(0.1)
    path.discard_last()  # a replacement the controller refused: the approach is what was commanded after all
    assert np.allclose(path.at(11.0), [1.0, 2.0])
    path.discard_last()
    with pytest.raises(RunError, match="nothing was commanded"):
        path.discard_last()


def test_braking_begins_at_the_first_state_whose_speed_has_fallen() -> None:
    stamps = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    assert speed_fell(stamps, np.array([1.0, 1.0, 1.0, 0.5, 0.0]), 0.15) == pytest.approx(0.15)
    assert math.isnan(speed_fell(stamps, np.zeros(5), 0.15))  # at rest: nothing to fall


def test_an_approachs_window_is_placed_on_the_start_its_link_reports() -> None:
    # A trajectory controller starts the arm at its goal's stamp, a planning and a start lead (10-250 ms) after the
    # runner asked at 100.0 s: the window, and the press 1.5 s into the motion, are on that stamp.
    outcome = ApproachOutcome(motion_start=100.26)
    window = outcome.window(end=104.0, press_time=1.5)
    assert (window.start, window.end) == (100.26, 104.0) and window.press == pytest.approx(101.76, abs=1e-12)
    assert math.isnan(outcome.window(104.0, math.nan).press)  # no press
    with pytest.raises(RunError, match="did not report when its motion started"):
        ApproachOutcome().window(104.0, 1.5)


def test_a_rehearsals_press_is_placed_on_the_links_clock_from_the_plans_seconds() -> None:
    # The rehearsal runs the plan at half speed: a press 1.5 s into the plan came 3 s after the arm started.
    window = ApproachOutcome(motion_start=100.0, speed_scale=0.5).window(end=110.0, press_time=1.5)
    assert window.press == pytest.approx(103.0, abs=1e-12)
