"""A Panda approach planned as the study plans it (IK of every sample, the tool pointing down), without the scene's
collision world: what the safety tests brake along and check."""

from __future__ import annotations

import functools

import numpy as np

from sim.robots import load_robot
from sim.study.design.paths import ON_TOP, ApproachPath
from sim.study.design.scene import load_scene
from sim.study.safety.kinematic_plan import kinematic_plan

PANDA = load_robot("panda")


@functools.lru_cache(maxsize=None)
def panda_plan(name: str, peak_speed: float, dt: float = 0.02) -> tuple[ApproachPath, np.ndarray]:
    return kinematic_plan(PANDA, load_scene(), name, ON_TOP, peak_speed, dt)
