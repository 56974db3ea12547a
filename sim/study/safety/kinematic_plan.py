"""An approach planned as the study plans it, without the scene's collision world: the path's samples solved by IK
with the tool pointing down, from the robot's home. What the safety tests and the braking bench brake along and
check. Pure (no I/O)."""

from __future__ import annotations

import numpy as np

from sim.control.scenarios.defaults import controllable_weights
from sim.geometry.kinematics import chain_for, solve_ik, solve_path_ik
from sim.robots import RobotSpec
from sim.study.design.paths import ApproachPath, approach_path
from sim.study.design.scene import Scene
from sim.study.design.tool import approach_rotation
from sim.study.safety.errors import SafetyError

__all__ = ["kinematic_plan"]


def kinematic_plan(
    robot: RobotSpec, scene: Scene, name: str, standoff: float, peak_speed: float, dt: float
) -> tuple[ApproachPath, np.ndarray]:
    """The approach `name` to `standoff` m at `peak_speed` m/s, sampled every `dt` s, and its joint positions (one row
    a sample); SafetyError when a sample has no IK solution."""
    path = approach_path(scene, name, standoff, peak_speed=peak_speed, dt=dt)
    chain = chain_for(robot)
    weights = controllable_weights(chain, robot.home)
    targets = np.tile(chain.fk(robot.home), (len(path.times), 1, 1))
    targets[:, :3, :3] = approach_rotation(chain, robot.home, scene.to_base_direction(np.array([0.0, 0.0, -1.0])))
    targets[:, :3, 3] = scene.to_base(path.positions)
    first = solve_ik(chain, targets[0], robot.home, weights=weights, restarts=20, rng=0)
    solved = solve_path_ik(chain, targets, first.q, weights=weights)
    if not solved.all_succeeded:
        raise SafetyError(f"the {name} approach to {standoff:g} m has no IK solution for {robot.name}")
    return path, solved.q
