"""The approaches' IK on every test arm (the Panda, the arms labs have and the study's own, sim.robots.examples):
one branch per approach, continuous along every bundled path; what an arm of fewer than six joints keeps; and the
paths sized to each arm. Pure logic: the arms' URDFs are written, their scenes built without pybullet."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sim.geometry.kinematics import chain_for
from sim.robots import RobotSpec, load_robot
from sim.robots.examples import LAB_ARM_EE_LINKS, LAB_ARMS, STUDY_ARMS
from sim.study.design.feasibility import BRANCH_JUMP, approach_targets, solve_approach
from sim.study.design.fit import (
    HAND_FRACTIONS,
    SIZE_FRACTION,
    TABLE_DROPS,
    candidate_scene,
    path_scale,
    proportions,
    screen,
)
from sim.study.design.paths import ON_TOP, PATH_NAMES, approach_path
from sim.study.design.scene import Scene, load_scene, scene_robot
from sim.study.design.tool import tool_axis
from sim.wire.contract import STEP_S
from tests.robot_files import LIFT_ARM
from tests.study_arms import study_arm

TEMPLATE = load_scene()
ARMS = ("panda", *LAB_ARMS, *(design.name for design in STUDY_ARMS))
COMBINATIONS = [(name, standoff, 0.3) for name in PATH_NAMES for standoff in (ON_TOP, 0.15)]


def arm(name: str, folder: Path) -> RobotSpec:
    if name == "panda":
        return scene_robot(TEMPLATE)
    ee_link = LAB_ARM_EE_LINKS.get(name)
    return load_robot(str(study_arm(folder, name)), **({"ee_link": ee_link} if ee_link else {}))


def sized_scene(robot: RobotSpec) -> Scene:
    """The Panda's bundled scene; for another arm, the first candidate of the proposal's (the hand out at a fraction
    of its reach, the table at its base or lower, the paths sized) whose approaches' starts and ends IK reaches: what
    `sim.study scene` then checks in pybullet."""
    if robot.name == "panda":
        return TEMPLATE
    chain = chain_for(robot)
    found = proportions(robot, chain)
    for strict in (True, False):  # an arm of fewer than six joints: where it points its tool down first, as fit_scene
        for drop in TABLE_DROPS:
            for hand in HAND_FRACTIONS:
                scene = candidate_scene(TEMPLATE, robot, hand * found.reach, -drop * found.reach)
                scene = dataclasses.replace(scene, approach_scale=path_scale(scene, found, PATH_NAMES))
                if not screen(robot, chain, scene, COMBINATIONS, STEP_S, strict):
                    return scene
    raise AssertionError(f"no candidate scene for {robot.name}")


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("arms")


@pytest.mark.parametrize("name", ARMS)
def test_every_bundled_path_is_one_continuous_ik_branch(name: str, folder: Path) -> None:
    robot = arm(name, folder)
    chain, scene = chain_for(robot), sized_scene(robot)
    for path_name in PATH_NAMES:
        for standoff in (ON_TOP, 0.15):
            path = approach_path(scene, path_name, standoff, 0.3)
            targets = approach_targets(chain, robot, scene, path)
            solved, kept = solve_approach(chain, robot, scene, targets)
            where = f"{name}, {path_name} to {standoff} m, kept {kept}"
            assert solved.all_succeeded, where
            jumps = np.abs(np.diff(solved.q, axis=0)).max()
            assert jumps < BRANCH_JUMP, f"{where}: a joint jumps by {jumps:.2f} rad between two samples"
            ends = np.array([chain.fk(q)[:3, 3] for q in solved.q])
            assert np.allclose(ends, targets[:, :3, 3], atol=1e-4), where  # the path itself, whatever was kept
            axis = tool_axis(chain, robot.home)
            for q in solved.q[:: max(1, len(solved.q) // 5)]:
                rotation = chain.fk(q)[:3, :3]
                if kept == "pose":
                    assert np.allclose(rotation, targets[0, :3, :3], atol=1e-3), where
                if kept in ("pose", "axis"):  # the tool points down
                    assert np.allclose(rotation @ axis, [0.0, 0.0, -1.0], atol=1e-3), where


def test_the_ur5_keeps_the_whole_pose_and_the_scara_the_tool_axis(folder: Path) -> None:
    kept = {}
    for name in ("ur5_like", "scara_like"):
        robot = arm(name, folder)
        chain, scene = chain_for(robot), sized_scene(robot)
        path = approach_path(scene, "vertical", 0.1, 0.15)
        kept[name] = solve_approach(chain, robot, scene, approach_targets(chain, robot, scene, path))[1]
    assert kept == {"ur5_like": "pose", "scara_like": "axis"}


def test_a_small_arms_paths_shrink_to_its_reach_and_a_large_ones_less(folder: Path) -> None:
    large = arm("ur5_like", folder)
    assert sized_scene(large).approach_scale > sized_scene(arm("widowx_like", folder)).approach_scale
    small = arm("widowx_like", folder)
    found = proportions(small, chain_for(small))
    scene = sized_scene(small)
    assert 0.3 <= scene.approach_scale < 1.0
    for path_name in PATH_NAMES:  # the wrist over every start within the fraction of the reach from the shoulder
        wrist = approach_path(scene, path_name, 0.05, 0.15).start + [0.0, 0.0, found.tool]
        assert (
            np.linalg.norm(scene.to_base(wrist) - found.shoulder) <= SIZE_FRACTION * (found.reach - found.tool) + 1e-9
        )


def test_an_arm_that_cannot_point_its_tool_down_is_told_so_and_keeps_the_position() -> None:
    # the four-joint lift arm (lift, shoulder yaw, elbow pitch, a wrist rolling about the forearm): 0.7 m out, the
    # vertical path's start is within its reach, but not with its tool pointing down
    robot = load_robot(str(LIFT_ARM))
    chain = chain_for(robot)
    scene = candidate_scene(TEMPLATE, robot, 0.7, 0.0)
    vertical = [("vertical", 0.1, 0.15)]
    assert screen(robot, chain, scene, vertical, STEP_S, strict=True) == (
        "the arm cannot point the tool down at the vertical path's start"
    )
    assert screen(robot, chain, scene, vertical, STEP_S) == ""
    path = approach_path(scene, "vertical", 0.1, 0.15)
    solved, kept = solve_approach(chain, robot, scene, approach_targets(chain, robot, scene, path))
    assert kept == "position" and solved.all_succeeded
