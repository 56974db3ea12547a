"""An approach path made joint motion and checked before it is ever run: IK of every sample
(sim.geometry.kinematics), joint position and velocity limits, no contact with the table, the hand or the robot
itself (pybullet's collision shapes; of its own link pairs only those that can really meet, see
sim.engine.self_contact), and the stand-off actually reached (FK of the planned end). An infeasible
combination is reported with every reason, never run.

The end effector keeps one orientation throughout, on the axes its chain controls (sim.control.scenarios.defaults):
its tool pointing straight down, turned the least from home (sim.study.design.tool; the Panda's is its home's).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Tuple

import numpy as np
import pybullet as p

from sim.control.scenarios.defaults import controllable_weights
from sim.engine.physics import load_urdf_text
from sim.engine.self_contact import CONTACT_MARGIN, link_names, self_contact  # closer than the margin is contact
from sim.geometry.frames import matrix_to_quat, rpy_to_matrix
from sim.geometry.kinematics import chain_for, solve_ik, solve_path_ik
from sim.robots import RobotSpec, find_ros_package
from sim.robots.meshes import resolve_shapes
from sim.study.design.paths import ApproachPath, approach_path
from sim.study.design.scene import Box, Scene
from sim.study.design.tool import approach_rotation

__all__ = [
    "CONTACT_MARGIN",
    "STANDOFF_TOLERANCE",
    "Combination",
    "PlannedApproach",
    "SceneWorld",
    "plan_approach",
    "plan_combinations",
]

STANDOFF_TOLERANCE = 0.002  # m: FK of the planned end vs the path's stand-off
_IK_RESTARTS = 20

# path name, stand-off (m), peak speed (m/s); typing.Tuple, as an alias is evaluated at run time (3.8 has no tuple[])
Combination = Tuple[str, float, float]


@dataclass
class PlannedApproach:
    path: ApproachPath
    positions: np.ndarray  # (N, dof) joint positions, rad or m
    velocities: np.ndarray  # (N, dof)
    reached_standoff: float  # m: FK of the last sample to the hand
    min_clearance: dict[str, float]  # smallest distance over the path: "table", "hand", "self"
    problems: list[str] = field(default_factory=list)

    @property
    def feasible(self) -> bool:
        return not self.problems


class SceneWorld:
    """The robot (with its collision shapes), the table and the hand in a pybullet DIRECT client of their own, for
    distance queries at given joint positions. Nothing is simulated."""

    def __init__(self, robot: RobotSpec, scene: Scene) -> None:
        self.robot = robot
        self._client = p.connect(p.DIRECT)
        try:
            self._load(scene)
        except Exception:
            p.disconnect(physicsClientId=self._client)
            raise

    def _load(self, scene: Scene) -> None:
        cid, urdf = self._client, self.robot.urdf_path
        text, _ = resolve_shapes(urdf.read_text(encoding="utf-8"), urdf.parent, find_ros_package)
        self._body = load_urdf_text(
            text,
            urdf.name,
            cid,
            scene.base_position.tolist(),
            matrix_to_quat(rpy_to_matrix(*scene.base_rpy)).tolist(),
            flags=p.URDF_USE_SELF_COLLISION | p.URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS,
        )
        index = {
            p.getJointInfo(self._body, j, physicsClientId=cid)[1].decode(): j
            for j in range(p.getNumJoints(self._body, physicsClientId=cid))
        }
        self._joints = [index[name] for name in self.robot.joint_names]
        # Links that move: below the first controlled joint. The others (the base, bolted to the table) may touch it.
        self._moving = {
            j for j in range(p.getNumJoints(self._body, physicsClientId=cid)) if self._below(j, self._joints[0])
        }
        self._obstacles = {"table": self._box(scene.table), "hand": self._box(scene.hand)}
        # Only link pairs that can really collide are checked against each other (adjacent ones, those that touch
        # by construction and those that never meet are not): decided once per robot, as MoveIt decides it.
        names = link_names(self._body, cid)
        verdict = self_contact(self.robot)
        self._checked = {
            (a, b)
            for a in range(-1, len(names) - 1)
            for b in range(a + 1, len(names) - 1)
            if verdict.checks(names[a + 1], names[b + 1])
        }

    def _below(self, link: int, joint: int) -> bool:
        """Whether pybullet link `link` (= its joint's index) is `joint`'s child or below it."""
        while link >= 0:
            if link == joint:
                return True
            link = p.getJointInfo(self._body, link, physicsClientId=self._client)[16]  # the parent link's index
        return False

    def _box(self, box: Box) -> int:
        cid = self._client
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=(box.size / 2).tolist(), physicsClientId=cid)
        return int(
            p.createMultiBody(
                0.0,
                shape,
                -1,
                box.position.tolist(),
                matrix_to_quat(rpy_to_matrix(0.0, 0.0, box.yaw)).tolist(),
                physicsClientId=cid,
            )
        )

    def _set(self, q: np.ndarray) -> None:
        for joint, value in zip(self._joints, q):
            p.resetJointState(self._body, joint, float(value), physicsClientId=self._client)

    def _self_distances(self, q: np.ndarray) -> list[tuple[tuple[int, int], float]]:
        self._set(q)
        points = p.getClosestPoints(self._body, self._body, CONTACT_MARGIN, physicsClientId=self._client)
        return [((min(c[3], c[4]), max(c[3], c[4])), float(c[8])) for c in points if c[3] != c[4]]

    def clearance(self, q: np.ndarray, reach: float = 0.5) -> dict[str, float]:
        """Smallest distance (m) from the robot to the table, to the hand, and between its own links (within
        CONTACT_MARGIN, else inf), at joint positions q; `reach` bounds the search."""
        self._set(q)
        result = {}
        for name, body in self._obstacles.items():
            points = p.getClosestPoints(self._body, body, reach, physicsClientId=self._client)
            result[name] = min((float(c[8]) for c in points if c[3] in self._moving), default=math.inf)
        touching = [distance for pair, distance in self._self_distances(q) if pair in self._checked]
        result["self"] = min(touching, default=math.inf)
        return result

    def close(self) -> None:
        if self._client is not None:
            p.disconnect(physicsClientId=self._client)
            self._client = None

    def __enter__(self) -> SceneWorld:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


def plan_approach(robot: RobotSpec, scene: Scene, path: ApproachPath, world: SceneWorld) -> PlannedApproach:
    """Joint motion for `path` (IK of every sample from home's end-effector orientation), checked (module doc)."""
    chain = chain_for(robot)
    home_pose = chain.fk(robot.home)
    weights = controllable_weights(chain, robot.home)
    targets = np.tile(home_pose, (len(path.times), 1, 1))
    targets[:, :3, :3] = approach_rotation(chain, robot.home, scene.to_base_direction(np.array([0.0, 0.0, -1.0])))
    targets[:, :3, 3] = scene.to_base(path.positions)
    problems: list[str] = []
    first = solve_ik(chain, targets[0], robot.home, weights=weights, restarts=_IK_RESTARTS, rng=0)
    solved = solve_path_ik(chain, targets, first.q, weights=weights)
    if not solved.all_succeeded:
        failed = np.flatnonzero(~solved.success)
        problems.append(
            f"IK failed at {failed.size} of {len(path.times)} samples, first at t = {path.times[failed[0]]:.2f} s"
        )
    positions = solved.q
    velocities = np.gradient(positions, path.dt, axis=0)
    velocities[0] = velocities[-1] = 0.0
    outside = ~((positions >= robot.lower - 1e-9) & (positions <= robot.upper + 1e-9))
    if outside.any():
        k, j = np.argwhere(outside)[0]
        problems.append(
            f"{robot.joint_names[j]} leaves its limits ({positions[k, j]:.3f} at t = {path.times[k]:.2f} s)"
        )
    too_fast = np.abs(velocities) > robot.max_velocity
    if too_fast.any():
        k, j = np.argwhere(too_fast)[0]
        problems.append(
            f"{robot.joint_names[j]} exceeds its velocity limit ({abs(velocities[k, j]):.3f} > "
            f"{robot.max_velocity[j]:.3f} at t = {path.times[k]:.2f} s)"
        )
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
    end = scene.end_effector(chain, positions[-1])
    reached = scene.hand.distance(end)
    if abs(reached - path.standoff) > STANDOFF_TOLERANCE:
        problems.append(f"the planned end is {reached:.4f} m from the hand, not the stand-off {path.standoff} m")
    return PlannedApproach(path, positions, velocities, reached, lowest, problems)


def plan_combinations(
    robot: RobotSpec, scene: Scene, combinations: Iterable[Combination], dt: float
) -> dict[Combination, PlannedApproach]:
    """Each distinct combination planned and checked once, in one scene world."""
    with SceneWorld(robot, scene) as world:
        return {
            combination: plan_approach(robot, scene, approach_path(scene, *combination, dt=dt), world)
            for combination in dict.fromkeys(combinations)
        }
