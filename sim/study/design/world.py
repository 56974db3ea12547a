"""The scene in pybullet: the robot with its collision shapes, the table and the hand, in a DIRECT client of their
own, for distance queries at given joint positions (nothing is simulated). The robot's distance to the hand is the
scene's definition of it (Scene.distance): its collision geometry's nearest point to the hand's surface, or the
thesis's, the end-effector point's.
"""

from __future__ import annotations

import math

import numpy as np
import pybullet as p

from sim.engine.physics import GRAVITY, load_urdf_text
from sim.engine.self_contact import CONTACT_MARGIN, link_names, self_contact
from sim.geometry.frames import matrix_to_quat, rpy_to_matrix
from sim.geometry.kinematics import chain_for
from sim.robots import RobotSpec, find_ros_package
from sim.robots.meshes import resolve_shapes
from sim.study.design.scene import Box, Scene

__all__ = ["CONTACT_MARGIN", "FAR", "SceneWorld"]

FAR = 2.0  # m: how far distance queries look; the scene is smaller than this


class SceneWorld:
    """The robot (with its collision shapes), the table and the hand in a pybullet DIRECT client of their own, for
    distance queries at given joint positions. Nothing is simulated."""

    def __init__(self, robot: RobotSpec, scene: Scene) -> None:
        self.robot, self.scene = robot, scene
        self._chain = chain_for(robot)
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
        # Gravity's loads on the joints (gravity_loads): pybullet's inverse dynamics takes every moving joint's
        # position, the others' (a gripper's fingers) where the URDF leaves them, as the engine's physics locks them
        dofs = [
            j
            for j in range(p.getNumJoints(self._body, physicsClientId=cid))
            if p.getJointInfo(self._body, j, physicsClientId=cid)[2] in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC)
        ]
        self._controlled = np.array([dofs.index(j) for j in self._joints])
        self._rest = np.array([p.getJointState(self._body, j, physicsClientId=cid)[0] for j in dofs])
        # gravity as the robot's base feels it: the inverse dynamics of a fixed base work in the base's frame
        base = rpy_to_matrix(*scene.base_rpy)
        p.setGravity(*(base.T @ np.array([0.0, 0.0, GRAVITY])).tolist(), physicsClientId=cid)
        # Links that move: below the first controlled joint. The others (the base, bolted to the table) may touch it.
        self._moving = {
            j for j in range(p.getNumJoints(self._body, physicsClientId=cid)) if self._below(j, self._joints[0])
        }
        # the pedestal the robot stands on is furniture like the table (its base resting on it is no contact: only
        # the moving links are measured)
        furniture = [scene.table] if scene.pedestal is None else [scene.table, scene.pedestal]
        self._obstacles = {"table": self._boxes(furniture), "hand": self._boxes([scene.hand])}
        # A robot whose moving links have no collision shapes is measured from its end-effector point
        self._solid = any(p.getCollisionShapeData(self._body, link, physicsClientId=cid) for link in self._moving)
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

    def _boxes(self, boxes: list[Box]) -> int:
        """One fixed body of these boxes (world frame)."""
        cid = self._client
        shape = p.createCollisionShapeArray(
            [p.GEOM_BOX] * len(boxes),
            halfExtents=[(box.size / 2).tolist() for box in boxes],
            collisionFramePositions=[box.position.tolist() for box in boxes],
            collisionFrameOrientations=[matrix_to_quat(rpy_to_matrix(0.0, 0.0, box.yaw)).tolist() for box in boxes],
            physicsClientId=cid,
        )
        return int(p.createMultiBody(0.0, shape, -1, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], physicsClientId=cid))

    def _set(self, q: np.ndarray) -> None:
        for joint, value in zip(self._joints, q):
            p.resetJointState(self._body, joint, float(value), physicsClientId=self._client)

    def _self_clearance(self) -> float:
        """The smallest distance between two of the robot's links that can meet, within CONTACT_MARGIN (else inf),
        where the robot is. Pair by pair: twenty times quicker than all of a body's pairs at once, then filtered."""
        cid, body = self._client, self._body
        return min(
            (
                float(c[8])
                for a, b in self._checked
                for c in p.getClosestPoints(body, body, CONTACT_MARGIN, a, b, physicsClientId=cid)
            ),
            default=math.inf,
        )

    def clearance(self, q: np.ndarray, reach: float = 0.5) -> dict[str, float]:
        """Smallest distance (m) from the robot to the table, to the hand, and between its own links (within
        CONTACT_MARGIN, else inf), at joint positions q; `reach` bounds the search."""
        self._set(q)
        result = {}
        for name, body in self._obstacles.items():
            points = p.getClosestPoints(self._body, body, reach, physicsClientId=self._client)
            result[name] = min((float(c[8]) for c in points if c[3] in self._moving), default=math.inf)
        result["self"] = self._self_clearance()
        return result

    def nearest_links(self, q: np.ndarray, what: str) -> str:
        """Which links are nearest where `what` ("table", "hand" or "self") is at joint positions q: "a and b" for the
        robot's own pair, else the robot's link."""
        self._set(q)
        cid, body, names = self._client, self._body, link_names(self._body, self._client)
        if what == "self":
            found = [
                (float(c[8]), a, b)
                for a, b in self._checked
                for c in p.getClosestPoints(body, body, CONTACT_MARGIN, a, b, physicsClientId=cid)
            ]
            if not found:
                return "no two links"
            _, a, b = min(found)
            return f"{names[a + 1]} and {names[b + 1]}"
        points = p.getClosestPoints(body, self._obstacles[what], FAR, physicsClientId=cid)
        nearest = min((c for c in points if c[3] in self._moving), key=lambda c: c[8], default=None)
        return "no link" if nearest is None else names[nearest[3] + 1]

    def gravity_loads(self, q: np.ndarray) -> np.ndarray:
        """(dof,): the torque (N·m), or a prismatic joint's force (N), each of the robot's joints must exert to hold
        it still at joint positions q against gravity (pybullet's inverse dynamics at zero velocity and acceleration,
        from the URDF's masses: the engine's physics's own gravity feed-forward)."""
        full = self._rest.copy()
        full[self._controlled] = q
        zeros = [0.0] * len(full)
        loads = p.calculateInverseDynamics(self._body, full.tolist(), zeros, zeros, physicsClientId=self._client)
        return np.asarray(loads, dtype=float)[self._controlled]

    def base_bottom(self) -> float:
        """The lowest point (world z) of the robot's base link, where it is mounted; its origin's without shapes."""
        if not p.getCollisionShapeData(self._body, -1, physicsClientId=self._client):
            return float(self.scene.base_position[2])
        return float(p.getAABB(self._body, -1, physicsClientId=self._client)[0][2])

    def base_footprint(self) -> tuple[float, float]:
        """The base link's extent along world x and y (m), what a pedestal under it is as wide as; 0.2 m without
        shapes."""
        if not p.getCollisionShapeData(self._body, -1, physicsClientId=self._client):
            return (0.2, 0.2)
        low, high = p.getAABB(self._body, -1, physicsClientId=self._client)
        return (float(high[0] - low[0]), float(high[1] - low[1]))

    def hand_distance(self, q: np.ndarray, shift: np.ndarray | None = None) -> float:
        """The robot's distance (m) to the hand at joint positions q, by the scene's definition: from its collision
        geometry's nearest point (negative when it is inside the hand), or from the end-effector point. Finite,
        however far the robot is. `shift` (m, world): the hand moved that far from where the scene has it (a tracked
        hand's live displacement)."""
        offset = np.zeros(3) if shift is None else np.asarray(shift, dtype=float)
        if self._measured_from_point:
            return self.scene.hand.distance(self.scene.end_effector(self._chain, q) - offset)
        nearest = self._nearest_to_hand(q, offset)
        if nearest is None:  # (_solid says some moving link has a shape, so pybullet found it)
            raise ValueError("no moving link of the robot has a collision shape")
        return float(nearest[8])

    def nearest_points(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(the robot's point, the hand's point) between which hand_distance is measured, in the world."""
        if self._measured_from_point:
            point = self.scene.end_effector(self._chain, q)
            return point, self.scene.hand.nearest_point(point)
        nearest = self._nearest_to_hand(q)
        if nearest is None:
            raise ValueError("no moving link of the robot has a collision shape")
        return np.array(nearest[5]), np.array(nearest[6])

    @property
    def _measured_from_point(self) -> bool:
        """The thesis's definition, or a robot whose moving links have no collision shapes."""
        return self.scene.distance == "ee_point" or not self._solid

    def _nearest_to_hand(self, q: np.ndarray, shift: np.ndarray | None = None) -> tuple | None:
        """pybullet's closest-point record of the robot's moving links to the hand at q (moved by `shift`, m). Looked
        for within FAR, and where no link is that near (a robot that fell away in a simulation, say), within the
        farthest any link's box reaches from the hand's: a distance, however large, is never made inf. None: no
        moving link has a shape."""
        self._set(q)
        cid, hand = self._client, self._obstacles["hand"]
        offset = None if shift is None or not np.any(shift) else [float(v) for v in shift]
        if offset is not None:  # for this query only: every other one measures to the scene's hand
            p.resetBasePositionAndOrientation(hand, offset, [0.0, 0.0, 0.0, 1.0], physicsClientId=cid)
        try:
            points = p.getClosestPoints(self._body, hand, FAR, physicsClientId=cid)
            nearest = min((c for c in points if c[3] in self._moving), key=lambda c: c[8], default=None)
            if nearest is not None:
                return nearest
            boxes = [np.array(p.getAABB(self._body, link, physicsClientId=cid)) for link in self._moving]
            centre = self.scene.hand.position + (np.zeros(3) if offset is None else np.asarray(offset))
            radius = float(np.linalg.norm(self.scene.hand.size))
            farthest = max(float(np.linalg.norm(np.max(np.abs(box - centre), axis=0))) for box in boxes) + radius
            points = p.getClosestPoints(self._body, hand, farthest, physicsClientId=cid)
        finally:
            if offset is not None:
                p.resetBasePositionAndOrientation(hand, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], physicsClientId=cid)
        return min((c for c in points if c[3] in self._moving), key=lambda c: c[8], default=None)

    def end_effector(self, q: np.ndarray) -> np.ndarray:
        """The end-effector point in the world at joint positions q."""
        return self.scene.end_effector(self._chain, q)

    def end_effector_distance(self, q: np.ndarray) -> float:
        """The end-effector point's distance (m) to the hand at joint positions q, whatever the definition."""
        return self.scene.hand.distance(self.scene.end_effector(self._chain, q))

    def close(self) -> None:
        if self._client is not None:
            p.disconnect(physicsClientId=self._client)
            self._client = None

    def __enter__(self) -> SceneWorld:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()
