"""A Panda approach planned as the study plans it (IK of every sample, the tool pointing down), without the scene's
collision world: what the safety tests brake along and check."""

from __future__ import annotations

import functools

import numpy as np

from sim.control.scenarios.defaults import controllable_weights
from sim.geometry.kinematics import chain_for, solve_ik, solve_path_ik
from sim.robots import load_robot
from sim.study.design.paths import ON_TOP, ApproachPath, approach_path
from sim.study.design.scene import load_scene
from sim.study.design.tool import approach_rotation

PANDA = load_robot("panda")


@functools.lru_cache(maxsize=None)
def panda_plan(name: str, peak_speed: float, dt: float = 0.02) -> tuple[ApproachPath, np.ndarray]:
    scene = load_scene()
    path = approach_path(scene, name, ON_TOP, peak_speed=peak_speed, dt=dt)
    chain = chain_for(PANDA)
    weights = controllable_weights(chain, PANDA.home)
    targets = np.tile(chain.fk(PANDA.home), (len(path.times), 1, 1))
    targets[:, :3, :3] = approach_rotation(chain, PANDA.home, scene.to_base_direction(np.array([0.0, 0.0, -1.0])))
    targets[:, :3, 3] = scene.to_base(path.positions)
    first = solve_ik(chain, targets[0], PANDA.home, weights=weights, restarts=20, rng=0)
    solved = solve_path_ik(chain, targets, first.q, weights=weights)
    assert solved.all_succeeded
    return path, solved.q
