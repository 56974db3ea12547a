"""The scenarios by name: `build_motion` checks the options every scenario shares and calls the one asked for.
Pure logic."""

from __future__ import annotations

import math
from collections.abc import Callable

from sim.control.scenarios.ik import ik_motion
from sim.control.scenarios.joint_space import one_joint, single, sweep
from sim.control.scenarios.motion import Motion, ScenarioConfig, ScenarioError, checked_motion, sample_times
from sim.geometry.trajectory import ORDERS
from sim.robots import RobotSpec

__all__ = ["SCENARIOS", "OLD_SCENARIO_NAMES", "build_motion"]

_BUILDERS: dict[str, Callable[[RobotSpec, str, ScenarioConfig], Motion]] = {
    "single": single,
    "one_joint": one_joint,
    "ik_joints": ik_motion,
    "ik_cartesian": ik_motion,
    "ik_orientation": ik_motion,
    "fk_confirm": ik_motion,
    "sweep": sweep,
}
SCENARIOS: tuple[str, ...] = tuple(_BUILDERS)
# Scenario names that were renamed: still understood by the commands, which say the new name.
OLD_SCENARIO_NAMES = {"trial": "sweep"}


def build_motion(robot: RobotSpec, scenario: str, config: ScenarioConfig | None = None) -> Motion:
    """The desired motion of `scenario` for `robot` (sim.control.scenarios says what each one does)."""
    config = config or ScenarioConfig()
    if config.order not in ORDERS:
        raise ScenarioError(f"order must be one of {list(ORDERS)}, got {config.order!r}")
    if config.duration is not None and not (math.isfinite(config.duration) and config.duration > 0):
        raise ScenarioError(f"duration must be a finite number > 0 s, got {config.duration!r}")
    sample_times(1.0, config.dt)  # validates dt
    if config.ik_restarts < 0:
        raise ScenarioError(f"IK restarts must be >= 0, got {config.ik_restarts}")
    if scenario not in _BUILDERS:
        raise ScenarioError(f"unknown scenario {scenario!r}; known: {', '.join(SCENARIOS)}")
    return checked_motion(_BUILDERS[scenario](robot, scenario, config))
