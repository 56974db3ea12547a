"""sim.study.design.verdicts: a plan's key tells apart every input it depends on, down to the last bit, and a kept
plan is taken once, by its key alone. (A fit's plans taken by the next planner of the same input, and not by another,
with pybullet: test_handed_on.py.)"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from sim.study.design.scene import Box, load_scene
from sim.study.design.verdicts import Kept, exact_text, verdict_key

SCENE = load_scene()
COMBINATION = ("straight", 0.1, 0.15)
DT = 0.02
ROBOT = '{"urdf": "<robot name=\\"r\\"/>", "files": [], "robot": {}}'


def nudged(value: float) -> float:
    return float(np.nextafter(value, np.inf))  # the next float up: the smallest change there is


def scene_variants() -> dict[str, object]:
    """The scene with each of its fields changed, the least that changes it."""
    moved = SCENE.base_position.copy()
    moved[2] = nudged(moved[2])
    hand = dataclasses.replace(SCENE.hand, yaw=nudged(SCENE.hand.yaw))
    table = dataclasses.replace(SCENE.table, size=SCENE.table.size * 1.001)
    return {
        "robot": dataclasses.replace(SCENE, robot=SCENE.robot + "x"),
        "ee_link": dataclasses.replace(SCENE, ee_link=None),
        "base_position": dataclasses.replace(SCENE, base_position=moved),
        "base_rpy": dataclasses.replace(SCENE, base_rpy=SCENE.base_rpy + 1e-9),
        "table": dataclasses.replace(SCENE, table=table),
        "hand": dataclasses.replace(SCENE, hand=hand),
        "seat": dataclasses.replace(SCENE, seat=SCENE.seat[::-1].copy()),
        "distance": dataclasses.replace(SCENE, distance="ee_point"),
        "approach_scale": dataclasses.replace(SCENE, approach_scale=nudged(SCENE.approach_scale)),
        "pedestal": dataclasses.replace(SCENE, pedestal=Box(np.array([0.2, 0.2, 0.1]), np.array([0.0, 0.0, -0.05]))),
    }


def test_every_field_of_the_scene_is_part_of_the_key() -> None:
    variants = scene_variants()
    assert sorted(variants) == sorted(field.name for field in dataclasses.fields(SCENE))  # none left out
    key = verdict_key(ROBOT, SCENE, COMBINATION, DT)
    for name, changed in variants.items():
        assert verdict_key(ROBOT, changed, COMBINATION, DT) != key, name


def test_the_combination_the_step_and_the_robots_content_are_part_of_the_key() -> None:
    key = verdict_key(ROBOT, SCENE, COMBINATION, DT)
    path, standoff, speed = COMBINATION
    for changed in (("vertical", standoff, speed), (path, nudged(standoff), speed), (path, standoff, 0.3)):
        assert verdict_key(ROBOT, SCENE, changed, DT) != key, changed
    assert verdict_key(ROBOT, SCENE, COMBINATION, 0.01) != key
    assert verdict_key(ROBOT.replace("r", "s"), SCENE, COMBINATION, DT) != key


def test_equal_inputs_give_the_same_key_whatever_objects_hold_them() -> None:
    key = verdict_key(ROBOT, SCENE, COMBINATION, DT)
    assert verdict_key(ROBOT, copy.deepcopy(SCENE), list(COMBINATION), np.float64(DT)) == key
    assert exact_text(np.zeros(3)) != exact_text(np.zeros((3, 1)))  # the shape too
    assert exact_text(0.0) != exact_text(-0.0) and exact_text(1) != exact_text(True)


def test_a_value_of_an_unknown_kind_is_refused_not_left_out() -> None:
    with pytest.raises(TypeError, match="no exact text for set"):
        exact_text(dataclasses.replace(SCENE, robot={"a"}))


def test_a_kept_plan_is_taken_once_by_its_key_and_a_new_keeping_replaces_the_old() -> None:
    kept: Kept[str] = Kept()
    assert not kept and kept.take("a") is None
    kept.keep({"a": "plan a", "b": "plan b"})
    assert kept.take("c") is None and kept.take("a") == "plan a" and kept.take("a") is None
    kept.keep({"c": "plan c"})
    assert kept.take("b") is None and kept.take("c") == "plan c" and not kept
