"""The IK scenarios (ik_joints, ik_cartesian, ik_orientation, fk_confirm): a goal pose, IK of start and goal, and
a path between them in joint or Cartesian space; and the pose errors their runs are judged by. Pure logic."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.control.scenarios.defaults import (
    IK_TOL_POS,
    IK_TOL_ROT,
    controllable_weights,
    describe_axes,
    ik_goal,
    position_weights,
    rotates_about_z_only,
)
from sim.control.scenarios.motion import (
    IKReport,
    Motion,
    ScenarioConfig,
    ScenarioError,
    UnreachableGoalError,
    checked_vector,
    fit_duration,
    sample_trajectory,
)
from sim.geometry.frames import matrix_to_rpy, rotation_exp, rotation_vector, rpy_to_matrix
from sim.geometry.kinematics import IKResult, KinematicChain, chain_for, solve_ik, solve_path_ik
from sim.geometry.trajectory import PolynomialTrajectory
from sim.robots import RobotSpec

__all__ = ["IK_SCENARIOS", "SPACES", "ik_motion", "pose_errors", "fk_path"]

IK_SCENARIOS: tuple[str, ...] = ("ik_joints", "ik_cartesian", "ik_orientation", "fk_confirm")
SPACES = ("joint", "cartesian")


@dataclass
class _GoalSpec:
    target: np.ndarray  # 4x4
    weights: tuple[float, ...]
    text: str


def _default_goal(robot: RobotSpec, scenario: str, chain: KinematicChain) -> tuple[np.ndarray, np.ndarray | None]:
    """(position, rpy or None for position only): the robot's own, or computed (sim.control.scenarios.defaults)."""
    own = robot.scenario_defaults
    if scenario == "ik_orientation":
        if own.orientation_goal_position is not None:
            given = own.orientation_goal_rpy
            return np.array(own.orientation_goal_position), None if given is None else np.array(given)
        return ik_goal(robot, chain, orientation=True)
    if own.ik_goal_position is not None:
        return np.array(own.ik_goal_position), None if own.ik_goal_rpy is None else np.array(own.ik_goal_rpy)
    position, computed_rpy = ik_goal(robot, chain, orientation=False)
    # Position only where the chain controls x, y and z; else the goal's orientation is part of the goal.
    return position, None if all(controllable_weights(chain, robot.home)[:3]) else computed_rpy


def _weights(config: ScenarioConfig, chain: KinematicChain, robot: RobotSpec, oriented: bool) -> tuple[float, ...]:
    if config.weights is not None:
        weights = checked_vector(config.weights, 6, "IK weights (x, y, z, roll, pitch, yaw)")
        if np.any(weights < 0) or not np.any(weights > 0):
            raise ScenarioError(f"IK weights must be >= 0 with at least one > 0, got {weights.tolist()}")
        return tuple(float(w) for w in weights)
    controllable = controllable_weights(chain, robot.home)
    return controllable if oriented else position_weights(controllable)


def _goal_spec(robot: RobotSpec, scenario: str, config: ScenarioConfig, chain: KinematicChain) -> _GoalSpec:
    home_pose = chain.fk(robot.home)
    default_position, default_rpy = _default_goal(robot, scenario, chain)
    given_rpy = config.goal_rpy if config.goal_rpy is not None else default_rpy
    rpy = None if given_rpy is None else checked_vector(given_rpy, 3, "goal rpy (XYZ Euler angles in rad)")
    weights = _weights(config, chain, robot, oriented=rpy is not None or scenario == "ik_orientation")
    free_z = weights[2] == 0
    if config.goal is None:
        position = np.array(default_position, dtype=float)
    else:
        position = checked_vector(
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
        position = checked_vector(config.start, (2, 3) if weights[2] == 0 else 3, "start position")
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


def ik_motion(robot: RobotSpec, scenario: str, config: ScenarioConfig) -> Motion:
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

    times = fit_duration(config.move_time + config.hold, config.duration, config.dt)
    max_jump = 0.0
    failed = 0
    if space == "joint":
        traj = PolynomialTrajectory([0.0, config.move_time], np.array([q_start, goal_result.q]), order=config.order)
        positions, velocities = sample_trajectory(traj, times)
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
