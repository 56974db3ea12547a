"""sim.control.scenarios.ik: goals reached (FK of the desired joints), straight Cartesian lines, unreachable goals
reported with their residual, the nearest-pose fallback."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.control.scenarios import (
    IK_SCENARIOS,
    ScenarioConfig,
    ScenarioError,
    UnreachableGoalError,
    build_motion,
    fk_path,
    pose_errors,
)
from sim.geometry.frames import rpy_to_matrix
from sim.geometry.kinematics import chain_for
from sim.robots import load_robot


@pytest.mark.parametrize("scenario", IK_SCENARIOS)
def test_ik_scenarios_reach_their_goal_by_fk_of_the_desired_joints(robot, scenario):
    motion = build_motion(robot, scenario)
    chain = chain_for(robot)
    assert motion.ik is not None and motion.ik.success and not motion.ik.fallback
    assert motion.goal is not None and motion.reference_path is not None
    final = chain.fk(motion.positions[-1])
    pos_err, rot_err = pose_errors(final[None], motion.goal[None], motion.ik.weights)
    assert pos_err[0] < 1e-5 and rot_err[0] < 1e-4
    # The motion starts at the start pose: home for the defaults.
    np.testing.assert_allclose(chain.fk(motion.positions[0])[:3, 3], chain.fk(robot.home)[:3, 3], atol=1e-6)
    # The desired joints follow the reference path all along.
    pos_path, rot_path = pose_errors(fk_path(chain, motion.positions), motion.reference_path, motion.ik.weights)
    assert pos_path.max() < 1e-5 and rot_path.max() < 1e-4


def test_panda_goals_and_weights():
    panda = load_robot("panda")
    position_only = build_motion(panda, "ik_joints")
    np.testing.assert_allclose(position_only.goal[:3, 3], [0.5, 0.375, 0.75])
    assert position_only.ik.weights == (1, 1, 1, 0, 0, 0)
    oriented = build_motion(panda, "ik_orientation")
    np.testing.assert_allclose(oriented.goal[:3, 3], [0.3, 0.5, 0.75])
    np.testing.assert_allclose(oriented.goal[:3, :3], rpy_to_matrix(math.pi / 4, math.pi / 5, math.pi / 3))
    assert oriented.ik.weights == (1, 1, 1, 1, 1, 1)
    np.testing.assert_allclose(chain_for(panda).fk(oriented.positions[-1]), oriented.goal, atol=1e-6)


def test_ik_cartesian_is_a_straight_line_and_reports_the_joint_jump():
    panda = load_robot("panda")
    motion = build_motion(panda, "ik_cartesian")
    path = fk_path(chain_for(panda), motion.positions)[:, :3, 3]
    start, goal = path[0], motion.goal[:3, 3]
    direction = (goal - start) / np.linalg.norm(goal - start)
    off_line = path - start - np.outer((path - start) @ direction, direction)
    assert np.abs(off_line).max() < 1e-5
    assert 0 < motion.ik.max_joint_jump < 0.05


@pytest.mark.parametrize("scenario", ["ik_joints", "ik_cartesian", "ik_orientation"])
def test_unreachable_goal_is_reported_with_the_residual(robot, scenario):
    far = (1.5, 0.0, 0.5) if robot.name == "panda" else (1.2, 0.3)
    with pytest.raises(UnreachableGoalError, match="unreachable: best residual") as info:
        build_motion(robot, scenario, ScenarioConfig(goal=far, ik_restarts=3))
    assert info.value.position_error > 0.1


def test_nearest_fallback_is_explicit_and_heads_for_a_reachable_pose(robot):
    far = (1.5, 0.0, 0.5) if robot.name == "panda" else (1.2, 0.3)
    motion = build_motion(robot, "ik_cartesian", ScenarioConfig(goal=far, nearest=True, ik_restarts=3))
    assert motion.ik.fallback and not motion.ik.success
    assert motion.ik.goal_position_error > 0.1
    assert any(w.startswith("FALLBACK: goal unreachable") for w in motion.warnings)
    assert motion.ik.failed_samples == 0  # the path to the nearest pose itself is feasible


def test_igt_rejects_roll_and_pitch():
    with pytest.raises(ScenarioError, match="igt can only reach x, y and yaw: goal rpy"):
        build_motion(load_robot("igt"), "ik_joints", ScenarioConfig(goal_rpy=(0.1, 0.0, 0.5)))
