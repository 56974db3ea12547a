"""What a scenario is: its options (`ScenarioConfig`), the `Motion` it yields, its errors, and the checks every
scenario's samples pass. Pure logic."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from sim.control.scenarios.defaults import IK_HOLD_S, IK_MOVE_TIME_S, IK_RESTARTS, IK_SEED
from sim.errors import SimError
from sim.geometry.trajectory import PolynomialTrajectory
from sim.robots import RobotSpec
from sim.wire.contract import STEP_S

__all__ = [
    "ScenarioError",
    "UnreachableGoalError",
    "ScenarioConfig",
    "IKReport",
    "Motion",
    "sample_times",
    "checked_vector",
    "joint_index",
    "sample_trajectory",
    "fit_duration",
    "check_position_limits",
    "velocity_warnings",
    "checked_motion",
]


class ScenarioError(SimError, ValueError):
    """A scenario that cannot be built from the given options (the message names the offending value)."""


class UnreachableGoalError(ScenarioError):
    """IK found no configuration within tolerance; carries the best residual found."""

    def __init__(self, message: str, position_error: float, orientation_error: float) -> None:
        super().__init__(message)
        self.position_error = position_error
        self.orientation_error = orientation_error


@dataclass
class ScenarioConfig:
    """Options of `build_motion`; None means the scenario's default (see sim.control.scenarios)."""

    dt: float = STEP_S
    duration: float | None = None  # total length in s: the motion is cut, or its end held
    positions: Sequence[float] | None = None  # single
    joint: str | None = None  # one_joint: a joint name or a 1-based index
    waypoints: Sequence[float] | None = None  # one_joint
    times: Sequence[float] | None = None  # one_joint
    order: str = "quintic"
    start: Sequence[float] | None = None  # IK: start position (m); default FK(home)
    goal: Sequence[float] | None = None  # IK: goal position (m); x, y only where z is not controlled
    goal_rpy: Sequence[float] | None = None  # IK: goal XYZ Euler angles (rad); given -> the axes the chain controls
    weights: Sequence[float] | None = None  # IK: x, y, z, roll, pitch, yaw weights (>= 0); default: see above
    move_time: float = IK_MOVE_TIME_S
    hold: float = IK_HOLD_S
    space: str | None = None  # ik_orientation / fk_confirm: joint | cartesian
    nearest: bool = False  # use the nearest configuration found when the goal is unreachable
    ik_restarts: int = IK_RESTARTS
    seed: int = IK_SEED


@dataclass
class IKReport:
    success: bool  # every IK problem of the scenario solved within tolerance
    goal_position_error: float  # m, FK(desired end) vs goal, over the weighted axes
    goal_orientation_error: float  # rad, idem
    weights: tuple[float, ...]
    space: str
    max_joint_jump: float = 0.0  # rad or m between consecutive samples (cartesian space)
    failed_samples: int = 0
    fallback: bool = False  # the nearest configuration found is commanded instead of an unreachable goal
    message: str = ""


@dataclass
class Motion:
    scenario: str
    robot: RobotSpec
    dt: float
    times: np.ndarray  # (N,) = k·dt
    positions: np.ndarray  # (N, n)
    velocities: np.ndarray  # (N, n)
    description: str
    goal: np.ndarray | None = None  # 4x4 end-effector goal
    reference_path: np.ndarray | None = None  # (N, 4, 4) Cartesian reference of the motion
    ik: IKReport | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    @property
    def steps(self) -> int:
        return len(self.times) - 1


def sample_times(duration: float, dt: float) -> np.ndarray:
    """t_k = k·dt for k = 0..ceil(duration/dt): computed from k, so grid values do not drift."""
    if not (math.isfinite(dt) and dt > 0):
        raise ScenarioError(f"dt must be a finite number > 0 s, got {dt!r}")
    if not (math.isfinite(duration) and duration > 0):
        raise ScenarioError(f"duration must be a finite number > 0 s, got {duration!r}")
    steps = int(math.ceil(duration / dt - 1e-9))
    return np.arange(steps + 1) * dt


def checked_vector(values: Sequence[float] | np.ndarray | None, size: int | tuple[int, ...], what: str) -> np.ndarray:
    sizes = (size,) if isinstance(size, int) else size
    array = np.asarray(values, dtype=float).reshape(-1)
    if array.size not in sizes:
        expected = " or ".join(str(s) for s in sizes)
        raise ScenarioError(f"{what} needs {expected} values, got {array.size}: {array.tolist()}")
    if not np.all(np.isfinite(array)):
        raise ScenarioError(f"{what} must be finite numbers, got {array.tolist()}")
    return array


def joint_index(robot: RobotSpec, joint: str) -> int:
    """Index of a joint given by name or 1-based number ("1" = the first joint)."""
    if joint in robot.joint_names:
        return robot.joint_names.index(joint)
    try:
        number = int(joint)
    except ValueError:
        number = 0
    if 1 <= number <= robot.dof:
        return number - 1
    raise ScenarioError(
        f"unknown joint {joint!r} for {robot.name}: give 1..{robot.dof} or one of {list(robot.joint_names)}"
    )


def sample_trajectory(traj: PolynomialTrajectory, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    sample = traj.sample(times)
    return sample.positions, sample.velocities


def fit_duration(natural_end: float, duration: float | None, dt: float) -> np.ndarray:
    """Samples over `duration` if given (cutting the motion or holding its end), else over its natural length."""
    return sample_times(natural_end if duration is None else duration, dt)


def check_position_limits(robot: RobotSpec, times: np.ndarray, positions: np.ndarray, what: str) -> None:
    below = positions < robot.lower - 1e-9
    above = positions > robot.upper + 1e-9
    if below.any() or above.any():
        k, j = np.argwhere(below | above)[0]
        raise ScenarioError(
            f"{what}: {robot.joint_names[j]} = {positions[k, j]:.4f} at t = {times[k]:.2f} s is outside its limits "
            f"[{robot.lower[j]:.4f}, {robot.upper[j]:.4f}]"
        )


def velocity_warnings(robot: RobotSpec, times: np.ndarray, velocities: np.ndarray) -> list[str]:
    notes = []
    for j, name in enumerate(robot.joint_names):
        peak = np.abs(velocities[:, j])
        k = int(np.argmax(peak))
        if peak[k] > robot.max_velocity[j] + 1e-9:
            unit = "m/s" if robot.joint_types[j] == "prismatic" else "rad/s"
            notes.append(
                f"{name} peaks at {peak[k]:.3f} {unit} (t = {times[k]:.2f} s), above its limit "
                f"{robot.max_velocity[j]:.3f} {unit}"
            )
    return notes


def checked_motion(motion: Motion) -> Motion:
    check_position_limits(motion.robot, motion.times, motion.positions, f"scenario {motion.scenario}")
    motion.warnings.extend(velocity_warnings(motion.robot, motion.times, motion.velocities))
    return motion
