"""Forward kinematics, geometric Jacobian and numerical inverse kinematics of serial chains read from URDF.

Pure numpy; the only I/O is reading the URDF once (parsed by sim.robots.urdf_model). Conventions:

* Transforms are 4x4 homogeneous matrices from the chain's base link to a link.
* URDF joint origins: translation xyz, then fixed-axis roll-pitch-yaw, R = Rz(y)·Ry(p)·Rx(r).
* `jacobian(q)` is the geometric Jacobian at the end-effector origin in the base frame:
  rows (vx, vy, vz, wx, wy, wz), one column per movable joint.
* The IK pose error is e = (p_target - p, rotvec(R_target · Rᵀ)), both in the base frame, so that
  e ≈ J·dq for small dq. It is solved by Levenberg–Marquardt with Sugihara's damping
  (T. Sugihara, "Solvability-unconcerned inverse kinematics by the Levenberg–Marquardt method", 2011):
  dq = (JᵀWJ + λI)⁻¹ JᵀWe with λ = E + bias, E = ½ eᵀWe. Far from the goal the large E makes it a short
  gradient step, near the goal it becomes Gauss–Newton; the small bias keeps it well-posed at singularities.

Per-axis weights W = diag(weights) select what must be reached:

* (1,1,1,1,1,1): full pose (default).
* (1,1,1,0,0,0) or `position_only=True`: position only.
* (1,1,0,0,0,1) = `PLANAR_WEIGHTS`: x, y and yaw, for planar robots such as the igt (rail + two z-joints),
  whose z and roll/pitch are fixed by construction. Build such targets with `planar_pose(x, y, yaw)`.

Reported errors honour the weights: `position_error` is the norm of the selected position components;
`orientation_error` is the rotation angle of R_target·Rᵀ when all three angular axes are selected, otherwise
the norm of the selected components of its rotation vector. For `planar_pose` targets and the igt
(rotations about z only) that is exactly |wrapped yaw error|.

One concern, and a long one: a chain's kinematics both ways. The IK solver iterates on the chain's own fast path
(`_frames`, `_jacobian_from_frames`) and its error is the Jacobian's convention; set apart, that path would be made
public for one caller.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Tuple

import numpy as np
from numpy.typing import ArrayLike

from sim.errors import SimError
from sim.geometry.frames import quat_to_matrix, rotation_log, rpy_to_matrix
from sim.robots import RobotError, RobotSpec
from sim.robots.urdf_model import parse_urdf

__all__ = [
    "MOVABLE_TYPES",
    "FULL_POSE_WEIGHTS",
    "POSITION_WEIGHTS",
    "PLANAR_WEIGHTS",
    "DEFAULT_DAMPING_BIAS",
    "KinematicsError",
    "ChainJoint",
    "pose_matrix",
    "planar_pose",
    "KinematicChain",
    "chain_for",
    "IKResult",
    "PathIKResult",
    "solve_ik",
    "solve_path_ik",
]

MOVABLE_TYPES = ("revolute", "continuous", "prismatic")
FULL_POSE_WEIGHTS = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
POSITION_WEIGHTS = (1.0, 1.0, 1.0, 0.0, 0.0, 0.0)
PLANAR_WEIGHTS = (1.0, 1.0, 0.0, 0.0, 0.0, 1.0)  # x, y, yaw
DEFAULT_DAMPING_BIAS = (
    1e-6  # Sugihara's w̄: larger values converge slowly near singular poses (measured: 1e-4 → 99.2 % in 100 iterations)
)
_STALL_STEP = 1e-13  # a (clipped) step shorter than this means the attempt cannot make progress
_STALL_ITERATIONS, _STALL_GAIN = 10, 1e-3  # ... as do this many iterations without E falling by this fraction


class KinematicsError(SimError, ValueError):
    """A URDF chain that cannot be built, or IK inputs of the wrong shape or value."""


@dataclass(frozen=True)
class ChainJoint:
    """A movable joint. `origin` is the fixed transform from the previous movable joint's frame (or the base)
    to this joint's frame at q = 0, fixed joints in between folded in; `axis` is a unit vector in that frame."""

    name: str
    joint_type: str  # "revolute" | "continuous" | "prismatic"
    origin: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float


def pose_matrix(
    position: Sequence[float] = (0.0, 0.0, 0.0), quat_xyzw: ArrayLike | None = None, rpy: ArrayLike | None = None
) -> np.ndarray:
    """4x4 transform from a position and at most one of a quaternion (x, y, z, w) or URDF rpy."""
    if quat_xyzw is not None and rpy is not None:
        raise KinematicsError(f"give either quat_xyzw={quat_xyzw} or rpy={rpy}, not both")
    pos = np.asarray(position, dtype=float)
    if pos.shape != (3,):
        raise KinematicsError(f"position must have 3 elements, got shape {pos.shape}")
    pose = np.eye(4)
    pose[:3, 3] = pos
    if quat_xyzw is not None:
        pose[:3, :3] = quat_to_matrix(quat_xyzw)
    elif rpy is not None:
        roll, pitch, yaw = np.asarray(rpy, dtype=float).reshape(3)
        pose[:3, :3] = rpy_to_matrix(float(roll), float(pitch), float(yaw))
    return pose


def planar_pose(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    """Target for x, y, yaw IK (use with `weights=PLANAR_WEIGHTS`); z only matters if z is weighted."""
    return pose_matrix((x, y, z), rpy=(0.0, 0.0, yaw))


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class KinematicChain:
    """A serial chain of movable joints from `base_link` to `ee_link`."""

    def __init__(self, joints: Sequence[ChainJoint], tail: np.ndarray, base_link: str, ee_link: str) -> None:
        if not joints:
            raise KinematicsError(f"chain {base_link} → {ee_link} has no movable joint")
        self.base_link = base_link
        self.ee_link = ee_link
        self._joints = tuple(joints)
        self._tail = np.array(tail, dtype=float)
        n = len(joints)
        self._n = n
        self._lower = np.array([j.lower for j in joints])
        self._upper = np.array([j.upper for j in joints])

        # Precomputed so that the local transforms of all joints (and the fixed tail, last) are, at once,
        #   L_i = P0_i + sin(q_i)·P1_i + (1 - cos(q_i))·P2_i + q_i·D_i
        # (Rodrigues' formula folded into the origin rotation; D moves prismatic joints along their axis).
        revolute = np.array([j.joint_type != "prismatic" for j in joints])
        self._revolute = revolute.astype(float)
        self._prismatic = (~revolute).astype(float)
        self._all_revolute = bool(revolute.all())
        self._axes = np.array([j.axis for j in joints])
        origin_r = np.array([j.origin[:3, :3] for j in joints])
        k = np.array([_skew(j.axis) for j in joints])
        self._p0 = np.concatenate([np.array([j.origin for j in joints]), self._tail[None]])
        self._p1 = np.zeros((n, 4, 4))
        self._p1[:, :3, :3] = origin_r @ k * self._revolute[:, None, None]
        self._p2 = np.zeros((n, 4, 4))
        self._p2[:, :3, :3] = origin_r @ k @ k * self._revolute[:, None, None]
        self._prismatic_dir = (origin_r @ self._axes[:, :, None])[:, :, 0] * self._prismatic[:, None]
        # Prefix-product shifts: the chain product in ceil(log2(n + 1)) batched matmuls instead of n calls.
        self._scan_shifts = [1 << i for i in range(max(1, math.ceil(math.log2(n + 1))))]
        # Joint axes that are the frame's z (most URDFs) can be read off the frames without a product.
        self._z_axes = bool(np.allclose(self._axes, [0.0, 0.0, 1.0]))

    # ----------------------------------------------------------------------------------------------- building
    @classmethod
    def from_urdf(
        cls, urdf_path: str | Path, base_link: str, ee_link: str, joint_names: Sequence[str] | None = None
    ) -> KinematicChain:
        """Parse `urdf_path` and build the chain base_link → ee_link; `joint_names`, if given, must equal
        the chain's movable joints in order."""
        try:
            model = parse_urdf(Path(urdf_path).read_text(encoding="utf-8"), str(urdf_path))
            path = model.path(base_link, ee_link)
        except (OSError, UnicodeDecodeError) as exc:
            raise KinematicsError(f"cannot read URDF {urdf_path}: {exc}") from exc
        except RobotError as exc:
            raise KinematicsError(str(exc)) from exc

        joints: list[ChainJoint] = []
        pending = np.eye(4)  # fixed transforms accumulated since the last movable joint
        for joint in path:
            origin = np.eye(4)
            origin[:3, :3] = rpy_to_matrix(*joint.rpy)
            origin[:3, 3] = joint.xyz
            pending = pending @ origin
            if joint.joint_type == "fixed":
                continue
            if joint.joint_type not in MOVABLE_TYPES:
                raise KinematicsError(
                    f"joint {joint.name!r} has unsupported type {joint.joint_type!r} "
                    f"(supported: fixed, {MOVABLE_TYPES})"
                )
            lower, upper = -math.inf, math.inf
            if joint.joint_type != "continuous" and joint.limit is not None:
                lower = -math.inf if joint.limit.lower is None else joint.limit.lower
                upper = math.inf if joint.limit.upper is None else joint.limit.upper
            joints.append(ChainJoint(joint.name, joint.joint_type, pending, np.array(joint.axis), lower, upper))
            pending = np.eye(4)

        chain = cls(joints, pending, base_link, ee_link)
        if joint_names is not None and tuple(joint_names) != chain.joint_names:
            raise KinematicsError(
                f"joint_names {tuple(joint_names)} differ from the movable joints {chain.joint_names} "
                f"of {base_link} → {ee_link} in {urdf_path}"
            )
        return chain

    def with_limits(self, lower: ArrayLike, upper: ArrayLike) -> KinematicChain:
        """The same chain with other joint limits (e.g. a datasheet's instead of the URDF's)."""
        lower_arr, upper_arr = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        if lower_arr.shape != (self._n,) or upper_arr.shape != (self._n,) or np.any(lower_arr > upper_arr):
            raise KinematicsError(f"limits lower={lower_arr} upper={upper_arr} do not fit {self._n} joints")
        joints = [
            ChainJoint(j.name, j.joint_type, j.origin, j.axis, float(lo), float(hi))
            for j, lo, hi in zip(self._joints, lower_arr, upper_arr)
        ]
        return KinematicChain(joints, self._tail, self.base_link, self.ee_link)

    # ----------------------------------------------------------------------------------------------- queries
    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self._joints)

    @property
    def joints(self) -> tuple[ChainJoint, ...]:
        return self._joints

    @property
    def dof(self) -> int:
        return self._n

    @property
    def lower(self) -> np.ndarray:
        return self._lower.copy()

    @property
    def upper(self) -> np.ndarray:
        return self._upper.copy()

    def _q(self, q: ArrayLike) -> np.ndarray:
        q_arr = np.asarray(q, dtype=float)
        if q_arr.shape != (self._n,):
            raise KinematicsError(f"q must have shape ({self._n},) for joints {self.joint_names}, got {q_arr.shape}")
        return q_arr

    def _frames(self, q: np.ndarray) -> np.ndarray:
        """(n + 1, 4, 4): base → each movable joint's child link, then base → ee. No input checks (hot path)."""
        n = self._n
        frames = self._p0.copy()
        frames[:n] += np.sin(q)[:, None, None] * self._p1 + (1.0 - np.cos(q))[:, None, None] * self._p2
        if not self._all_revolute:
            frames[:n, :3, 3] += q[:, None] * self._prismatic_dir
        # Inclusive prefix product (Hillis–Steele): after the pass with shift k, frames[i] = L_{i-2k+1} ··· L_i.
        for shift in self._scan_shifts:
            frames[shift:] = frames[:-shift] @ frames[shift:]
        return frames

    def _jacobian_from_frames(self, frames: np.ndarray) -> np.ndarray:
        n = self._n
        if self._z_axes:
            z = frames[:n, :3, 2]
        else:
            z = (frames[:n, :3, :3] @ self._axes[:, :, None])[:, :, 0]
        d = frames[n, :3, 3] - frames[:n, :3, 3]  # joint origin → ee origin
        jac = np.empty((6, n))
        zx, zy, zz = z[:, 0], z[:, 1], z[:, 2]
        dx, dy, dz = d[:, 0], d[:, 1], d[:, 2]
        jac[0] = zy * dz - zz * dy
        jac[1] = zz * dx - zx * dz
        jac[2] = zx * dy - zy * dx
        jac[3:] = z.T
        if not self._all_revolute:  # prismatic joints: linear velocity along the axis, no angular velocity
            jac[:3] = jac[:3] * self._revolute + z.T * self._prismatic
            jac[3:] *= self._revolute
        return jac

    def fk(self, q: ArrayLike) -> np.ndarray:
        """Pose (4x4) of ee_link in base_link at joint positions q."""
        return self._frames(self._q(q))[-1].copy()

    def fk_link_frames(self, q: ArrayLike) -> list[np.ndarray]:
        """Pose (4x4) in base_link of each movable joint's child link, in chain order."""
        frames = self._frames(self._q(q))
        return [frames[i].copy() for i in range(self._n)]

    def jacobian(self, q: ArrayLike) -> np.ndarray:
        """Geometric Jacobian (6 x n) at the ee origin in the base frame, rows (v, ω)."""
        return self._jacobian_from_frames(self._frames(self._q(q)))


# typing.Tuple: an alias is evaluated at run time, and Python 3.8 (ROS Noetic's) cannot subscript tuple.
_ChainKey = Tuple[str, int, int, str, str, Tuple[str, ...], Tuple[float, ...], Tuple[float, ...]]
_CHAINS: dict[_ChainKey, KinematicChain] = {}


def _chain_key(robot: RobotSpec) -> _ChainKey:
    """What a chain is made of: the URDF file as it is now (path, modification time, size), the links and joints,
    and the limits. Never the robot's name: two URDFs may carry one name."""
    urdf = Path(robot.urdf_path).resolve()
    stat = urdf.stat()
    return (
        str(urdf),
        stat.st_mtime_ns,
        stat.st_size,
        robot.base_link,
        robot.ee_link,
        tuple(robot.joint_names),
        tuple(float(v) for v in robot.lower),
        tuple(float(v) for v in robot.upper),
    )


def chain_for(robot: RobotSpec) -> KinematicChain:
    """The chain of a `RobotSpec`, with the spec's joint limits (cached by what it is made of, see _chain_key)."""
    key = _chain_key(robot)
    chain = _CHAINS.get(key)
    if chain is None:
        chain = KinematicChain.from_urdf(robot.urdf_path, robot.base_link, robot.ee_link)
        if chain.joint_names != tuple(robot.joint_names):
            raise KinematicsError(
                f"robot {robot.name!r}: URDF chain {robot.base_link} → {robot.ee_link} has movable joints "
                f"{chain.joint_names}, the registry says {tuple(robot.joint_names)}"
            )
        chain = chain.with_limits(robot.lower, robot.upper)
        _CHAINS[key] = chain
    return chain


# ------------------------------------------------------------------------------------------------------ IK
@dataclass
class IKResult:
    q: np.ndarray
    success: bool
    position_error: float  # m, over the weighted position axes
    orientation_error: float  # rad, see the module docstring
    iterations: int  # over all attempts
    restarts: int  # random restarts used
    message: str = ""


@dataclass
class PathIKResult:
    q: np.ndarray  # (N, n)
    success: np.ndarray  # (N,) bool
    max_joint_jump: float  # largest |Δq| of any joint between consecutive solutions
    results: list[IKResult] = field(default_factory=list)

    @property
    def all_succeeded(self) -> bool:
        return bool(np.all(self.success))


class _Problem:
    """One IK target with its weights, set up once so that the iterations do little Python work."""

    def __init__(self, chain: KinematicChain, target: np.ndarray, weights: np.ndarray, bias: float) -> None:
        self.chain = chain
        self.target_rot = np.ascontiguousarray(target[:3, :3])
        self.target_pos = target[:3, 3].tolist()
        self.w = weights
        self.w_list = weights.tolist()
        self.pos_axes = [i for i in range(3) if weights[i] > 0]
        self.rot_axes = [i for i in range(3) if weights[3 + i] > 0]
        self.bias = bias
        self.diag = np.arange(chain.dof) * (chain.dof + 1)

    def error(self, frames: np.ndarray) -> tuple[np.ndarray, float, float, float]:
        """(e, E, position_error, orientation_error) at the ee frame frames[-1]."""
        ee = frames[-1]
        tx, ty, tz = self.target_pos
        px, py, pz = ee[:3, 3].tolist()
        e = [tx - px, ty - py, tz - pz]
        rx, ry, rz, angle = rotation_log((self.target_rot @ ee[:3, :3].T).tolist())
        e += (rx, ry, rz)
        w = self.w_list
        energy = 0.5 * sum(w[i] * e[i] * e[i] for i in range(6))
        pos_err = math.sqrt(sum(e[i] * e[i] for i in self.pos_axes))
        if len(self.rot_axes) == 3:
            rot_err = angle
        else:
            rot_err = math.sqrt(sum(e[3 + i] * e[3 + i] for i in self.rot_axes))
        return np.array(e), energy, pos_err, rot_err


def _step_at_limits(
    jac: np.ndarray,
    w: np.ndarray,
    e: np.ndarray,
    damping: float,
    q: np.ndarray,
    q_new: np.ndarray,
    outside: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> np.ndarray:
    """Clip the joints that would leave their limits and re-solve the step for the others, so that they make up
    for the clipped motion (plain clipping alone stalls near limits)."""
    for _ in range(3):
        clipped = np.minimum(np.maximum(q_new, lower), upper)
        frozen_motion = np.where(outside, clipped - q, 0.0)
        residual = e - jac @ frozen_motion
        free_jac = jac * ~outside
        jtw = free_jac.T * w
        hessian = jtw @ free_jac
        hessian.flat[:: len(q) + 1] += damping
        q_new = q + frozen_motion + np.linalg.solve(hessian, jtw @ residual)
        newly_outside = ((q_new < lower) | (q_new > upper)) & ~outside
        if not newly_outside.any():
            break
        outside = outside | newly_outside
    return np.minimum(np.maximum(q_new, lower), upper)


def _attempt(
    problem: _Problem,
    q: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    tol_pos: float,
    tol_rot: float,
    max_iter: int,
) -> tuple[np.ndarray, bool, float, float, float, int]:
    """LM iterations from q. Returns (q, converged, E, position_error, orientation_error, iterations)."""
    chain = problem.chain
    w = problem.w
    diag = problem.diag
    frames = chain._frames(q)
    e, energy, pos_err, rot_err = problem.error(frames)
    iterations = 0
    best_energy, last_improvement = energy, 0
    while not (pos_err <= tol_pos and rot_err <= tol_rot) and iterations < max_iter:
        jac = chain._jacobian_from_frames(frames)
        jtw = jac.T * w
        hessian = jtw @ jac
        hessian.flat[diag] += energy + problem.bias
        step = np.linalg.solve(hessian, jtw @ e)
        q_new = q + step
        outside = (q_new < lower) | (q_new > upper)
        if outside.any():
            q_new = _step_at_limits(jac, w, e, energy + problem.bias, q, q_new, outside, lower, upper)
        moved = np.abs(q_new - q).max()
        q = q_new
        iterations += 1
        frames = chain._frames(q)
        e, energy, pos_err, rot_err = problem.error(frames)
        if energy < best_energy * (1.0 - _STALL_GAIN):
            best_energy, last_improvement = energy, iterations
        if moved < _STALL_STEP or iterations - last_improvement >= _STALL_ITERATIONS:
            break  # pinned against limits or stuck in a local minimum of E: better restart than keep going
    return q, pos_err <= tol_pos and rot_err <= tol_rot, energy, pos_err, rot_err, iterations


def _weights(weights: ArrayLike | None, position_only: bool) -> np.ndarray:
    if weights is None:
        w = np.array(POSITION_WEIGHTS if position_only else FULL_POSE_WEIGHTS)
    else:
        if position_only:
            raise KinematicsError(f"give either weights={weights!r} or position_only=True, not both")
        w = np.asarray(weights, dtype=float)
    if w.shape != (6,) or np.any(w < 0) or not np.any(w > 0) or not np.all(np.isfinite(w)):
        raise KinematicsError(f"weights must be 6 finite values ≥ 0, not all zero; got {weights!r}")
    return w


def solve_ik(
    chain: KinematicChain,
    target: np.ndarray,
    q0: ArrayLike,
    *,
    lower: ArrayLike | None = None,
    upper: ArrayLike | None = None,
    weights: ArrayLike | None = None,
    position_only: bool = False,
    tol_pos: float = 1e-6,
    tol_rot: float = 1e-5,
    max_iter: int = 100,
    restarts: int = 0,
    rng: np.random.Generator | int | None = None,
    damping_bias: float = DEFAULT_DAMPING_BIAS,
) -> IKResult:
    """Joint positions reaching `target` (4x4 in the base frame), warm-started from q0.

    Joint limits (default: the chain's) are respected at every step. If the attempt from q0 fails, up to
    `restarts` further attempts start from uniformly random configurations within the limits (±π for
    unlimited joints). The best attempt is returned; `success` is True only if it meets tol_pos and tol_rot.
    """
    n = chain.dof
    target_arr = np.asarray(target, dtype=float)
    if target_arr.shape != (4, 4) or not np.all(np.isfinite(target_arr)):
        raise KinematicsError(f"target must be a finite 4x4 transform, got shape {target_arr.shape}")
    q_start = chain._q(q0)
    lo = chain._lower if lower is None else np.asarray(lower, dtype=float)
    hi = chain._upper if upper is None else np.asarray(upper, dtype=float)
    if lo.shape != (n,) or hi.shape != (n,) or np.any(lo > hi):
        raise KinematicsError(f"limits lower={lo} upper={hi} do not fit {n} joints")
    if max_iter < 1 or restarts < 0:
        raise KinematicsError(f"max_iter={max_iter} must be ≥ 1 and restarts={restarts} ≥ 0")
    problem = _Problem(chain, target_arr, _weights(weights, position_only), damping_bias)

    q = np.minimum(np.maximum(q_start, lo), hi)
    best: tuple[np.ndarray, bool, float, float, float, int] | None = None
    total_iterations = 0
    generator: np.random.Generator | None = None
    for attempt in range(restarts + 1):
        if attempt > 0:
            if generator is None:
                generator = np.random.default_rng(rng)
            q = generator.uniform(np.maximum(lo, -math.pi), np.minimum(hi, math.pi))
        outcome = _attempt(problem, q, lo, hi, tol_pos, tol_rot, max_iter)
        total_iterations += outcome[5]
        if best is None or outcome[2] < best[2] or (outcome[1] and not best[1]):
            best = outcome
        if outcome[1]:
            break
    assert best is not None  # the loop runs at least once
    q_best, success, _, pos_err, rot_err, _ = best
    used_restarts = attempt
    if success:
        message = "converged"
    else:
        message = (
            f"no solution within tol_pos={tol_pos} m, tol_rot={tol_rot} rad after {restarts + 1} attempt(s); "
            f"best residual {pos_err:.3g} m, {rot_err:.3g} rad (target unreachable or attempt stuck)"
        )
    return IKResult(q_best, success, pos_err, rot_err, total_iterations, used_restarts, message)


def solve_path_ik(
    chain: KinematicChain, targets: Sequence[np.ndarray] | np.ndarray, q0: ArrayLike, **ik_kwargs: Any
) -> PathIKResult:
    """IK for each of `targets` in turn, each warm-started from the previous solution (the first from q0)."""
    results: list[IKResult] = []
    q = chain._q(q0)
    for target in targets:
        result = solve_ik(chain, target, q, **ik_kwargs)
        results.append(result)
        q = result.q
    if not results:
        return PathIKResult(np.empty((0, chain.dof)), np.empty(0, dtype=bool), 0.0, results)
    qs = np.array([r.q for r in results])
    jump = float(np.abs(np.diff(qs, axis=0)).max()) if len(qs) > 1 else 0.0
    return PathIKResult(qs, np.array([r.success for r in results]), jump, results)
