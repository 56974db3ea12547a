"""The commander's scenarios as pure data: scenario name + options -> desired joint trajectory sampled at dt.

No ROS here (sim.commander streams what this module builds). Every scenario yields a `Motion`: samples at
t_k = k·dt, k = 0..N-1, of joint positions and velocities (robot joint order, rad or m), starting at rest. For the
IK scenarios also the end-effector goal (4x4, base frame, ROS RH z-up), the Cartesian reference path (one 4x4 per
sample), the IK weights and a goal report.

Scenarios (defaults in brackets; "home" = the robot's home configuration). Defaults not stated for a robot are
computed from its limits and its chain (sim.control.scenario_defaults); the Panda's and the igt's below are kept in
their
robot YAML (sim/robots/*.yaml) so that they stay the motions the README documents:

  single          constant joint positions [home]; runs `duration` [5 s]. Like the thesis's a_SingleInput.
  one_joint       one joint through waypoints at times, polynomial (`order` [quintic]), others hold home.
                  [computed: the first joint through fractions of its range, slowed to 0.8 of its velocity limit];
                  panda [joint 1 through 0.25, 1, 2.75, 1.5, -2, -2.45 rad at t = 0, 2, ..., 10 s];
                  igt [the rail through 0.05, 0.2, 0, -0.2, 0.05, -0.15 m at t = 0, 2, ..., 10 s];
                  `duration` [last waypoint time + 1 s]. (The seed held the other Panda joints at 0, but 0 is
                  outside Franka's limits for panda_joint4 (-3.0718 .. -0.0698 rad), hence home.)
                  Note: the thesis's 1.5 -> -2 rad in 2 s peaks at 3.28 rad/s, above the Panda's 2.175 rad/s joint-1
                  limit; this is kept as the thesis had it and reported as a warning.
  ik_joints       IK of start and goal, then a polynomial in joint space over `move_time` [4 s] and a `hold` [1 s].
                  IK weights [the axes the chain controls; position only where it controls x, y and z and no goal
                  orientation is given] (`weights`). [computed: FK of a reachable offset from home];
                  panda [start = home flange position, goal 0.5, 0.375, 0.75 m, position only];
                  igt [start = home tool tip, goal x, y = 0.3, 0.4 m, yaw 1.0 rad; x, y, yaw weights].
  ik_cartesian    polynomial in Cartesian space (position quintic, orientation along the geodesic with the same
                  time scaling), IK of every sample warm-started from the previous one; the max joint jump between
                  samples is reported. Same defaults as ik_joints.
  ik_orientation  position + XYZ Euler goal (fixed axes, R = Rz·Ry·Rx, = URDF rpy), weighting every axis the chain
                  controls (the full pose for the Panda) [computed: FK of an offset from home the other way],
                  panda [0.3, 0.5, 0.75 m at pi/4, pi/5, pi/3 rad; reachable: IK finds it after a few restarts];
                  igt [x, y = 0.45, -0.25 m, yaw -1.0 rad] (the igt can only reach x, y, yaw).
                  `space` [joint] or cartesian.
  fk_confirm      an IK motion (`space` [cartesian], goal as ik_joints); the commander compares FK of the achieved
                  joint states with the reference path. The reference path is what the motion means in Cartesian
                  space: the Cartesian polynomial (cartesian) or FK of the desired joints (joint).
  trial           the accuracy trial, `duration` [40 s]: every joint at once follows
                  c -> c+A -> c -> c-A -> c -> c-A -> c -> c+A -> c in eight quintic segments of 5 s (time-symmetric,
                  amplitude-antisymmetric), with per-joint centres c and amplitudes A (`trial_table`): inside the
                  limits with margin, and of one sign over the whole swing (c ± A ≠ 0) so that MAPE, which divides
                  by the reference, stays meaningful. Peak speeds are well below the limits.

Unreachable IK goals raise `UnreachableGoalError` with the best residual, unless `nearest=True`: then the best
configuration found is used and the motion says so (`Motion.ik.fallback`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.control.scenario_defaults import (
    ONE_JOINT_SPEED_FRACTION,
    controllable_weights,
    describe_axes,
    ik_goal,
    one_joint_default,
    position_weights,
    rotates_about_z_only,
    trial_table,
)
from sim.errors import SimError
from sim.geometry.frames import matrix_to_rpy, rotation_exp, rotation_vector, rpy_to_matrix
from sim.geometry.kinematics import (
    IKResult,
    KinematicChain,
    chain_for,
    solve_ik,
    solve_path_ik,
)
from sim.geometry.trajectory import ORDERS, PolynomialTrajectory
from sim.robots import RobotSpec
from sim.wire.contract import STEP_S
from sim.wire.joint_csv import write_joint_csv

__all__ = [
    "SCENARIOS",
    "IK_SCENARIOS",
    "SPACES",
    "SINGLE_DURATION_S",
    "ONE_JOINT_SPACING_S",
    "ONE_JOINT_HOLD_S",
    "IK_MOVE_TIME_S",
    "IK_HOLD_S",
    "IK_RESTARTS",
    "IK_SEED",
    "IK_TOL_POS",
    "IK_TOL_ROT",
    "TRIAL_DURATION_S",
    "TRIAL_SEGMENT_S",
    "TRIAL_PATTERN",
    "APPROACH_MIN_S",
    "APPROACH_SPEED_FRACTION",
    "ScenarioError",
    "UnreachableGoalError",
    "ScenarioConfig",
    "IKReport",
    "Motion",
    "sample_times",
    "joint_index",
    "check_position_limits",
    "velocity_warnings",
    "pose_errors",
    "fk_path",
    "approach",
    "build_motion",
    "write_engine_csv",
    "Schedule",
    "build_schedule",
]

SCENARIOS: tuple[str, ...] = (
    "single",
    "one_joint",
    "ik_joints",
    "ik_cartesian",
    "ik_orientation",
    "fk_confirm",
    "trial",
)
IK_SCENARIOS: tuple[str, ...] = ("ik_joints", "ik_cartesian", "ik_orientation", "fk_confirm")
SPACES = ("joint", "cartesian")

SINGLE_DURATION_S = 5.0
ONE_JOINT_SPACING_S = 2.0
ONE_JOINT_HOLD_S = 1.0
IK_MOVE_TIME_S = 4.0
IK_HOLD_S = 1.0
IK_RESTARTS = 20
IK_SEED = 0
IK_TOL_POS = 1e-6  # m
IK_TOL_ROT = 1e-5  # rad
TRIAL_DURATION_S = 40.0
TRIAL_SEGMENT_S = 5.0
TRIAL_PATTERN = (0.0, 1.0, 0.0, -1.0, 0.0, -1.0, 0.0, 1.0, 0.0)  # multiples of A around c, one per 5 s
APPROACH_MIN_S = 2.0
APPROACH_SPEED_FRACTION = 0.5  # approach segments peak at no more than this fraction of the velocity limits


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
    """Options of `build_motion`; None means the scenario's default (see the module docstring)."""

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


# ------------------------------------------------------------------------------------------------ helpers
def sample_times(duration: float, dt: float) -> np.ndarray:
    """t_k = k·dt for k = 0..ceil(duration/dt): computed from k, so grid values do not drift."""
    if not (math.isfinite(dt) and dt > 0):
        raise ScenarioError(f"dt must be a finite number > 0 s, got {dt!r}")
    if not (math.isfinite(duration) and duration > 0):
        raise ScenarioError(f"duration must be a finite number > 0 s, got {duration!r}")
    steps = int(math.ceil(duration / dt - 1e-9))
    return np.arange(steps + 1) * dt


def _vector(values: Sequence[float] | np.ndarray | None, size: int | tuple[int, ...], what: str) -> np.ndarray:
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


def _sample_trajectory(traj: PolynomialTrajectory, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    sample = traj.sample(times)
    return sample.positions, sample.velocities


def _fit_duration(natural_end: float, duration: float | None, dt: float) -> np.ndarray:
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


def _finish(motion: Motion) -> Motion:
    check_position_limits(motion.robot, motion.times, motion.positions, f"scenario {motion.scenario}")
    motion.warnings.extend(velocity_warnings(motion.robot, motion.times, motion.velocities))
    return motion


def pose_errors(actual: np.ndarray, reference: np.ndarray, weights: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample (position error [m], orientation error [rad]) of actual vs reference poses (N, 4, 4).

    Only the axes with a non-zero weight count, as in sim.geometry.kinematics: position = norm of the selected
    components of p_ref - p; orientation = angle of R_ref·Rᵀ if all rotation axes are selected, else the norm of
    the selected components of its rotation vector (for the igt's yaw-only weights: |yaw error|).
    """
    w = np.asarray(weights, dtype=float)
    pos_axes = w[:3] > 0
    rot_axes = w[3:] > 0
    position_error = np.linalg.norm((reference[:, :3, 3] - actual[:, :3, 3])[:, pos_axes], axis=1)
    orientation_error = np.zeros(len(actual))
    if rot_axes.any():
        for k in range(len(actual)):
            rotvec = rotation_vector(reference[k, :3, :3] @ actual[k, :3, :3].T)
            orientation_error[k] = np.linalg.norm(rotvec) if rot_axes.all() else np.linalg.norm(rotvec[rot_axes])
    return position_error, orientation_error


def fk_path(chain: KinematicChain, positions: np.ndarray) -> np.ndarray:
    return np.array([chain.fk(q) for q in positions])


# ----------------------------------------------------------------------------------------------- approach
def approach(
    robot: RobotSpec, q_from: np.ndarray, q_to: np.ndarray, dt: float, min_time: float = APPROACH_MIN_S
) -> tuple[np.ndarray, np.ndarray]:
    """A quintic from rest at q_from to rest at q_to, sampled at dt (first sample q_from, last q_to).

    Its length is at least `min_time` and long enough that no joint exceeds APPROACH_SPEED_FRACTION of its
    velocity limit (a quintic peaks at 1.875·Δ/T). Returns (positions, velocities), each (M+1, n).
    """
    q_from = _vector(q_from, robot.dof, "approach start")
    q_to = _vector(q_to, robot.dof, "approach end")
    needed = float(np.max(1.875 * np.abs(q_to - q_from) / (APPROACH_SPEED_FRACTION * robot.max_velocity)))
    duration = max(min_time, needed)
    times = sample_times(duration, dt)
    traj = PolynomialTrajectory([0.0, times[-1]], np.array([q_from, q_to]), order="quintic")
    return _sample_trajectory(traj, times)


# ---------------------------------------------------------------------------------------------- scenarios
def build_motion(robot: RobotSpec, scenario: str, config: ScenarioConfig | None = None) -> Motion:
    """The desired motion of `scenario` for `robot` (see the module docstring for what each one does)."""
    config = config or ScenarioConfig()
    if config.order not in ORDERS:
        raise ScenarioError(f"order must be one of {list(ORDERS)}, got {config.order!r}")
    if config.duration is not None and not (math.isfinite(config.duration) and config.duration > 0):
        raise ScenarioError(f"duration must be a finite number > 0 s, got {config.duration!r}")
    sample_times(1.0, config.dt)  # validates dt
    if config.ik_restarts < 0:
        raise ScenarioError(f"IK restarts must be >= 0, got {config.ik_restarts}")
    builders = {
        "single": _single,
        "one_joint": _one_joint,
        "ik_joints": _ik_motion,
        "ik_cartesian": _ik_motion,
        "ik_orientation": _ik_motion,
        "fk_confirm": _ik_motion,
        "trial": _trial,
    }
    if scenario not in builders:
        raise ScenarioError(f"unknown scenario {scenario!r}; known: {', '.join(SCENARIOS)}")
    return _finish(builders[scenario](robot, scenario, config))


def _single(robot: RobotSpec, scenario: str, config: ScenarioConfig) -> Motion:
    q = (
        robot.home.copy()
        if config.positions is None
        else _vector(config.positions, robot.dof, f"{robot.name} positions ({', '.join(robot.joint_names)})")
    )
    times = sample_times(SINGLE_DURATION_S if config.duration is None else config.duration, config.dt)
    positions = np.tile(q, (len(times), 1))
    return Motion(
        scenario,
        robot,
        config.dt,
        times,
        positions,
        np.zeros_like(positions),
        f"hold {np.round(q, 4).tolist()} for {times[-1]:.2f} s",
    )


def _one_joint(robot: RobotSpec, scenario: str, config: ScenarioConfig) -> Motion:
    default_joint, default_points = one_joint_default(robot)
    j = default_joint if config.joint is None else joint_index(robot, config.joint)
    if config.waypoints is None:
        if config.joint is not None and j != default_joint:
            raise ScenarioError(
                f"--joint {config.joint} needs --waypoints (the defaults are for {robot.joint_names[default_joint]})"
            )
        points = default_points
        if robot.hints.one_joint_waypoints is None:  # computed: slowed down to stay within the velocity limit
            points = _slowed(points, j, robot, config)
    else:
        points = _vector(config.waypoints, tuple(range(2, 1000)), "waypoints (at least 2)")
    if config.times is None:
        wp_times = np.arange(len(points)) * ONE_JOINT_SPACING_S
    else:
        wp_times = _vector(config.times, len(points), f"times (one per waypoint, {len(points)} waypoints)")
        if wp_times[0] < 0 or np.any(np.diff(wp_times) <= 0):
            raise ScenarioError(f"times must start at >= 0 s and increase strictly, got {wp_times.tolist()}")
    name = robot.joint_names[j]
    bad = (points < robot.lower[j] - 1e-9) | (points > robot.upper[j] + 1e-9)
    if bad.any():
        raise ScenarioError(
            f"waypoint {points[bad][0]} of {name} is outside its limits [{robot.lower[j]}, {robot.upper[j]}]"
        )
    if wp_times[0] > 0:  # hold the first waypoint from t = 0
        wp_times = np.concatenate([[0.0], wp_times])
        points = np.concatenate([[points[0]], points])
    traj = PolynomialTrajectory(wp_times, points, order=config.order)
    times = _fit_duration(wp_times[-1] + ONE_JOINT_HOLD_S, config.duration, config.dt)
    joint_pos, joint_vel = _sample_trajectory(traj, times)
    positions = np.tile(robot.home, (len(times), 1))
    velocities = np.zeros_like(positions)
    positions[:, j] = joint_pos[:, 0]
    velocities[:, j] = joint_vel[:, 0]
    description = (
        f"{name} through {points.tolist()} at t = {wp_times.tolist()} s ({config.order}), other joints at home"
    )
    return Motion(scenario, robot, config.dt, times, positions, velocities, description)


def _slowed(points: np.ndarray, j: int, robot: RobotSpec, config: ScenarioConfig) -> np.ndarray:
    """Computed one_joint waypoints drawn towards their mean until the motion peaks at ONE_JOINT_SPEED_FRACTION of
    the joint's velocity limit (the polynomial is linear in the waypoints, so one scaling does it)."""
    times = np.arange(len(points)) * ONE_JOINT_SPACING_S if config.times is None else np.asarray(config.times)
    if len(times) != len(points):
        return points  # the times are wrong; the caller reports it
    centre = float(np.mean(points))
    speeds = PolynomialTrajectory(times, points, order=config.order).sample(sample_times(times[-1], config.dt))
    peak = float(np.abs(speeds.velocities).max())
    limit = ONE_JOINT_SPEED_FRACTION * float(robot.max_velocity[j])
    return points if peak <= limit else centre + (points - centre) * (limit / peak)


def _trial(robot: RobotSpec, scenario: str, config: ScenarioConfig) -> Motion:
    centres, amplitudes = trial_table(robot)
    pattern = np.array(TRIAL_PATTERN)
    wp_times = np.arange(len(pattern)) * TRIAL_SEGMENT_S
    points = centres[None, :] + pattern[:, None] * amplitudes[None, :]
    traj = PolynomialTrajectory(wp_times, points, order="quintic")
    times = _fit_duration(TRIAL_DURATION_S, config.duration, config.dt)
    positions, velocities = _sample_trajectory(traj, times)
    description = (
        f"trial: every joint c -> c+A -> c -> c-A -> c -> c-A -> c -> c+A -> c, {TRIAL_SEGMENT_S:g} s quintic "
        f"segments; c = {centres.tolist()}, A = {amplitudes.tolist()}"
    )
    return Motion(scenario, robot, config.dt, times, positions, velocities, description)


# -------------------------------------------------------------------------------------------- IK scenarios
@dataclass
class _GoalSpec:
    target: np.ndarray  # 4x4
    weights: tuple[float, ...]
    text: str


def _default_goal(robot: RobotSpec, scenario: str, chain: KinematicChain) -> tuple[np.ndarray, np.ndarray | None]:
    """(position, rpy or None for position only): the robot YAML's, or computed (sim.control.scenario_defaults)."""
    hints = robot.hints
    if scenario == "ik_orientation":
        if hints.orientation_goal_position is not None:
            given = hints.orientation_goal_rpy
            return np.array(hints.orientation_goal_position), None if given is None else np.array(given)
        return ik_goal(robot, chain, orientation=True)
    if hints.ik_goal_position is not None:
        return np.array(hints.ik_goal_position), None if hints.ik_goal_rpy is None else np.array(hints.ik_goal_rpy)
    position, computed_rpy = ik_goal(robot, chain, orientation=False)
    # Position only where the chain controls x, y and z; else the goal's orientation is part of the goal.
    return position, None if all(controllable_weights(chain, robot.home)[:3]) else computed_rpy


def _weights(config: ScenarioConfig, chain: KinematicChain, robot: RobotSpec, oriented: bool) -> tuple[float, ...]:
    if config.weights is not None:
        weights = _vector(config.weights, 6, "IK weights (x, y, z, roll, pitch, yaw)")
        if np.any(weights < 0) or not np.any(weights > 0):
            raise ScenarioError(f"IK weights must be >= 0 with at least one > 0, got {weights.tolist()}")
        return tuple(float(w) for w in weights)
    controllable = controllable_weights(chain, robot.home)
    return controllable if oriented else position_weights(controllable)


def _goal_spec(robot: RobotSpec, scenario: str, config: ScenarioConfig, chain: KinematicChain) -> _GoalSpec:
    home_pose = chain.fk(robot.home)
    default_position, default_rpy = _default_goal(robot, scenario, chain)
    given_rpy = config.goal_rpy if config.goal_rpy is not None else default_rpy
    rpy = None if given_rpy is None else _vector(given_rpy, 3, "goal rpy (XYZ Euler angles in rad)")
    weights = _weights(config, chain, robot, oriented=rpy is not None or scenario == "ik_orientation")
    free_z = weights[2] == 0
    if config.goal is None:
        position = np.array(default_position, dtype=float)
    else:
        position = _vector(
            config.goal,
            (2, 3) if free_z else 3,
            f"{robot.name} goal (x, y [, z ignored] in m)" if free_z else "goal position (x, y, z in m)",
        )
    if position.size == 2 or free_z:  # the end effector's height is not controlled: it stays where home has it
        position = np.append(position[:2], home_pose[2, 3])
    target = np.eye(4)
    target[:3, 3] = position
    if not any(weights[3:]):
        target[:3, :3] = home_pose[:3, :3]  # reference orientation only; not weighted
        axes = describe_axes(weights)
        return _GoalSpec(target, weights, f"position {np.round(position, 6).tolist()} m ({axes} only)")
    if rpy is None:  # ik_orientation with no goal orientation given: keep home's
        rpy = np.array(matrix_to_rpy(home_pose[:3, :3]))
    home_rpy = matrix_to_rpy(home_pose[:3, :3])
    if rotates_about_z_only(chain, robot.home) and abs(home_rpy[0]) < 1e-9 and abs(home_rpy[1]) < 1e-9:
        if abs(rpy[0]) > 1e-12 or abs(rpy[1]) > 1e-12:  # e.g. the igt: rotations about z only, by construction
            raise ScenarioError(
                f"the {robot.name} can only reach {describe_axes(weights)}: goal rpy {list(rpy)} must "
                f"have roll = pitch = 0"
            )
    target[:3, :3] = rpy_to_matrix(*rpy)
    axes = "" if all(weights) else f" ({describe_axes(weights)})"
    return _GoalSpec(
        target, weights, f"position {np.round(position, 6).tolist()} m, XYZ Euler {np.round(rpy, 6).tolist()} rad{axes}"
    )


def _start_target(
    robot: RobotSpec, config: ScenarioConfig, chain: KinematicChain, weights: Sequence[float]
) -> np.ndarray:
    start = chain.fk(robot.home)
    if config.start is not None:
        position = _vector(config.start, (2, 3) if weights[2] == 0 else 3, "start position")
        start[: position.size, 3] = position
    return start


def _solve(
    chain: KinematicChain, target: np.ndarray, q0: np.ndarray, weights: Sequence[float], config: ScenarioConfig
) -> IKResult:
    return solve_ik(
        chain,
        target,
        q0,
        weights=weights,
        tol_pos=IK_TOL_POS,
        tol_rot=IK_TOL_ROT,
        restarts=config.ik_restarts,
        rng=config.seed,
    )


def _unreachable(
    what: str, result: IKResult, weights: Sequence[float], nearest_hint: bool = True
) -> UnreachableGoalError:
    hint = "; pass --nearest to command the nearest configuration found instead" if nearest_hint else ""
    return UnreachableGoalError(
        f"{what} is unreachable: best residual {result.position_error:.4g} m, {result.orientation_error:.4g} rad "
        f"(weights {tuple(weights)}){hint}",
        result.position_error,
        result.orientation_error,
    )


def _ik_motion(robot: RobotSpec, scenario: str, config: ScenarioConfig) -> Motion:
    chain = chain_for(robot)
    if scenario == "ik_joints":
        space = "joint"
    elif scenario == "ik_cartesian":
        space = "cartesian"
    else:
        space = config.space or ("joint" if scenario == "ik_orientation" else "cartesian")
    if space not in SPACES:
        raise ScenarioError(f"space must be one of {list(SPACES)}, got {space!r}")
    if not (math.isfinite(config.move_time) and config.move_time > 0) or not (
        math.isfinite(config.hold) and config.hold >= 0
    ):
        raise ScenarioError(f"move time must be > 0 s and hold >= 0 s, got {config.move_time} and {config.hold}")
    goal = _goal_spec(robot, scenario, config, chain)
    weights = goal.weights
    notes: list[str] = []
    fallback = False

    start_result = _solve(chain, _start_target(robot, config, chain, weights), robot.home, weights, config)
    if not start_result.success:
        if not config.nearest:
            raise _unreachable("start pose", start_result, weights)
        fallback = True
        notes.append(
            "FALLBACK: start unreachable, starting at the nearest configuration "
            f"(residual {start_result.position_error:.4g} m, {start_result.orientation_error:.4g} rad)"
        )
    q_start = start_result.q
    goal_result = _solve(chain, goal.target, q_start, weights, config)
    if not goal_result.success:
        if not config.nearest:
            raise _unreachable(f"goal ({goal.text})", goal_result, weights)
        fallback = True
        nearest = chain.fk(goal_result.q)
        notes.append(
            f"FALLBACK: goal unreachable, commanding the nearest pose found instead: position "
            f"{np.round(nearest[:3, 3], 4).tolist()} m, "
            f"XYZ Euler {np.round(matrix_to_rpy(nearest[:3, :3]), 4).tolist()} rad "
            f"(residual {goal_result.position_error:.4g} m, {goal_result.orientation_error:.4g} rad)"
        )
    # The Cartesian path heads for the goal, or for the nearest reachable pose when falling back.
    path_goal = goal.target if goal_result.success else chain.fk(goal_result.q)

    times = _fit_duration(config.move_time + config.hold, config.duration, config.dt)
    max_jump = 0.0
    failed = 0
    if space == "joint":
        traj = PolynomialTrajectory([0.0, config.move_time], np.array([q_start, goal_result.q]), order=config.order)
        positions, velocities = _sample_trajectory(traj, times)
        reference = fk_path(chain, positions)
    else:
        start_pose = chain.fk(q_start)
        reference = _cartesian_path(start_pose, path_goal, weights, config.move_time, config.order, times)
        moving = times <= config.move_time + 1e-9
        path = solve_path_ik(chain, reference[moving], q_start, weights=weights, tol_pos=IK_TOL_POS, tol_rot=IK_TOL_ROT)
        failed = int(np.count_nonzero(~path.success))
        if failed:
            worst = max(path.results, key=lambda r: r.position_error + r.orientation_error)
            first = int(np.argmin(path.success))
            if not config.nearest:
                raise UnreachableGoalError(
                    f"Cartesian path to {goal.text}: IK failed at {failed} of {len(path.success)} samples, first at "
                    f"t = {times[moving][first]:.2f} s; worst residual {worst.position_error:.4g} m, "
                    f"{worst.orientation_error:.4g} rad; pass --nearest to command the nearest configurations found",
                    worst.position_error,
                    worst.orientation_error,
                )
            fallback = True
            notes.append(f"FALLBACK: IK failed at {failed} path samples; commanding the nearest configurations found")
        positions = np.empty((len(times), robot.dof))
        positions[moving] = path.q
        positions[~moving] = path.q[-1]
        # Central differences (one-sided at the ends), zero while holding.
        velocities = np.gradient(positions, config.dt, axis=0)
        velocities[~moving] = 0.0
        velocities[0] = 0.0
        max_jump = path.max_joint_jump  # a branch switch of the IK shows up here and as a velocity warning

    final_pose = chain.fk(positions[-1])
    pos_err, rot_err = pose_errors(final_pose[None], goal.target[None], weights)
    report = IKReport(
        success=not fallback and failed == 0,
        goal_position_error=float(pos_err[0]),
        goal_orientation_error=float(rot_err[0]),
        weights=tuple(weights),
        space=space,
        max_joint_jump=max_jump,
        failed_samples=failed,
        fallback=fallback,
        message=goal_result.message,
    )
    description = f"{scenario}: to {goal.text} in {space} space over {config.move_time:g} s, hold {config.hold:g} s"
    return Motion(
        scenario,
        robot,
        config.dt,
        times,
        positions,
        velocities,
        description,
        goal=goal.target,
        reference_path=reference,
        ik=report,
        warnings=notes,
    )


def _cartesian_path(
    start: np.ndarray, goal: np.ndarray, weights: Sequence[float], move_time: float, order: str, times: np.ndarray
) -> np.ndarray:
    """Poses along a straight line (position) and the geodesic (orientation), both timed by one polynomial
    s(t) from 0 to 1 with zero velocity (and acceleration for quintic) at both ends."""
    scaling = PolynomialTrajectory([0.0, move_time], [[0.0], [1.0]], order=order).sample(times).positions[:, 0]
    goal_rotation = goal[:3, :3] if np.any(np.asarray(weights)[3:] > 0) else start[:3, :3]
    delta = rotation_vector(goal_rotation @ start[:3, :3].T)
    path = np.tile(np.eye(4), (len(times), 1, 1))
    for k, s in enumerate(scaling):
        path[k, :3, 3] = start[:3, 3] + s * (goal[:3, 3] - start[:3, 3])
        path[k, :3, :3] = rotation_exp(s * delta) @ start[:3, :3]
    # Axes the IK does not control keep the start's value (e.g. the igt tool tip's fixed height).
    for axis in range(3):
        if weights[axis] == 0:
            path[:, axis, 3] = start[axis, 3]
    return path


# ------------------------------------------------------------------------------------------------- CSV I/O
def write_engine_csv(path: Path, motion: Motion) -> None:
    """The desired joint positions as the engine's CSV (sim.wire.joint_csv), exact doubles."""
    write_joint_csv(path, motion.robot.joint_names, motion.times, motion.positions, exact=True)


# ----------------------------------------------------------------------------------------------- schedule
@dataclass
class Schedule:
    """What the commander streams: an optional approach from the robot's current state, then the motion.

    Sample i is for the end of step i (sample 0 = where the robot is at the start). `motion_index[i]` is the
    index of the motion sample, or -1 during the approach.
    """

    positions: np.ndarray  # (M, n)
    velocities: np.ndarray  # (M, n)
    motion_index: np.ndarray  # (M,) int

    @property
    def approach_steps(self) -> int:
        """Index of the motion's first sample in the schedule (= approach length in steps)."""
        return int(np.argmax(self.motion_index >= 0))


def build_schedule(
    motion: Motion, q_start: np.ndarray | None = None, approach_min_s: float = APPROACH_MIN_S
) -> Schedule:
    """The motion, preceded by a quintic approach from `q_start` to its first sample if they differ by more than
    1e-4 (rad or m) and the approach is enabled (`approach_min_s` > 0, `q_start` given)."""
    index = np.arange(len(motion.times))
    if q_start is None or approach_min_s <= 0:
        return Schedule(motion.positions, motion.velocities, index)
    q_start = _vector(q_start, motion.robot.dof, "start state")
    if np.max(np.abs(q_start - motion.positions[0])) <= 1e-4:
        return Schedule(motion.positions, motion.velocities, index)
    positions, velocities = approach(motion.robot, q_start, motion.positions[0], motion.dt, approach_min_s)
    return Schedule(
        np.concatenate([positions[:-1], motion.positions]),
        np.concatenate([velocities[:-1], motion.velocities]),
        np.concatenate([np.full(len(positions) - 1, -1), index]),
    )
