"""sim.study.safety.limits: the makers' published tables, each picked for its robot; one refusal line per limit a motion
exceeds, positions past the URDF's range too; and what the check says it did not check."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from sim.robots import load_robot
from sim.robots.examples import write_lab_arm
from sim.study.safety.errors import SafetyError
from sim.study.safety.limits import (
    IIWA7_LIMITS,
    IIWA14_LIMITS,
    KNOWN_TABLES,
    PANDA_LIMITS,
    UR5_LIMITS,
    UR10_LIMITS,
    XARM6_LIMITS,
    PublishedLimits,
    coverage,
    limits_for,
    motion_refusals,
    table_for,
)
from tests.robot_files import THIRD_PARTY_URDFS
from tests.unit.sim.study.safety.plans import PANDA, panda_plan

TIMES = np.arange(0.0, 2.0, 0.002)


def test_the_panda_gets_its_published_table_and_another_arm_its_urdf_alone() -> None:
    limits = limits_for(PANDA)
    np.testing.assert_allclose(limits.velocity, [2.175] * 4 + [2.61] * 3)
    np.testing.assert_allclose(limits.acceleration, [15, 7.5, 10, 12.5, 15, 20, 20])
    np.testing.assert_allclose(limits.jerk, [7500, 3750, 5000, 6250, 7500, 10000, 10000])
    assert (limits.cartesian_velocity, limits.cartesian_acceleration, limits.cartesian_jerk) == (1.7, 13.0, 6500.0)
    igt = load_robot("igt")
    urdf_only = limits_for(igt)
    assert urdf_only.acceleration is None and urdf_only.jerk is None and urdf_only.source == "URDF"
    np.testing.assert_allclose(urdf_only.velocity, igt.max_velocity)
    with pytest.raises(SafetyError, match="7 joint velocity limits for igt"):
        limits_for(igt, PANDA_LIMITS)


def test_a_motion_beyond_the_pandas_acceleration_limit_is_refused_in_one_line_naming_it() -> None:
    joints = np.tile(PANDA.home, (len(TIMES), 1))
    joints[:, 1] += 0.125 * np.sin(8.0 * TIMES)  # 1 rad/s, 8 rad/s², 64 rad/s³ on panda_joint2
    (line,) = motion_refusals("approach straight", TIMES, joints, limits_for(PANDA), margin=0.8)
    assert re.match(r"approach straight: panda_joint2 acceleration 7\.99\d rad/s² at t = \d\.\d\d s", line), line
    assert "exceeds 6.000, 80% of its limit 7.5 (URDF and Franka Control Interface limits for the Panda)" in line
    joints = np.tile(PANDA.home, (len(TIMES), 1))
    joints[:, 0] += 0.125 * np.sin(8.0 * TIMES)  # the same on panda_joint1, whose limit is 15 rad/s²
    assert motion_refusals("approach straight", TIMES, joints, limits_for(PANDA), margin=0.8) == []


def test_the_end_effectors_cartesian_limits_and_the_margin_are_checked() -> None:
    joints = np.tile(PANDA.home, (len(TIMES), 1))
    world = np.column_stack([1.5 * TIMES, np.zeros_like(TIMES), np.zeros_like(TIMES)])  # 1.5 m/s
    (line,) = motion_refusals("plan", TIMES, joints, limits_for(PANDA), 0.8, world_positions=world)
    assert "the end effector's velocity 1.500 m/s" in line and "80% of its limit 1.7" in line
    for margin in (0.0, 1.5, float("nan")):
        with pytest.raises(SafetyError, match="safety margin"):
            motion_refusals("plan", TIMES, joints, limits_for(PANDA), margin)


def test_a_planned_panda_approach_is_checked_sample_by_sample() -> None:
    path, joints = panda_plan("diagonal", 0.5)
    assert motion_refusals("diagonal", path.times, joints, limits_for(PANDA), world_positions=path.positions) == []
    path, joints = panda_plan("straight", 0.3)  # past the wrist's singularity: joint 5 whips round
    refusals = motion_refusals("straight", path.times, joints, limits_for(PANDA))
    assert any("panda_joint5 velocity" in line for line in refusals)
    assert any("acceleration" in line for line in refusals)


@pytest.mark.parametrize("table", KNOWN_TABLES, ids=lambda table: table.robots[0])
def test_each_published_table_has_a_positive_figure_per_joint_or_says_why_it_has_none(table: PublishedLimits) -> None:
    joints = len(table.joints[0])
    assert all(len(naming) == joints for naming in table.joints) and table.robots and table.source
    for values in (table.velocity, table.acceleration, table.jerk):
        assert values is None or (len(values) == joints and all(v > 0 for v in values))
    cartesian = (table.cartesian_velocity, table.cartesian_acceleration, table.cartesian_jerk)
    assert all(v is None or v > 0 for v in cartesian)
    unknown = table.acceleration is None or table.jerk is None or None in cartesian
    assert bool(table.unpublished) == unknown  # a missing kind is said, never made up


def test_the_makers_figures_are_the_published_ones() -> None:
    np.testing.assert_allclose(np.degrees(UR5_LIMITS.velocity), [180] * 6)
    np.testing.assert_allclose(np.degrees(UR10_LIMITS.velocity), [120, 120, 180, 180, 180, 180])
    np.testing.assert_allclose(np.degrees(IIWA14_LIMITS.velocity), [85, 85, 100, 75, 130, 135, 135])
    np.testing.assert_allclose(np.degrees(IIWA7_LIMITS.velocity), [98, 98, 100, 130, 140, 180, 180])
    assert XARM6_LIMITS.velocity == (3.14,) * 6
    assert all(t.acceleration is None and t.jerk is None for t in KNOWN_TABLES if t is not PANDA_LIMITS)


def test_each_table_is_picked_for_its_robot_by_name_and_joints(tmp_path: Path) -> None:
    iiwa = load_robot(str(THIRD_PARTY_URDFS["lbr_iiwa"]))
    xarm6 = load_robot(str(THIRD_PARTY_URDFS["xarm6"]))
    ur5_like = load_robot(str(write_lab_arm(tmp_path, "ur5_like")), ee_link="tool0")
    assert table_for(PANDA) is PANDA_LIMITS and table_for(load_robot("igt")) is None
    assert table_for(iiwa) is IIWA14_LIMITS  # pybullet's lbr_iiwa is the 14; the slower of the two in any case
    assert table_for(dataclasses.replace(iiwa, name="lbr_iiwa_7_r800")) is IIWA7_LIMITS  # the longest name fits
    assert table_for(xarm6) is XARM6_LIMITS and table_for(ur5_like) is UR5_LIMITS
    assert table_for(dataclasses.replace(ur5_like, name="ur10_robot")) is UR10_LIMITS
    assert table_for(dataclasses.replace(ur5_like, name="ur5e")) is None  # the e-series is another robot
    np.testing.assert_allclose(limits_for(iiwa).velocity, IIWA14_LIMITS.velocity)  # below its URDF's 10 rad/s
    with pytest.raises(SafetyError, match="6 joint velocity limits for ur5's 7 joints"):
        table_for(dataclasses.replace(iiwa, name="ur5"))
    with pytest.raises(SafetyError, match=r"xarm6's joints \(joint1, .*\) are not the table's \(shoulder_pan_joint"):
        limits_for(xarm6, UR5_LIMITS)


def test_a_sample_past_a_joints_position_limit_is_refused_naming_the_joint_the_value_and_the_limit() -> None:
    joints = np.tile(PANDA.home, (len(TIMES), 1))
    joints[:, 3] = np.linspace(-1.0, 0.05, len(TIMES))  # panda_joint4's upper limit is -0.0698
    (line,) = motion_refusals("approach straight", TIMES, joints, limits_for(PANDA))
    said = "approach straight: panda_joint4 position 0.0500 rad at t = 2.00 s is past its upper limit -0.0698 (URDF)"
    assert line == said
    assert motion_refusals("approach straight", TIMES[:2], joints[-2:], limits_for(PANDA))  # even with 2 samples


def test_what_was_not_checked_is_said_for_a_robot_without_a_table_and_for_a_table_without_a_kind(
    tmp_path: Path,
) -> None:
    within, unchecked = coverage("panda", limits_for(PANDA), 0.8)
    assert within.startswith("within panda's joint position limits and, at 80%, its joint velocity, acceleration and")
    assert unchecked == ""
    within, unchecked = coverage("igt", limits_for(load_robot("igt")), 0.8)
    assert within == "within igt's joint position limits and, at 80%, its joint velocity limits (URDF)"
    unknown = "joint acceleration and jerk; the end effector's velocity, acceleration and jerk"
    assert unchecked == f"{unknown} (no published table for igt)"
    ur5_like = load_robot(str(write_lab_arm(tmp_path, "ur5_like")), ee_link="tool0")
    within, unchecked = coverage("ur5_like", limits_for(ur5_like), 0.5)
    assert "at 50%, its joint velocity limits (URDF and UR5 (CB3) user manual" in within
    assert unchecked.startswith(f"{unknown} (Universal Robots publish none")
