"""sim.control.scenarios.build: every scenario by name builds on the dt grid, inside the limits, from rest."""

from __future__ import annotations

import numpy as np
import pytest

from sim.control.scenarios import (
    SCENARIOS,
    ScenarioConfig,
    ScenarioError,
    build_motion,
)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_every_scenario_builds_on_the_dt_grid_inside_limits_from_rest(robot, scenario):
    motion = build_motion(robot, scenario, ScenarioConfig(dt=0.02))
    n = len(motion.times)
    assert motion.positions.shape == motion.velocities.shape == (n, robot.dof)
    np.testing.assert_array_equal(motion.times, np.arange(n) * 0.02)
    assert robot.within_limits(motion.positions.min(axis=0)) and robot.within_limits(motion.positions.max(axis=0))
    np.testing.assert_allclose(motion.velocities[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(motion.velocities[-1], 0.0, atol=1e-9)
    # Velocities are consistent with the positions (central differences, interior samples).
    finite = (motion.positions[2:] - motion.positions[:-2]) / (2 * 0.02)
    np.testing.assert_allclose(motion.velocities[1:-1], finite, atol=0.02 * max(1.0, np.abs(finite).max()))


def test_unknown_scenario_is_named(robot):
    with pytest.raises(ScenarioError, match="unknown scenario 'dance'"):
        build_motion(robot, "dance")
