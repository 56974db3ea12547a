"""The robot's physics as the game engine (Unity) would simulate it: pybullet for the dynamics, no ROS, no sockets.

Three modes (`Mode`):
  physics             Unity ArticulationDrive on every controlled joint:
                        F = stiffness·(target − q) − damping·(q̇ − target_velocity), clamped to ±force_limit,
                      integrated implicitly (see `implicit_drive_step`) so that stiff drives are stable at dt = 0.02 s.
  no_physics          kinematic: the joints are set exactly to the targets every step; efforts are 0.
  infinite_stiffness  the limit stiffness → ∞ with unlimited force of the physics mode: every target is reached
                      exactly at the end of its step; the velocity is (target − q)/dt and the effort is the torque
                      that motion takes (inverse dynamics), however large.

Timing convention (it matters for accuracy): a target set before step k is the target for the END of step k,
with its velocity feed-forward for that same instant. The drive evaluates its force at the end of the step
(backward Euler), so a smooth trajectory is tracked to ~0.01 %. Passing targets for the START of the step instead
adds a one-step lag (~3 % MAPE on the thesis's test).

Integration: pybullet supplies the mass matrix M(q), the bias torques c(q, q̇) (gravity + Coriolis) and the
kinematics; the integration itself is ours (semi-implicit Euler: v⁺ from the implicit drive, with the Coriolis
torques linearised at the step's end too, q⁺ = q + dt·v⁺), and pybullet's joint states are set from it (lazily,
for ee_pose and pictures). Why not torque control + stepSimulation: pybullet enforces the URDF's joint
limits as constraints (Panda joint 4 stops at 0, the thesis's test commands 0) and adds its own default link damping,
so its v⁺ would not be the one the implicit drive solved for, and a stiff drive would fight those constraints.
Consequences: joint limits are NOT enforced (by design: the physics does not clamp), there are no contacts
(the scene has nothing to touch), and joints outside `robot.joint_names` (the Panda's fingers) are locked rigidly at
their start positions, which is exact: the reduced M and c over the controlled joints describe the locked system.

One concern, and a long one: the three modes' drives stepped on one pybullet body, and what is read back from it (state,
ee_pose, pictures); all of it shares the body, its client and its lazily set joint states, which a cut would pass across
modules.
"""

from __future__ import annotations

import logging
import math
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, replace
from enum import Enum
from pathlib import Path

import numpy as np
import pybullet as p

from sim.errors import SimError
from sim.robots import RobotSpec, find_ros_package
from sim.robots.meshes import resolve_shapes, without_shapes
from sim.wire.contract import STEP_S

__all__ = [
    "GRAVITY",
    "DEFAULT_STIFFNESS",
    "PhysicsError",
    "Mode",
    "DriveParams",
    "implicit_drive_step",
    "SimulatedJointState",
    "PhysicsWorld",
    "load_urdf_text",
    "render_gif",
]

log = logging.getLogger(__name__)

GRAVITY = -9.81  # m/s², along world z


class PhysicsError(SimError, ValueError):
    """Invalid physics input: targets of the wrong shape or not finite, bad drive parameters, bad step size."""


class Mode(str, Enum):
    PHYSICS = "physics"
    NO_PHYSICS = "no_physics"
    INFINITE_STIFFNESS = "infinite_stiffness"


# --------------------------------------------------------------------------------------------------------------
# Drive parameters

# Defaults for any robot, from its model (Unity ArticulationDrive units: N·m/rad, N·m·s/rad, N·m; N/m, N·s/m, N for
# prismatic joints):
# Stiffness: DEFAULT_STIFFNESS on every joint, as stiff as Unity users set position drives (1e4–1e5), which the
# implicit drive keeps stable at any dt.
# Damping: 2·sqrt(stiffness · M_ii) with M_ii the joint's inertia at the robot's home pose (pybullet's mass
# matrix), i.e. critically damped in continuous time, so the response does not depend on dt (backward Euler adds
# numerical damping of its own, which shrinks with dt). For the Panda, M_ii(home) ≈ [1.56, 2.35, 1.78, 1.65, 0.83,
# 0.74, 0.60] kg·m² gives ≈ [790, 970, 840, 810, 580, 540, 490]. With these values joint 1 of the thesis's test tracks
# to ~0.01 % MAPE. Less damping tracks closer still (damping weighs the end-of-step velocity feed-forward, which
# differs from the step's mean velocity by ~dt·acceleration/2, against the position target: D = 100 gives
# ~0.0004 %), but the drive is then under-damped and rings after disturbances once dt is small.
# Force limit: the robot's rated max_effort (unlimited where its URDF states none). The thesis's test needs at most
# ~6.3 N·m on Panda joint 1 (87 N·m allowed), so the limit never binds there; a step target saturates the drive,
# as it would on the real robot.
# Gravity feed-forward (physics mode, on by default): the drive adds the gravity torque g(q) of the measured state,
# as a real position controller with a model does, so a heavy link does not sag by m·g/K (a 20 kg vertical lift at
# K = 1e5 N/m would sit 2 mm low). The force limit bounds the sum.
DEFAULT_STIFFNESS = 1e5


@dataclass(frozen=True)
class DriveParams:
    """Per-joint drive gains, arrays in robot.joint_names order (Unity ArticulationDrive semantics)."""

    stiffness: np.ndarray  # N·m/rad (revolute) or N/m (prismatic)
    damping: np.ndarray  # N·m·s/rad or N·s/m
    force_limit: np.ndarray  # N·m or N, the largest |drive force|; inf = unlimited

    @classmethod
    def for_robot(cls, robot: RobotSpec, home_inertia: np.ndarray) -> DriveParams:
        """The defaults for `robot` (see DEFAULT_STIFFNESS above), `home_inertia` being the diagonal of its mass
        matrix at home (`PhysicsWorld.home_inertia()`)."""
        stiffness = np.full(robot.dof, DEFAULT_STIFFNESS)
        damping = 2.0 * np.sqrt(stiffness * np.maximum(np.asarray(home_inertia, dtype=float), 0.0))
        return cls(stiffness, damping, np.array(robot.max_effort, dtype=float))

    def with_overrides(
        self, stiffness: float | None = None, damping: float | None = None, force_limit: float | None = None
    ) -> DriveParams:
        """A copy with the given values for every joint; None keeps the current per-joint values."""
        changes = {}
        for name, value in (("stiffness", stiffness), ("damping", damping), ("force_limit", force_limit)):
            if value is not None:
                changes[name] = np.full_like(getattr(self, name), float(value), dtype=float)
        return replace(self, **changes)

    def validated(self, dof: int) -> DriveParams:
        """Self as float arrays of length `dof`, or PhysicsError naming the bad field."""
        arrays = {}
        for name in ("stiffness", "damping", "force_limit"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != (dof,):
                raise PhysicsError(f"drive {name} has shape {value.shape}, expected ({dof},)")
            if np.any(np.isnan(value)) or np.any(value < 0):
                raise PhysicsError(f"drive {name} must be >= 0 (not NaN), got {value.tolist()}")
            arrays[name] = value
        if not np.all(np.isfinite(arrays["stiffness"])) or not np.all(np.isfinite(arrays["damping"])):
            raise PhysicsError("drive stiffness and damping must be finite; use Mode.INFINITE_STIFFNESS instead")
        return DriveParams(**arrays)


# --------------------------------------------------------------------------------------------------------------
# The implicit drive (pure numpy, unit-tested on its own)


def implicit_drive_step(
    mass: np.ndarray,
    bias: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    target: np.ndarray,
    target_velocity: np.ndarray,
    drive: DriveParams,
    dt: float,
    bias_jacobian: np.ndarray | None = None,
    feedforward: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(v⁺, F): next velocity and drive force of one backward-Euler step of M·q̈ + c(q, q̇) = F.

    The drive force is evaluated at the END of the step, q⁺ = q + dt·v⁺:
        F = K·(x* − q − dt·v⁺) − D·(v⁺ − v*),        M·(v⁺ − v)/dt = F − c
    hence  (M + dt·D + dt²·K)·v⁺ = M·v + dt·(K·(x* − q) + D·v* − c).
    The added dt·D + dt²·K on the diagonal makes the step stable for any gains (an explicit PD at dt = 0.02 s
    diverges once dt·sqrt(K/M) > 2, i.e. already at K ≈ 1e4 for a 1 kg·m² joint).

    bias_jacobian C = ∂c/∂q̇ (optional): the Coriolis/centrifugal torques are then linearised at the end of the
    step too, c(v⁺) ≈ c(v) + C·(v⁺ − v), i.e. M is replaced by M + dt·C. Without it, a robot whipped around at tens
    of rad/s (a force-limited drive chasing a far target) gains energy from the explicit v² terms and blows up.

    Force limit: F_i = clip(drive law_i(v⁺), ±limit_i), a piecewise linear equation in v⁺ (the drive law decreases
    in v⁺_i, so for positive definite M it has exactly one solution). Solved by a semi-smooth Newton method with
    backtracking on |residual|²: exact in a few iterations. Clamping joints one by one instead can cycle or settle
    on a wrong set of clamped joints, which feeds the robot energy (seen: NaN within seconds on a far step target).
    v⁺ is finally recomputed from the forces so that M·(v⁺ − v)/dt = F − c holds to rounding.

    feedforward (optional): a force added to the drive law before the limit, e.g. the gravity torque g(q).
    """
    stiffness, damping, limit = drive.stiffness, drive.damping, drive.force_limit
    inertia = mass if bias_jacobian is None else mass + dt * bias_jacobian
    spring = stiffness * (target - q) + damping * target_velocity  # the drive's terms that do not depend on v⁺
    if feedforward is not None:
        spring = spring + feedforward
    slope = dt * stiffness + damping  # the drive law is spring − slope·v⁺
    momentum = inertia @ v - dt * bias
    v_next = np.linalg.solve(inertia + dt * np.diag(slope), momentum + dt * spring)  # the unlimited solution
    force = spring - slope * v_next
    if np.all(np.abs(force) <= limit):
        return v_next, force
    scale = float(np.max(np.abs(momentum))) + float(np.max(np.abs(dt * spring))) + 1.0
    for _ in range(50):
        residual = _drive_residual(v_next, inertia, momentum, spring, slope, limit, dt)
        merit = float(residual @ residual)
        if merit <= (1e-12 * scale) ** 2:
            break
        linear = np.abs(spring - slope * v_next) < limit
        direction = -np.linalg.solve(inertia + dt * np.diag(np.where(linear, slope, 0.0)), residual)
        step = 1.0
        while step > 1e-10:  # backtrack until the residual shrinks (Armijo on |residual|²)
            trial = _drive_residual(v_next + step * direction, inertia, momentum, spring, slope, limit, dt)
            if float(trial @ trial) <= (1.0 - 1e-4 * step) * merit:
                break
            step *= 0.5
        v_next = v_next + step * direction
    else:
        log.debug("force-limited drive step stopped after 50 Newton iterations")
    force = np.clip(spring - slope * v_next, -limit, limit)
    return np.linalg.solve(inertia, momentum + dt * force), force


def _drive_residual(
    velocity: np.ndarray,
    inertia: np.ndarray,
    momentum: np.ndarray,
    spring: np.ndarray,
    slope: np.ndarray,
    limit: np.ndarray,
    dt: float,
) -> np.ndarray:
    """Newton's law of the step, zero at the solution: inertia·v⁺ − momentum − dt·clip(drive law, ±limit)."""
    return inertia @ velocity - momentum - dt * np.clip(spring - slope * velocity, -limit, limit)


# --------------------------------------------------------------------------------------------------------------
# The world


@dataclass(frozen=True)
class SimulatedJointState:
    """The physics world's joint state after a step, as the engine publishes it on joint_states."""

    time: float  # sim seconds since the world was made
    positions: np.ndarray  # rad or m, robot.joint_names order
    velocities: np.ndarray  # rad/s or m/s
    efforts: np.ndarray  # the drive's applied force/torque over the last step (N·m or N)


class PhysicsWorld:
    """One robot in a pybullet DIRECT client of its own; several worlds can live in one process."""

    def __init__(
        self,
        robot: RobotSpec,
        mode: Mode = Mode.PHYSICS,
        dt: float = STEP_S,
        substeps: int = 1,
        drive: DriveParams | None = None,
        gravity: bool = True,
        q0: Sequence[float] | np.ndarray | None = None,
        gravity_feedforward: bool = True,
        shapes: bool = False,
    ) -> None:
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise PhysicsError(f"dt must be a finite number > 0 s, got {dt!r}")
        if not (isinstance(substeps, int) and substeps >= 1):
            raise PhysicsError(f"substeps must be an integer >= 1, got {substeps!r}")
        self.robot = robot
        self.mode = Mode(mode)
        self.dt = float(dt)
        self.substeps = substeps
        self.shapes = shapes  # visual and collision shapes: only pictures need them (there are no contacts)
        # Gravity feed-forward only where there is gravity to feed forward and a drive to add it to.
        self.gravity_feedforward = bool(gravity_feedforward and gravity and self.mode is Mode.PHYSICS)
        self._client = p.connect(p.DIRECT)
        try:
            self._load(gravity)
            self.drive = (drive if drive is not None else DriveParams.for_robot(robot, self.home_inertia())).validated(
                robot.dof
            )
        except Exception:
            p.disconnect(physicsClientId=self._client)
            raise
        if robot.default_inertia_links and self.mode is not Mode.NO_PHYSICS:
            log.warning(
                "%s: link(s) %s have no <inertial> in %s; pybullet gives each 1 kg and a default inertia, "
                "which the dynamics then include",
                robot.name,
                ", ".join(robot.default_inertia_links),
                robot.urdf_path,
            )
        if robot.zeroed_inertia_links and self.mode is not Mode.NO_PHYSICS:
            log.warning(
                "%s: link(s) %s have inertia tensors that are not physical in %s (principal moments that "
                "break the triangle inequality); pybullet sets their inertia to zero and keeps the mass",
                robot.name,
                ", ".join(robot.zeroed_inertia_links),
                robot.urdf_path,
            )
        start = robot.home if q0 is None else q0
        self._q = self._checked("q0", start)
        self._v = np.zeros(robot.dof)
        self._effort = np.zeros(robot.dof)
        self._target = self._q.copy()
        self._target_velocity = np.zeros(robot.dof)
        self._start_target, self._start_velocity = self._target, self._target_velocity  # for substeps
        self._time = 0.0
        self._engine_synced = False

    def _load(self, gravity: bool) -> None:
        cid = self._client
        p.setGravity(0.0, 0.0, GRAVITY if gravity else 0.0, physicsClientId=cid)
        p.setTimeStep(self.dt / self.substeps, physicsClientId=cid)
        # The dynamics come from <inertial> alone. With shapes (for pictures), their files are found as ROS finds
        # them (package:// through rospack), and shapes whose mesh is nowhere are left out.
        urdf = self.robot.urdf_path
        text = urdf.read_text(encoding="utf-8")
        if not self.shapes:
            text = without_shapes(text)
        else:
            text, missing = resolve_shapes(text, urdf.parent, find_ros_package)
            if missing:
                log.warning(
                    "%s: %d mesh or texture file(s) named in %s are nowhere (e.g. %s); pictures show the "
                    "robot without them",
                    self.robot.name,
                    len(missing),
                    urdf,
                    missing[0],
                )
        # URDF_USE_INERTIA_FROM_FILE: the URDF's inertias, not pybullet's estimate from the collision shapes.
        self._body = load_urdf_text(text, urdf.name, cid, flags=p.URDF_USE_INERTIA_FROM_FILE)
        names_to_index: dict[str, int] = {}
        self._link_index = {p.getBodyInfo(self._body, physicsClientId=cid)[0].decode(): -1}
        self._dof_indices: list[int] = []  # pybullet joint index of every movable joint, in DoF order
        for index in range(p.getNumJoints(self._body, physicsClientId=cid)):
            info = p.getJointInfo(self._body, index, physicsClientId=cid)
            names_to_index[info[1].decode()] = index
            self._link_index[info[12].decode()] = index
            if info[2] in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC):
                self._dof_indices.append(index)
            elif info[2] != p.JOINT_FIXED:
                raise PhysicsError(f"joint {info[1].decode()!r} of {self.robot.name} has unsupported type {info[2]}")
        missing = [name for name in self.robot.joint_names if name not in names_to_index]
        if missing:
            raise PhysicsError(f"joints {missing} of {self.robot.name} are not in {self.robot.urdf_path}")
        if self.robot.ee_link not in self._link_index:
            raise PhysicsError(f"end-effector link {self.robot.ee_link!r} is not in {self.robot.urdf_path}")
        self._joint_indices = [names_to_index[name] for name in self.robot.joint_names]
        # Position of each controlled joint within the full DoF vector that pybullet's dynamics functions take.
        self._controlled = np.array([self._dof_indices.index(i) for i in self._joint_indices])
        self._full_q = np.array([p.getJointState(self._body, i, physicsClientId=cid)[0] for i in self._dof_indices])
        # Only our forces act: pybullet's default velocity motors would otherwise brake every joint.
        p.setJointMotorControlArray(
            self._body,
            self._dof_indices,
            p.VELOCITY_CONTROL,
            forces=[0.0] * len(self._dof_indices),
            physicsClientId=cid,
        )

    def home_inertia(self) -> np.ndarray:
        """The diagonal of the mass matrix over the controlled joints at home: each joint's inertia (kg·m² or kg)."""
        mass, _ = self._dynamics(np.asarray(self.robot.home, dtype=float), np.zeros(self.robot.dof))
        return np.diag(mass).copy()

    def set_drive(self, drive: DriveParams) -> None:
        """Other drive gains from the next step on (e.g. `world.drive.with_overrides(stiffness=1e4)`)."""
        self.drive = drive.validated(self.robot.dof)

    # --- life cycle ---------------------------------------------------------------------------------------------
    def close(self) -> None:
        if self._client is not None:
            p.disconnect(physicsClientId=self._client)
            self._client = None

    def __enter__(self) -> PhysicsWorld:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def _require_open(self) -> int:
        if self._client is None:
            raise PhysicsError(f"the {self.robot.name} world is closed")
        return self._client

    # --- inputs -------------------------------------------------------------------------------------------------
    def _checked(self, what: str, values: Sequence[float] | np.ndarray) -> np.ndarray:
        try:
            array = np.array(values, dtype=float)
        except (TypeError, ValueError):
            raise PhysicsError(f"{what} must be {self.robot.dof} numbers, got {values!r}") from None
        if array.shape != (self.robot.dof,):
            raise PhysicsError(
                f"{what} has shape {array.shape}, expected ({self.robot.dof},) for {list(self.robot.joint_names)}"
            )
        if not np.all(np.isfinite(array)):
            bad = [name for name, ok in zip(self.robot.joint_names, np.isfinite(array)) if not ok]
            raise PhysicsError(f"{what} must be finite; not finite for {bad}: {array.tolist()}")
        return array

    def set_targets(
        self, positions: Sequence[float] | np.ndarray, velocities: Sequence[float] | np.ndarray | None = None
    ) -> None:
        """Targets for the END of the next step (robot.joint_names order); velocities default to 0."""
        target = self._checked("target positions", positions)
        target_velocity = (
            np.zeros(self.robot.dof) if velocities is None else self._checked("target velocities", velocities)
        )
        self._target, self._target_velocity = target, target_velocity

    def reset(self, q: Sequence[float] | np.ndarray) -> None:
        """Teleport to `q` at rest, holding it (targets = q). Sim time keeps running."""
        self._q = self._checked("reset positions", q)
        self._v = np.zeros(self.robot.dof)
        self._effort = np.zeros(self.robot.dof)
        self._target = self._q.copy()
        self._target_velocity = np.zeros(self.robot.dof)
        self._start_target, self._start_velocity = self._target, self._target_velocity
        self._engine_synced = False

    # --- stepping -----------------------------------------------------------------------------------------------
    def step(self) -> SimulatedJointState:
        """Advance exactly one fixed step dt towards the targets set before it."""
        self._require_open()
        if self.mode is Mode.NO_PHYSICS:
            self._q, self._v, self._effort = self._target.copy(), self._target_velocity.copy(), np.zeros(self.robot.dof)
        elif self.mode is Mode.INFINITE_STIFFNESS:
            v_next = (self._target - self._q) / self.dt
            mass, bias = self._dynamics(self._q, self._v)
            self._effort = mass @ (v_next - self._v) / self.dt + bias
            self._q, self._v = self._target.copy(), v_next
        else:
            self._step_drive()
        self._start_target, self._start_velocity = self._target, self._target_velocity
        self._time += self.dt
        self._engine_synced = False
        return self.state()

    def _step_drive(self) -> None:
        # Substeps follow the target linearly from the previous step's end to this one's (not a jump at the start).
        h = self.dt / self.substeps
        for i in range(1, self.substeps + 1):
            share = i / self.substeps
            target = self._start_target + share * (self._target - self._start_target)
            target_velocity = self._start_velocity + share * (self._target_velocity - self._start_velocity)
            mass, bias = self._dynamics(self._q, self._v)
            feedforward = self._gravity(self._q) if self.gravity_feedforward else None
            v_next, force = implicit_drive_step(
                mass,
                bias,
                self._q,
                self._v,
                target,
                target_velocity,
                self.drive,
                h,
                bias_jacobian=self._bias_jacobian(self._q, self._v),
                feedforward=feedforward,
            )
            self._q = self._q + h * v_next
            self._v = v_next
            self._effort = force

    def _bias_jacobian(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """C = ∂c/∂q̇ by central differences of unit size, exact because c is quadratic in q̇."""
        full_q, full_v = self._full_vectors(q, v)
        zeros = [0.0] * len(full_q)
        jacobian = np.empty((v.size, v.size))
        for column, dof in enumerate(self._controlled):
            faster, slower = list(full_v), list(full_v)  # plain lists: this loop is the drive's main cost
            faster[dof] += 1.0
            slower[dof] -= 1.0
            high = p.calculateInverseDynamics(self._body, full_q, faster, zeros, physicsClientId=self._client)
            low = p.calculateInverseDynamics(self._body, full_q, slower, zeros, physicsClientId=self._client)
            jacobian[:, column] = (np.array(high)[self._controlled] - np.array(low)[self._controlled]) / 2.0
        return jacobian

    def _bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        full_q, full_v = self._full_vectors(q, v)
        bias = p.calculateInverseDynamics(self._body, full_q, full_v, [0.0] * len(full_q), physicsClientId=self._client)
        return np.array(bias)[self._controlled]

    def _gravity(self, q: np.ndarray) -> np.ndarray:
        """g(q): the joint torques that hold the robot still at q against gravity."""
        return self._bias(q, np.zeros_like(q))

    def _full_vectors(self, q: np.ndarray, v: np.ndarray) -> tuple[list[float], list[float]]:
        """Pybullet's full DoF vectors: the controlled joints from q, v; the locked ones at rest where they are."""
        full_q = self._full_q.copy()
        full_q[self._controlled] = q
        full_v = np.zeros_like(full_q)
        full_v[self._controlled] = v
        return full_q.tolist(), full_v.tolist()

    def _dynamics(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """M and c = gravity + Coriolis over the controlled joints, the others locked (zero velocity)."""
        full_q, _ = self._full_vectors(q, v)
        mass = np.array(p.calculateMassMatrix(self._body, full_q, physicsClientId=self._client))
        return mass[np.ix_(self._controlled, self._controlled)], self._bias(q, v)

    # --- outputs ------------------------------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return self._time

    def state(self) -> SimulatedJointState:
        return SimulatedJointState(self._time, self._q.copy(), self._v.copy(), self._effort.copy())

    def _sync_engine(self) -> int:
        """Copy our joint state into pybullet (only needed for kinematics and pictures, hence lazily)."""
        cid = self._require_open()
        if not self._engine_synced:
            for index, position, velocity in zip(self._joint_indices, self._q, self._v):
                p.resetJointState(
                    self._body, index, float(position), targetVelocity=float(velocity), physicsClientId=cid
                )
            self._engine_synced = True
        return cid

    def ee_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """End-effector link frame in the world: (position xyz in m, quaternion xyzw)."""
        cid = self._sync_engine()
        index = self._link_index[self.robot.ee_link]
        if index == -1:
            position, orientation = p.getBasePositionAndOrientation(self._body, physicsClientId=cid)
        else:
            # [4:6] is the link frame; [0:2] would be the link's centre of mass.
            position, orientation = p.getLinkState(
                self._body, index, computeForwardKinematics=True, physicsClientId=cid
            )[4:6]
        return np.array(position), np.array(orientation)

    def capture(self, width: int = 640, height: int = 480) -> np.ndarray:
        """An RGB picture (height, width, 3 uint8) of the robot from pybullet's headless TinyRenderer."""
        if not self.shapes:
            raise PhysicsError("this world was made without shapes; make it with shapes=True to take pictures")
        cid = self._sync_engine()
        base = np.array(p.getBasePositionAndOrientation(self._body, physicsClientId=cid)[0])
        ee, _ = self.ee_pose()
        reach = max(float(np.linalg.norm(ee - base)), 0.3)
        view = p.computeViewMatrixFromYawPitchRoll(
            cameraTargetPosition=((base + ee) / 2).tolist(),
            distance=2.2 * reach,
            yaw=50.0,
            pitch=-25.0,
            roll=0.0,
            upAxisIndex=2,
        )
        projection = p.computeProjectionMatrixFOV(fov=50.0, aspect=width / height, nearVal=0.05, farVal=20.0)
        _, _, rgba, _, _ = p.getCameraImage(
            width, height, view, projection, renderer=p.ER_TINY_RENDERER, physicsClientId=cid
        )
        return np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[:, :, :3]

    def render(self, path: str | Path, width: int = 640, height: int = 480) -> Path:
        """Write a PNG of the current pose to `path`."""
        from PIL import Image  # Pillow comes with matplotlib; only pictures need it

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(self.capture(width, height)).save(path, format="PNG")
        return path


def load_urdf_text(
    text: str,
    file_name: str,
    client: int,
    position: Sequence[float] = (0.0, 0.0, 0.0),
    orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
    flags: int = 0,
) -> int:
    """Load URDF text (e.g. with its shapes resolved or removed) as a fixed-base body: pybullet loads only files,
    so it goes through a temporary one named `file_name`. Returns the body's id."""
    with tempfile.TemporaryDirectory(prefix="sim_urdf_") as folder:
        path = Path(folder) / file_name
        path.write_text(text, encoding="utf-8")
        return int(
            p.loadURDF(
                str(path), list(position), list(orientation), useFixedBase=True, flags=flags, physicsClientId=client
            )
        )


def render_gif(frames: Sequence[np.ndarray], path: str | Path, frame_duration_s: float = 0.1) -> Path:
    """Write RGB frames (e.g. from PhysicsWorld.capture) as a looping animated GIF."""
    from PIL import Image

    if not frames:
        raise PhysicsError(f"no frames to write to {path}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    images = [Image.fromarray(np.asarray(frame, dtype=np.uint8)) for frame in frames]
    images[0].save(
        path,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=max(int(round(frame_duration_s * 1000)), 10),
        loop=0,
    )
    return path
