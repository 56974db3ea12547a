"""sim.study's scene and path library, pure: every path ends at its stand-off, never comes closer on the way, starts
and ends at rest, peaks at the requested speed, stays above the table; bad input is one StudyError naming it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim.study.design.paths import MAX_STANDOFF, ON_TOP, PATH_NAMES, approach_path, end_point, hand_frame
from sim.study.design.scene import Box, load_scene, parse_scene
from sim.study.errors import StudyError

SCENE = load_scene()
STANDOFFS = (ON_TOP, 0.05, 0.15, MAX_STANDOFF)


def scene_data() -> dict:
    return {
        "robot": "panda",
        "base": {"xyz": [0, 0, 0], "rpy": [0, 0, 0]},
        "table": {"size": [1.4, 1.0, 0.05], "xyz": [0.4, 0, -0.025]},
        "hand": {"size": [0.19, 0.09, 0.035], "xyz": [0.55, 0, 0.0175]},
        "seat": {"xyz": [0.55, -0.65, 0.45]},
    }


def test_the_bundled_scene_has_the_hand_resting_on_the_table_in_front_of_the_robot():
    assert SCENE.robot == "panda"
    assert SCENE.hand.top == pytest.approx([0.55, 0.0, 0.035])
    assert SCENE.hand.distance(SCENE.hand.top + [0, 0, 0.1]) == pytest.approx(0.1)
    assert SCENE.hand.distance(SCENE.hand.position) == 0.0
    np.testing.assert_allclose(hand_frame(SCENE), np.eye(3), atol=1e-12)  # the hand straight ahead of the robot


def test_a_turned_box_measures_distance_in_its_own_axes():
    box = Box(np.array([0.2, 0.1, 0.1]), np.zeros(3), yaw=np.pi / 2)
    assert box.distance([0.0, 0.15, 0.0]) == pytest.approx(0.05)  # its x axis now points along world y
    assert box.distance([0.15, 0.0, 0.0]) == pytest.approx(0.10)


@pytest.mark.parametrize("name", PATH_NAMES)
@pytest.mark.parametrize("standoff", STANDOFFS)
def test_every_path_ends_at_its_standoff_and_never_comes_closer(name, standoff):
    path = approach_path(SCENE, name, standoff, peak_speed=0.2)
    distances = np.array([SCENE.hand.distance(point) for point in path.positions])
    assert distances[-1] == pytest.approx(standoff, abs=1e-9)
    assert distances.min() >= standoff - 1e-9
    assert distances[0] >= standoff + 0.05
    assert path.positions[:, 2].min() > 0.03  # above the table top (z = 0) all the way


@pytest.mark.parametrize("name", PATH_NAMES)
def test_the_speed_profile_is_smooth_starts_and_ends_at_rest_and_peaks_at_the_requested_speed(name):
    path = approach_path(SCENE, name, 0.05, peak_speed=0.25, dt=0.01)
    np.testing.assert_allclose(path.times, 0.01 * np.arange(len(path.times)))
    assert path.speeds[0] == 0.0 and path.speeds[-1] == pytest.approx(0.0, abs=1e-12)
    assert 0.24 <= path.peak_speed <= 0.25
    moved = np.linalg.norm(np.diff(path.positions, axis=0), axis=1) / 0.01
    midpoints = (path.speeds[1:] + path.speeds[:-1]) / 2
    np.testing.assert_allclose(moved, midpoints, atol=0.01 * path.peak_speed + 1e-3)
    assert abs(np.sum(moved) * 0.01 - path.length) < 1e-3


def test_a_faster_path_takes_proportionally_less_time():
    slow, fast = (approach_path(SCENE, "vertical", 0.1, speed) for speed in (0.1, 0.3))
    assert slow.length == pytest.approx(fast.length)
    assert slow.duration == pytest.approx(3 * fast.duration, rel=0.02)


def test_the_end_point_is_found_along_any_direction():
    for direction in ([0, 0, 1], [-1, 0, 1], [0.2, 0.5, 0.3]):
        point = end_point(SCENE.hand, np.array(direction, dtype=float), 0.07)
        assert SCENE.hand.distance(point) == pytest.approx(0.07, abs=1e-9)


def test_an_end_point_asked_for_again_is_the_same_the_callers_own_and_moves_with_the_hand():
    # (end points are kept by their exact inputs, sim.study.design.paths._END_POINTS: a fit asks for each many times)
    direction = np.array([-1.0, 0.0, 1.0])
    first = end_point(SCENE.hand, direction, 0.07)
    found = first.copy()
    first[:] = 0.0  # the caller's to change: what is kept is not
    np.testing.assert_array_equal(end_point(SCENE.hand, direction, 0.07), found)
    shift = np.array([0.1, -0.05, 0.02])
    moved = dataclasses.replace(SCENE.hand, position=SCENE.hand.position + shift)
    np.testing.assert_allclose(end_point(moved, direction, 0.07), found + shift, atol=1e-12)
    turned = dataclasses.replace(SCENE.hand, yaw=np.pi / 2)  # the hand's longer side now across the direction
    assert turned.distance(end_point(turned, direction, 0.07)) == pytest.approx(0.07, abs=1e-9)
    assert end_point(SCENE.hand, direction, 0.08) != pytest.approx(found)


def test_a_negative_stand_off_puts_the_end_point_inside_the_hand_against_the_direction():
    # (a tool frame beyond the gripper's geometry: the point goes into the hand so that the surface ends outside)
    for direction in ([0, 0, 1], [-1, 0, 1]):
        unit = np.array(direction, dtype=float) / np.linalg.norm(direction)
        point = end_point(SCENE.hand, unit, -0.015)
        assert SCENE.hand.distance(point) == 0.0
        np.testing.assert_allclose(point, SCENE.hand.top - 0.015 * unit)
    # continuous through the top centre: the point at stand-off 0 from either side is the top centre
    np.testing.assert_allclose(end_point(SCENE.hand, np.array([0.0, 0.0, 1.0]), 1e-9), SCENE.hand.top, atol=1e-8)


@pytest.mark.parametrize(
    "args, message",
    [
        (("zigzag", 0.1, 0.2), "unknown path 'zigzag'; known paths: straight, vertical"),
        (("straight", 0.5, 0.2), "stand-off must be 0.01..0.3 m, got 0.5"),
        (("straight", float("nan"), 0.2), "stand-off must be"),
        (("straight", 0.1, 0.0), "peak speed must be > 0"),
        (("straight", 0.1, 2.0), "at most 1 m/s"),
    ],
)
def test_bad_path_requests_are_named(args, message):
    with pytest.raises(StudyError, match=message):
        approach_path(SCENE, *args)


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d.pop("hand"), r"missing key\(s\) \['hand'\]"),
        (lambda d: d.update(lamp={}), r"unknown key\(s\) \['lamp'\]"),
        (lambda d: d["hand"].update(xyz=[0.55, 0, 0.2]), "the hand must rest on the table"),
        (lambda d: d["table"].update(size=[1, -1, 0.05]), "table.size must be > 0"),
        (lambda d: d["hand"].update(xyz=[0.5, "x", 0.0]), "hand.xyz must be 3 finite numbers"),
        (lambda d: d["hand"].update(colour="pink"), r"hand has unknown key\(s\) \['colour'\]"),
        (lambda d: d.update(robot=""), "robot must be a robot name or a URDF path"),
    ],
)
def test_a_bad_scene_is_one_clear_error(change, message):
    data = scene_data()
    change(data)
    with pytest.raises(StudyError, match=message):
        parse_scene(data)


def test_a_hand_under_the_robot_cannot_be_approached():
    data = scene_data()
    data["hand"]["xyz"] = [0.0, 0.0, 0.0175]
    with pytest.raises(StudyError, match="right under the robot's base"):
        approach_path(parse_scene(data), "vertical", 0.1, 0.2)
