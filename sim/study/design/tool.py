"""Which way a robot's tool points, and the orientation it keeps on an approach: its tool axis straight down at the
hand, turned as little as possible from how the tool sits at home. Pure logic.

The tool axis is the axis of the chain's last revolute joint (the wrist's roll, on a 6- or 7-joint arm), signed to
point away from the arm: from the joint before it towards the end effector. So the Panda, whose hand points down
at home, keeps its home orientation, and an arm that stands upright at home (the LBR iiwa) turns its flange down.
"""

from __future__ import annotations

import numpy as np

from sim.geometry.kinematics import KinematicChain

__all__ = ["approach_rotation", "tool_axis"]


def tool_axis(chain: KinematicChain, q: np.ndarray) -> np.ndarray:
    """The tool axis (unit vector) in the end effector's frame, at joint positions q; the end effector's z axis for
    a chain without a revolute joint."""
    jacobian = chain.jacobian(q)
    revolute = [k for k in range(chain.dof) if np.linalg.norm(jacobian[3:, k]) > 0.5]
    pose = chain.fk(q)
    if not revolute:
        return np.array([0.0, 0.0, 1.0])
    last = revolute[-1]
    axis = jacobian[3:, last] / np.linalg.norm(jacobian[3:, last])
    before = chain.fk_link_frames(q)[last - 1][:3, 3] if last > 0 else np.zeros(3)
    if float(axis @ (pose[:3, 3] - before)) < 0.0:
        axis = -axis
    return pose[:3, :3].T @ axis


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector a onto unit vector b."""
    cross, cosine = np.cross(a, b), float(a @ b)
    if cosine > 1.0 - 1e-12:
        return np.eye(3)
    if cosine < -1.0 + 1e-12:  # opposite: half a turn about any axis perpendicular to a
        perpendicular = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        perpendicular /= np.linalg.norm(perpendicular)
        return 2.0 * np.outer(perpendicular, perpendicular) - np.eye(3)
    skew = np.array([[0.0, -cross[2], cross[1]], [cross[2], 0.0, -cross[0]], [-cross[1], cross[0], 0.0]])
    return np.eye(3) + skew + skew @ skew / (1.0 + cosine)


def approach_rotation(chain: KinematicChain, home: np.ndarray, down: np.ndarray) -> np.ndarray:
    """The end effector's orientation (3x3, base frame) for approaching the hand: its tool axis along `down` (the
    world's -z in the base frame), turned the least from its orientation at `home`."""
    rotation = chain.fk(home)[:3, :3]
    pointing = rotation @ tool_axis(chain, home)
    return _rotation_between(pointing, np.asarray(down, dtype=float) / np.linalg.norm(down)) @ rotation
