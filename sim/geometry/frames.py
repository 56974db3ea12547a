"""Coordinate-frame conversions between ROS and Unity, and quaternion / Euler / matrix helpers. Pure numpy.

ROS (REP 103) is right-handed, z-up, "FLU": x forward, y left, z up.
Unity is left-handed, y-up, "RUF": x right, y up, z forward.
Unity's ROS-TCP-Connector (ROSGeometry, coordinate space `FLU`) maps

    point:       unity (x, y, z)    = (-ros.y, ros.z, ros.x)
    quaternion:  unity (x, y, z, w) = (ros.y, -ros.z, -ros.x, ros.w)

Derivation of the quaternion rule: points map by the matrix M (rows (0,-1,0), (0,0,1), (1,0,0)), whose
determinant is -1 (a handedness flip). A rotation R maps to M R Mᵀ; its axis is a pseudo-vector, so it maps
to det(M)·M·axis = -M·axis while the angle is unchanged, which gives (ros.y, -ros.z, -ros.x) for the vector part.
The numeric quaternion-to-matrix formula is the same in both frames, so "rotate in ROS, then convert" equals
"convert, then rotate in Unity" (see tests/unit/sim/geometry/test_frames.py).

Quaternions are (x, y, z, w) arrays everywhere. Euler angles are URDF-style fixed-axis roll-pitch-yaw:
R = Rz(yaw) · Ry(pitch) · Rx(roll), i.e. rotate about the fixed x, then fixed y, then fixed z axis.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from sim.errors import SimError

__all__ = [
    "FrameError",
    "rotation_vector",
    "rotation_log",
    "rotation_exp",
    "ros_to_unity_point",
    "unity_to_ros_point",
    "ros_to_unity_quat",
    "unity_to_ros_quat",
    "ros_to_unity_matrix",
    "quat_to_matrix",
    "matrix_to_quat",
    "rpy_to_matrix",
    "matrix_to_rpy",
    "euler_xyz_to_quat",
    "quat_to_euler_xyz",
    "quat_multiply",
]

_ROS_TO_UNITY = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


class FrameError(SimError, ValueError):
    """A point, quaternion or matrix of the wrong shape, or a zero quaternion."""


def _vec(value: ArrayLike, size: int, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape[-1:] != (size,):
        raise FrameError(f"{what} must have a last dimension of {size}, got shape {arr.shape}")
    return arr


def ros_to_unity_point(p: ArrayLike) -> np.ndarray:
    """ROS FLU point(s) (..., 3) → Unity RUF point(s): (-y, z, x)."""
    p = _vec(p, 3, "point")
    return np.stack([-p[..., 1], p[..., 2], p[..., 0]], axis=-1)


def unity_to_ros_point(p: ArrayLike) -> np.ndarray:
    """Unity RUF point(s) (..., 3) → ROS FLU point(s): (z, -x, y)."""
    p = _vec(p, 3, "point")
    return np.stack([p[..., 2], -p[..., 0], p[..., 1]], axis=-1)


def ros_to_unity_quat(q: ArrayLike) -> np.ndarray:
    """ROS quaternion(s) (x, y, z, w) → Unity quaternion(s): (y, -z, -x, w)."""
    q = _vec(q, 4, "quaternion")
    return np.stack([q[..., 1], -q[..., 2], -q[..., 0], q[..., 3]], axis=-1)


def unity_to_ros_quat(q: ArrayLike) -> np.ndarray:
    """Unity quaternion(s) (x, y, z, w) → ROS quaternion(s): (-z, x, -y, w)."""
    q = _vec(q, 4, "quaternion")
    return np.stack([-q[..., 2], q[..., 0], -q[..., 1], q[..., 3]], axis=-1)


def ros_to_unity_matrix(rotation: ArrayLike) -> np.ndarray:
    """A ROS rotation matrix expressed in Unity axes (M R Mᵀ)."""
    return _ROS_TO_UNITY @ np.asarray(rotation, dtype=float) @ _ROS_TO_UNITY.T


def quat_to_matrix(q: ArrayLike) -> np.ndarray:
    """Rotation matrix (3, 3) of a quaternion (x, y, z, w); the quaternion is normalised first."""
    x, y, z, w = _vec(q, 4, "quaternion").reshape(4)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if norm < 1e-12:
        raise FrameError(f"zero quaternion {(x, y, z, w)} has no rotation")
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quat(rotation: ArrayLike) -> np.ndarray:
    """Unit quaternion (x, y, z, w) with w ≥ 0 of a rotation matrix (Shepperd's method, stable for all angles)."""
    r = np.asarray(rotation, dtype=float)
    if r.shape != (3, 3):
        raise FrameError(f"rotation matrix must be 3x3, got shape {r.shape}")
    trace = r[0, 0] + r[1, 1] + r[2, 2]
    # Pick the largest of w², x², y², z² as the divisor to avoid cancellation.
    candidates = (trace, r[0, 0], r[1, 1], r[2, 2])
    best = int(np.argmax(candidates))
    if best == 0:
        s = 2.0 * math.sqrt(max(1.0 + trace, 0.0))
        q = np.array([(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s])
    elif best == 1:
        s = 2.0 * math.sqrt(max(1.0 + r[0, 0] - r[1, 1] - r[2, 2], 0.0))
        q = np.array([0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s, (r[2, 1] - r[1, 2]) / s])
    elif best == 2:
        s = 2.0 * math.sqrt(max(1.0 - r[0, 0] + r[1, 1] - r[2, 2], 0.0))
        q = np.array([(r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s, (r[0, 2] - r[2, 0]) / s])
    else:
        s = 2.0 * math.sqrt(max(1.0 - r[0, 0] - r[1, 1] + r[2, 2], 0.0))
        q = np.array([(r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s, (r[1, 0] - r[0, 1]) / s])
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def rpy_to_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) · Ry(pitch) · Rx(roll) (URDF rpy, fixed axes)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_to_rpy(rotation: ArrayLike) -> tuple[float, float, float]:
    """(roll, pitch, yaw) with R = Rz·Ry·Rx, pitch in [-π/2, π/2]; at pitch = ±π/2 roll is set to 0."""
    r = np.asarray(rotation, dtype=float)
    pitch = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    if abs(r[2, 0]) < 1.0 - 1e-12:
        roll = math.atan2(r[2, 1], r[2, 2])
        yaw = math.atan2(r[1, 0], r[0, 0])
    else:  # gimbal lock: only roll ∓ yaw is defined
        roll = 0.0
        yaw = math.atan2(-r[0, 1], r[1, 1])
    return roll, pitch, yaw


def euler_xyz_to_quat(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Quaternion (x, y, z, w) of fixed-axis XYZ Euler angles, R = Rz(yaw)·Ry(pitch)·Rx(roll) (as URDF rpy)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    q = np.array(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ]
    )
    return -q if q[3] < 0 else q


def quat_to_euler_xyz(q: ArrayLike) -> tuple[float, float, float]:
    """(roll, pitch, yaw) of a quaternion (x, y, z, w), inverse of `euler_xyz_to_quat` (pitch in [-π/2, π/2])."""
    return matrix_to_rpy(quat_to_matrix(q))


def quat_multiply(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Hamilton product a ⊗ b of quaternions (x, y, z, w): the rotation b followed by a."""
    ax, ay, az, aw = _vec(a, 4, "quaternion")
    bx, by, bz, bw = _vec(b, 4, "quaternion")
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """Rotation vector (axis · angle, angle in [0, π]) of a 3x3 rotation matrix: the log map the IK uses."""
    rx, ry, rz, _ = rotation_log(np.asarray(rotation, dtype=float).tolist())
    return np.array([rx, ry, rz])


def rotation_log(r: list[list[float]]) -> tuple[float, float, float, float]:
    """Rotation vector (x, y, z) and angle of a rotation matrix given as nested lists (the log map, in plain floats:
    the IK calls it every iteration)."""
    lx, ly, lz = r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]
    trace = r[0][0] + r[1][1] + r[2][2]
    norm_l = math.sqrt(lx * lx + ly * ly + lz * lz)  # = 2 sin(angle)
    if norm_l > 1e-9:
        angle = math.atan2(norm_l, trace - 1.0)
        k = angle / norm_l
        return k * lx, k * ly, k * lz, angle
    if trace > 1.0:  # ~identity: rotvec ≈ l / 2
        return 0.5 * lx, 0.5 * ly, 0.5 * lz, 0.5 * norm_l
    # ~half turn: axis from the diagonal, sign from the largest off-diagonal pair
    ax = math.sqrt(max((r[0][0] + 1.0) / 2.0, 0.0))
    ay = math.sqrt(max((r[1][1] + 1.0) / 2.0, 0.0))
    az = math.sqrt(max((r[2][2] + 1.0) / 2.0, 0.0))
    if ax >= ay and ax >= az:
        ay, az = math.copysign(ay, r[0][1] + r[1][0]), math.copysign(az, r[0][2] + r[2][0])
    elif ay >= az:
        ax, az = math.copysign(ax, r[0][1] + r[1][0]), math.copysign(az, r[1][2] + r[2][1])
    else:
        ax, ay = math.copysign(ax, r[0][2] + r[2][0]), math.copysign(ay, r[1][2] + r[2][1])
    return math.pi * ax, math.pi * ay, math.pi * az, math.pi


def rotation_exp(rotvec: np.ndarray) -> np.ndarray:
    """The rotation matrix of a rotation vector (axis · angle): the exp map, inverse of rotation_vector."""
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-12:
        return np.eye(3)
    k = rotvec / angle
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * kx @ kx
