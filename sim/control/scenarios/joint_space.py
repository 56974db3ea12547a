"""The joint-space scenarios: single, one_joint and the accuracy trials' sweep. Pure logic."""

from __future__ import annotations

import numpy as np

from sim.control.scenarios.defaults import (
    ONE_JOINT_HOLD_S,
    ONE_JOINT_SPACING_S,
    ONE_JOINT_SPEED_FRACTION,
    SINGLE_DURATION_S,
    SWEEP_DURATION_S,
    SWEEP_PATTERN,
    SWEEP_SEGMENT_S,
    one_joint_default,
    sweep_table,
)
from sim.control.scenarios.motion import (
    Motion,
    ScenarioConfig,
    ScenarioError,
    checked_vector,
    fit_duration,
    joint_index,
    sample_times,
    sample_trajectory,
)
from sim.geometry.trajectory import PolynomialTrajectory
from sim.robots import RobotSpec

__all__ = ["single", "one_joint", "sweep"]


def single(robot: RobotSpec, scenario: str, config: ScenarioConfig) -> Motion:
    q = (
        robot.home.copy()
        if config.positions is None
        else checked_vector(config.positions, robot.dof, f"{robot.name} positions ({', '.join(robot.joint_names)})")
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


def one_joint(robot: RobotSpec, scenario: str, config: ScenarioConfig) -> Motion:
    default_joint, default_points = one_joint_default(robot)
    j = default_joint if config.joint is None else joint_index(robot, config.joint)
    if config.waypoints is None:
        if config.joint is not None and j != default_joint:
            raise ScenarioError(
                f"--joint {config.joint} needs --waypoints (the defaults are for {robot.joint_names[default_joint]})"
            )
        points = default_points
        if (
            robot.scenario_defaults.one_joint_waypoints is None
        ):  # computed: slowed down to stay within the velocity limit
            points = _slowed(points, j, robot, config)
    else:
        points = checked_vector(config.waypoints, tuple(range(2, 1000)), "waypoints (at least 2)")
    if config.times is None:
        wp_times = np.arange(len(points)) * ONE_JOINT_SPACING_S
    else:
        wp_times = checked_vector(config.times, len(points), f"times (one per waypoint, {len(points)} waypoints)")
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
    times = fit_duration(wp_times[-1] + ONE_JOINT_HOLD_S, config.duration, config.dt)
    joint_pos, joint_vel = sample_trajectory(traj, times)
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


def sweep(robot: RobotSpec, scenario: str, config: ScenarioConfig) -> Motion:
    centres, amplitudes = sweep_table(robot)
    pattern = np.array(SWEEP_PATTERN)
    wp_times = np.arange(len(pattern)) * SWEEP_SEGMENT_S
    points = centres[None, :] + pattern[:, None] * amplitudes[None, :]
    traj = PolynomialTrajectory(wp_times, points, order="quintic")
    times = fit_duration(SWEEP_DURATION_S, config.duration, config.dt)
    positions, velocities = sample_trajectory(traj, times)
    description = (
        f"sweep: every joint c -> c+A -> c -> c-A -> c -> c-A -> c -> c+A -> c, "
        f"{SWEEP_SEGMENT_S:g} s quintic segments; c = {centres.tolist()}, A = {amplitudes.tolist()}"
    )
    return Motion(scenario, robot, config.dt, times, positions, velocities, description)
