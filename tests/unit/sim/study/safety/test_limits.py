"""sim.study.safety.limits: the Panda's published table, and one refusal line per limit a motion exceeds."""

from __future__ import annotations

import re

import numpy as np
import pytest

from sim.robots import load_robot
from sim.study.safety.errors import SafetyError
from sim.study.safety.limits import PANDA_LIMITS, limits_for, motion_refusals
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
