"""A fit's plans handed on (Approaches.hand_on, sim.study.design.verdicts): the next planner of exactly the same
robot, scene, combination and step takes them, in whatever order it asks, and gets what planning again gives; a
changed stand-off, step, scene or URDF is planned afresh."""

from __future__ import annotations

import copy
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sim.robots import load_robot
from sim.robots.examples import STUDY_ARMS, write_arm
from sim.study.design.feasibility import FITTED, Approaches, PlannedApproach, plan_combinations
from sim.study.design.scene import load_scene, scene_robot
from sim.wire.contract import STEP_S

SCENE = load_scene()
PANDA = scene_robot(SCENE)
SHORT = ("vertical", 0.25, 0.15)  # the design's shortest approach
OTHER = ("straight", 0.25, 0.15)


@pytest.fixture(autouse=True)
def nothing_kept():
    FITTED.keep({})
    yield
    FITTED.keep({})


def handed_on(robot, scene, combinations) -> dict:
    with Approaches(robot, scene, STEP_S) as fitting:
        planned = fitting.plan_all(combinations)
        fitting.hand_on()
    return planned


def same_plan(a: PlannedApproach, b: PlannedApproach) -> bool:
    arrays = ("positions", "velocities", "distances")
    return (
        all(np.array_equal(getattr(a, name), getattr(b, name)) for name in arrays)
        and (a.reached_standoff, a.min_clearance, a.problems, a.constraints)
        == (b.reached_standoff, b.min_clearance, b.problems, b.constraints)
        and np.array_equal(a.path.positions, b.path.positions)
    )


def test_the_same_input_takes_the_fits_plans_in_any_order_and_they_are_what_planning_again_gives() -> None:
    fitted = handed_on(PANDA, SCENE, [SHORT, OTHER])
    taken = plan_combinations(PANDA, copy.deepcopy(SCENE), [OTHER, SHORT], STEP_S)  # as check asks, in its order
    assert list(taken) == [OTHER, SHORT] and all(taken[c] is fitted[c] for c in taken) and not FITTED
    again = plan_combinations(PANDA, SCENE, [OTHER, SHORT], STEP_S)  # nothing kept now: planned
    assert all(again[c] is not fitted[c] and same_plan(again[c], fitted[c]) for c in again)


def test_a_changed_stand_off_step_or_scene_is_planned_afresh() -> None:
    fitted = handed_on(PANDA, SCENE, [SHORT])[SHORT]
    moved = dataclasses.replace(SCENE, hand=dataclasses.replace(SCENE.hand, position=SCENE.hand.position + 0.001))
    path, standoff, speed = SHORT
    changed = [(SCENE, (path, 0.2, speed), STEP_S), (SCENE, SHORT, STEP_S / 2), (moved, SHORT, STEP_S)]
    for scene, combination, dt in changed:
        planned = plan_combinations(PANDA, scene, [combination], dt)[combination]
        assert planned is not fitted, (combination, dt)
    assert plan_combinations(PANDA, SCENE, [SHORT], STEP_S)[SHORT] is fitted  # (still kept for the same input)


def test_an_edited_urdf_is_planned_afresh(tmp_path: Path) -> None:
    urdf = write_arm(tmp_path, next(design for design in STUDY_ARMS if design.overlapping_meshes))
    robot = load_robot(str(urdf))
    scene = dataclasses.replace(SCENE, robot=str(urdf), ee_link=robot.ee_link)
    fitted = handed_on(robot, scene, [SHORT])[SHORT]
    text = urdf.read_text(encoding="utf-8")
    urdf.write_text(text + "<!-- edited -->\n", encoding="utf-8")
    assert plan_combinations(load_robot(str(urdf)), scene, [SHORT], STEP_S)[SHORT] is not fitted
    urdf.write_text(text, encoding="utf-8")
    assert plan_combinations(robot, scene, [SHORT], STEP_S)[SHORT] is fitted
