"""A combination's approach as planned and checked (sim.study.design.feasibility): its joint motion, its distances
and clearances, and every problem found. Its own module, as the planner and the cache that keeps plans
(sim.study.design.kept_plans) both make one."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.study.design.paths import ApproachPath

__all__ = ["PlannedApproach"]


@dataclass
class PlannedApproach:
    path: ApproachPath
    positions: np.ndarray  # (N, dof) joint positions, rad or m
    velocities: np.ndarray  # (N, dof)
    reached_standoff: float  # m: the robot's distance to the hand at the last sample (the scene's definition)
    min_clearance: dict[str, float]  # smallest distance over the path: "table", "hand", "self"
    distances: np.ndarray  # (N,) m: the robot's distance to the hand at every sample (the scene's definition)
    problems: list[str] = field(default_factory=list)
    unreachable: int = 0  # samples IK could not reach
    remedies: list[str] = field(default_factory=list)  # what to change, one per kind of problem (REMEDIES)
    constraints: str = "pose"  # what IK kept along the path: a key of CONSTRAINTS

    @property
    def feasible(self) -> bool:
        return not self.problems
