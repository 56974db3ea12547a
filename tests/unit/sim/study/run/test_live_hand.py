"""The hand as the distance floor sees it during an approach: the scene's hand moved by the displacement of the
tracked hand under the robot, and the scene world's distance to a hand so moved."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim.study.design.scene import Box, load_scene, scene_robot
from sim.study.design.world import SceneWorld
from sim.study.run.links.hand import LiveHand

SCENE = load_scene()
ROBOT = scene_robot(SCENE)
HAND = SCENE.hand.position


def test_the_hand_under_the_robot_is_followed_from_where_it_was_first_seen() -> None:
    live = LiveHand(HAND)
    # the tracker sits 5 cm off the hand's centre; the other hand is further away, and the head is no hand
    start = {"left_hand": HAND + [0.0, 0.2, 0.0], "right_hand": HAND + [0.05, 0.0, 0.0], "head": HAND}
    assert np.array_equal(live.shift(start), np.zeros(3)) and live.body == "right_hand"
    reaching = dict(start, right_hand=start["right_hand"] + [0.0, 0.0, 0.12], left_hand=HAND)
    np.testing.assert_allclose(live.shift(reaching), [0.0, 0.0, 0.12])  # the left hand coming near changes nothing
    lost = {"left_hand": HAND}  # the right hand not seen: its box stays where it was last seen
    np.testing.assert_allclose(live.shift(lost), [0.0, 0.0, 0.12])


def test_without_a_tracked_hand_near_the_scenes_hand_the_hand_stays_the_scenes() -> None:
    live = LiveHand(HAND)
    assert np.array_equal(live.shift({}), np.zeros(3))
    assert np.array_equal(live.shift({"right_hand": HAND + [0.3, 0.0, 0.0]}), np.zeros(3)) and live.body == ""
    live.shift({"right_hand": HAND + [0.1, 0.0, 0.0]})  # comes within reach: taken from here
    np.testing.assert_allclose(live.shift({"right_hand": HAND + [0.1, 0.0, 0.05]}), [0.0, 0.0, 0.05])


@pytest.mark.parametrize("distance", ["surface", "ee_point"])
def test_the_distance_to_a_moved_hand_is_that_of_a_scene_with_the_hand_there(distance: str) -> None:
    shift = np.array([0.02, -0.01, 0.15])
    scene = dataclasses.replace(SCENE, distance=distance)
    moved = dataclasses.replace(scene, hand=Box(SCENE.hand.size, HAND + shift, SCENE.hand.yaw))
    q = np.asarray(ROBOT.home, dtype=float)
    with SceneWorld(ROBOT, scene) as world, SceneWorld(ROBOT, moved) as there:
        before = world.hand_distance(q)
        assert world.hand_distance(q, shift) == pytest.approx(there.hand_distance(q), abs=1e-6)
        assert world.hand_distance(q, shift) < before - 0.05  # raised towards the arm above it
        assert world.hand_distance(q) == pytest.approx(before, abs=1e-9)  # only that query saw it moved
