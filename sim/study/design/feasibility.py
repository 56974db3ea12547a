"""An approach path made joint motion and checked before it is ever run: IK of every sample
(sim.geometry.kinematics), joint position and velocity limits, no contact with the table, the hand or the robot
itself (pybullet's collision shapes; of its own link pairs only those that can really meet, see
sim.engine.self_contact), and the stand-off actually reached (FK of the planned end). An infeasible
combination is reported with every reason, never run. Distances to the hand are the scene's (Scene.distance):
by default from the robot's collision geometry, so a path's end is where its nearest surface is the stand-off.

The end effector keeps one orientation throughout, on the axes its chain controls (sim.control.scenarios.defaults):
its tool pointing straight down, turned the least from home (sim.study.design.tool; the Panda's is its home's).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Tuple

import numpy as np

from sim.control.scenarios.defaults import controllable_weights
from sim.geometry.kinematics import chain_for, solve_ik, solve_path_ik
from sim.robots import RobotSpec
from sim.study.design.errors import DesignError
from sim.study.design.paths import ApproachPath, approach_path
from sim.study.design.scene import Scene
from sim.study.design.tool import approach_rotation
from sim.study.design.world import CONTACT_MARGIN, SceneWorld

__all__ = [
    "REMEDIES",
    "remedies",
    "Approaches",
    "CONTACT_MARGIN",
    "STANDOFF_TOLERANCE",
    "Combination",
    "PlannedApproach",
    "SceneWorld",
    "plan_approach",
    "plan_combination",
    "plan_combinations",
]

STANDOFF_TOLERANCE = 0.002  # m: FK of the planned end vs the path's stand-off
_IK_RESTARTS = 20
_STANDOFF_ROUNDS = 4

# path name, stand-off (m), peak speed (m/s); typing.Tuple, as an alias is evaluated at run time (3.8 has no tuple[])
Combination = Tuple[str, float, float]


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

    @property
    def feasible(self) -> bool:
        return not self.problems


# What to change, by the kind of problem: said with the combinations that are not feasible
REMEDIES = {
    "reach": "the hand within the arm's reach (the scene's hand.xyz), or the scene `sim.study scene` proposes",
    "limits": "another path, or the hand placed elsewhere",
    "speed": "a lower peak speed",
    "table": "a larger stand-off, or the table lower",
    "hand": "a larger stand-off, or another path",
    "self": "another path, or the hand placed elsewhere",
    "standoff": "another stand-off, or the hand placed elsewhere",
}


def remedies(approaches: Iterable[PlannedApproach]) -> str:
    """What to change for these approaches, each remedy once: "" when all are feasible."""
    return "; ".join(dict.fromkeys(remedy for approach in approaches for remedy in approach.remedies))


def plan_approach(robot: RobotSpec, scene: Scene, path: ApproachPath, world: SceneWorld) -> PlannedApproach:
    """Joint motion for `path` (IK of every sample from home's end-effector orientation), checked (module doc)."""
    chain = chain_for(robot)
    home_pose = chain.fk(robot.home)
    weights = controllable_weights(chain, robot.home)
    targets = np.tile(home_pose, (len(path.times), 1, 1))
    targets[:, :3, :3] = approach_rotation(chain, robot.home, scene.to_base_direction(np.array([0.0, 0.0, -1.0])))
    targets[:, :3, 3] = scene.to_base(path.positions)
    problems: list[str] = []
    kinds: list[str] = []
    first = solve_ik(chain, targets[0], robot.home, weights=weights, restarts=_IK_RESTARTS, rng=0)
    solved = solve_path_ik(chain, targets, first.q, weights=weights)
    if not solved.all_succeeded:
        failed = np.flatnonzero(~solved.success)
        where = path.positions[failed[0]]
        reach = float(np.linalg.norm(scene.to_base(where)))
        problems.append(
            f"IK failed at {failed.size} of {len(path.times)} samples, first at t = {path.times[failed[0]]:.2f} s "
            f"at ({where[0]:.3f}, {where[1]:.3f}, {where[2]:.3f}) m in the world, {reach:.3f} m from the robot's base"
        )
        kinds.append("reach")
    positions = solved.q
    velocities = np.gradient(positions, path.dt, axis=0)
    velocities[0] = velocities[-1] = 0.0
    outside = ~((positions >= robot.lower - 1e-9) & (positions <= robot.upper + 1e-9))
    if outside.any():
        k, j = np.argwhere(outside)[0]
        problems.append(
            f"{robot.joint_names[j]} leaves its limits ({positions[k, j]:.3f} at t = {path.times[k]:.2f} s)"
        )
        kinds.append("limits")
    too_fast = np.abs(velocities) > robot.max_velocity
    if too_fast.any():
        k, j = np.argwhere(too_fast)[0]
        problems.append(
            f"{robot.joint_names[j]} exceeds its velocity limit ({abs(velocities[k, j]):.3f} > "
            f"{robot.max_velocity[j]:.3f} at t = {path.times[k]:.2f} s)"
        )
        kinds.append("speed")
    lowest = {"table": math.inf, "hand": math.inf, "self": math.inf}
    for k in range(len(path.times)):
        for what, distance in world.clearance(positions[k]).items():
            if distance < lowest[what]:
                lowest[what] = distance
    for what, distance in lowest.items():
        if distance < CONTACT_MARGIN:
            problems.append(
                f"the robot comes within {max(distance, 0.0) * 1000:.1f} mm of "
                f"{'itself' if what == 'self' else 'the ' + what}"
            )
            kinds.append(what)
    distances = np.array([world.hand_distance(q) for q in positions])
    reached = float(distances[-1])
    if abs(reached - path.standoff) > STANDOFF_TOLERANCE:
        problems.append(f"the planned end is {reached:.4f} m from the hand, not the stand-off {path.standoff} m")
        kinds.append("standoff")
    unreachable = int((~solved.success).sum())
    fixes = [REMEDIES[kind] for kind in dict.fromkeys(kinds)]
    return PlannedApproach(path, positions, velocities, reached, lowest, distances, problems, unreachable, fixes)


def plan_combination(
    robot: RobotSpec, scene: Scene, combination: Combination, dt: float, world: SceneWorld
) -> PlannedApproach:
    """The combination's path planned and checked. Where the robot's distance is its surface's, the path's end (an
    end-effector point) is moved along the approach until that surface, not the point, ends at the stand-off: each
    round moves it by the last round's miss, which shrinks fast since near the end the two differ by about the
    tool's reach beyond the point."""
    name, standoff, peak_speed = combination
    planned = plan_approach(robot, scene, approach_path(scene, name, standoff, peak_speed, dt), world)
    point_standoff = standoff
    for _ in range(_STANDOFF_ROUNDS):
        miss = planned.reached_standoff - standoff
        if scene.distance == "ee_point" or planned.unreachable or not abs(miss) > STANDOFF_TOLERANCE / 4:
            break  # (where IK fails, the distances say nothing about the path's end; NaN or inf: no surface)
        point_standoff -= miss
        try:
            path = approach_path(scene, name, standoff, peak_speed, dt, point_standoff)
        except DesignError:
            break  # the end moved out too far for the path's start: the last plan says it misses its stand-off
        planned = plan_approach(robot, scene, path, world)
    return planned


class Approaches:
    """The combinations of one robot in one scene, each planned when first asked for and kept, and the robot's
    distance to the hand by the scene's definition: what the runner, the simulated participant and the live view
    share. It holds a SceneWorld (a pybullet client): close it."""

    def __init__(self, robot: RobotSpec, scene: Scene, dt: float) -> None:
        self.robot, self.scene, self.dt = robot, scene, dt
        self.world = SceneWorld(robot, scene)
        self._planned: dict[Combination, PlannedApproach] = {}

    def plan(self, combination: Combination) -> PlannedApproach:
        if combination not in self._planned:
            self._planned[combination] = plan_combination(self.robot, self.scene, combination, self.dt, self.world)
        return self._planned[combination]

    def plan_all(self, combinations: Iterable[Combination]) -> dict[Combination, PlannedApproach]:
        """Each distinct combination planned and checked once, in order."""
        return {combination: self.plan(combination) for combination in dict.fromkeys(combinations)}

    def hand_distance(self, q: np.ndarray) -> float:
        return self.world.hand_distance(q)

    def end_effector(self, q: np.ndarray) -> np.ndarray:
        return self.world.end_effector(q)

    def close(self) -> None:
        self.world.close()

    def __enter__(self) -> Approaches:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


def plan_combinations(
    robot: RobotSpec, scene: Scene, combinations: Iterable[Combination], dt: float
) -> dict[Combination, PlannedApproach]:
    """Each distinct combination planned and checked once, in one scene world."""
    with Approaches(robot, scene, dt) as approaches:
        return approaches.plan_all(combinations)
