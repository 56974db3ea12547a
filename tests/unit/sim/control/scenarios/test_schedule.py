"""sim.control.scenarios.schedule: the approach to a motion's start and the schedule streamed."""

from __future__ import annotations

import numpy as np

from sim.control.scenarios import (
    ScenarioConfig,
    approach,
    build_motion,
    build_schedule,
)


def test_approach_reaches_target_within_speed_fraction(robot):
    q_to = robot.home + 0.1 * (robot.upper - robot.home)
    positions, velocities = approach(robot, robot.home, q_to, 0.02)
    np.testing.assert_array_equal(positions[0], robot.home)
    np.testing.assert_allclose(positions[-1], q_to)
    assert np.all(np.abs(velocities).max(axis=0) <= 0.5 * robot.max_velocity + 1e-9)
    assert len(positions) >= 101  # at least 2 s


def test_schedule_prepends_an_approach_only_when_needed(robot):
    motion = build_motion(robot, "sweep", ScenarioConfig(duration=1.0))
    direct = build_schedule(motion, motion.positions[0])
    assert direct.approach_steps == 0 and len(direct.positions) == len(motion.times)
    assert build_schedule(motion, None).approach_steps == 0
    assert build_schedule(motion, robot.home, approach_min_s=0.0).approach_steps == 0
    schedule = build_schedule(motion, robot.home)
    m = schedule.approach_steps
    assert m >= 100
    np.testing.assert_array_equal(schedule.positions[0], robot.home)
    np.testing.assert_array_equal(schedule.positions[m:], motion.positions)
    np.testing.assert_array_equal(schedule.motion_index[m:], np.arange(len(motion.times)))
    assert np.all(schedule.motion_index[:m] == -1)
    # Continuous at the joint between approach and motion (both at rest there).
    assert np.abs(np.diff(schedule.positions, axis=0)).max() < 0.05
