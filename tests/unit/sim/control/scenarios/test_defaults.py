"""Scenario defaults computed from the robot: every scenario builds on robots that are not ours, inside their limits,
and the computed values keep the rules the docstring of sim.control.scenarios.defaults states."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from sim.control.scenarios import SCENARIOS, ScenarioConfig, ScenarioError, build_motion, fk_path, pose_errors
from sim.control.scenarios.defaults import controllable_weights, sweep_table, usable_range
from sim.geometry.kinematics import PLANAR_WEIGHTS, chain_for
from sim.robots import load_robot
from tests.robot_files import LIFT_ARM, THIRD_PARTY_URDFS


@pytest.fixture(scope="module", params=sorted(THIRD_PARTY_URDFS))
def robot(request):
    return load_robot(str(THIRD_PARTY_URDFS[request.param]))


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_every_scenario_builds_on_a_robot_that_is_not_ours(robot, scenario):
    motion = build_motion(robot, scenario, ScenarioConfig(dt=0.02))
    assert robot.within_limits(motion.positions.min(axis=0)) and robot.within_limits(motion.positions.max(axis=0))
    assert not [w for w in motion.warnings if "peaks at" in w]  # computed motions respect the velocity limits
    if motion.ik is not None:
        assert motion.ik.success
        final = chain_for(robot).fk(motion.positions[-1])
        position_error, rotation_error = pose_errors(final[None], motion.goal[None], motion.ik.weights)
        assert position_error[0] < 1e-5 and rotation_error[0] < 1e-4


def test_the_trial_never_crosses_zero_and_stays_slow(robot):
    centres, amplitudes = sweep_table(robot)
    lower, upper = usable_range(robot)
    assert np.all(centres - amplitudes >= lower) and np.all(centres + amplitudes <= upper)
    assert np.all(np.sign(centres - amplitudes) == np.sign(centres + amplitudes))
    assert np.all(amplitudes > 0)
    motion = build_motion(robot, "sweep")
    assert np.all(np.abs(motion.velocities).max(axis=0) <= 0.5 * robot.max_velocity + 1e-9)


def test_computed_one_joint_waypoints_are_slowed_to_the_velocity_limit(tmp_path):
    shutil.copy(LIFT_ARM, tmp_path / "slow_lift.urdf")
    (tmp_path / "slow_lift.yaml").write_text("ee_link: tool_tip\nlimits:\n  lift: {velocity: 0.05}\n")
    slow = load_robot(str(tmp_path / "slow_lift.urdf"))
    motion = build_motion(slow, "one_joint")
    assert np.abs(motion.velocities[:, 0]).max() == pytest.approx(0.8 * 0.05, rel=1e-6)
    fast = build_motion(load_robot(str(LIFT_ARM)), "one_joint")  # 0.3 m/s: the waypoints need no slowing
    assert np.abs(fast.velocities[:, 0]).max() < 0.8 * 0.3
    assert not np.allclose(fast.positions[:, 0], motion.positions[:, 0])


@pytest.mark.parametrize(
    "name, expected",
    [
        ("panda", (1.0,) * 6),
        ("igt", PLANAR_WEIGHTS),
    ],
)
def test_ik_weights_are_the_axes_the_chain_controls(name, expected):
    robot = load_robot(name)
    assert controllable_weights(chain_for(robot), robot.home) == expected


def test_a_four_joint_arm_controls_position_and_yaw():
    arm = load_robot(str(THIRD_PARTY_URDFS["lift_arm"]))
    assert controllable_weights(chain_for(arm), arm.home) == (1.0, 1.0, 1.0, 0.0, 0.0, 1.0)
    assert build_motion(arm, "ik_joints").ik.weights == (1.0, 1.0, 1.0, 0.0, 0.0, 0.0)  # a position goal
    assert build_motion(arm, "ik_orientation").ik.weights == (1.0, 1.0, 1.0, 0.0, 0.0, 1.0)


def test_given_weights_win_and_are_validated():
    panda = load_robot("panda")
    motion = build_motion(panda, "ik_joints", ScenarioConfig(weights=(1, 1, 1, 0, 0, 1), goal_rpy=(3.14, 0, 0)))
    assert motion.ik.weights == (1, 1, 1, 0, 0, 1)
    for bad, message in (((1, 1, 1), "needs 6 values"), ((0,) * 6, "at least one > 0"), ((1, -1, 0, 0, 0, 0), ">= 0")):
        with pytest.raises(ScenarioError, match=message):
            build_motion(panda, "ik_joints", ScenarioConfig(weights=bad))


def test_the_ik_goal_is_reached_along_a_straight_line_on_a_third_party_arm():
    xarm = load_robot(str(THIRD_PARTY_URDFS["xarm6"]))
    motion = build_motion(xarm, "ik_cartesian")
    path = fk_path(chain_for(xarm), motion.positions)[:, :3, 3]
    start, goal = path[0], motion.goal[:3, 3]
    direction = (goal - start) / np.linalg.norm(goal - start)
    off_line = path - start - np.outer((path - start) @ direction, direction)
    assert np.linalg.norm(goal - start) > 0.05 and np.abs(off_line).max() < 1e-5
