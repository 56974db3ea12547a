"""Every scenario default, in one place: the fixed ones, a robot's own (its YAML's `scenario_defaults:`, read by
sim.robots.loading into `RobotSpec.scenario_defaults`) and the ones computed from a robot when it has none. Pure logic.

The Panda and the igt fix theirs in their YAML, to keep the motions the README documents; for any other robot they
are computed here from the limits and the kinematic chain, never tabled by its name:

  usable range     the joint limits; a continuous joint (±2π) is used over ±π. A margin of MARGIN of the range is
                   kept at each end.
  sweep            per joint a centre c and amplitude A such that c ± A stays on one side of 0 (MAPE divides by the
                   reference): on the range's larger side of 0, c in its middle and A = 0.3 of its width, so the
                   swing keeps 0.2 of the width from 0; A at most SWEEP_MAX_SWING and slow enough that the 5 s
                   quintic segments peak at half the velocity limit.
  one_joint        the first joint through ONE_JOINT_FRACTIONS of its usable range (the thesis's shape: up, far up,
                   back, far down), scaled towards the centre if needed so it peaks at 0.8 of its velocity limit.
  IK weights       the task-space axes the chain controls: greedily x, y, z, yaw, roll, pitch, each kept when it
                   raises the rank of the Jacobian's selected rows (at the best of a few seeded configurations).
                   Six controllable axes = full pose; the igt's = x, y and yaw.
  IK goals         the FK of reachable offsets from home (every joint IK_GOAL_SHIFT of its usable range towards the
                   side with more room, at most IK_GOAL_MAX_SHIFT); ik_orientation shifts the other way.
"""

from __future__ import annotations

import math

import numpy as np

from sim.geometry.frames import matrix_to_rpy
from sim.geometry.kinematics import KinematicChain
from sim.robots import RobotSpec

__all__ = [
    "SINGLE_DURATION_S",
    "ONE_JOINT_SPACING_S",
    "ONE_JOINT_HOLD_S",
    "IK_MOVE_TIME_S",
    "IK_HOLD_S",
    "IK_RESTARTS",
    "IK_SEED",
    "IK_TOL_POS",
    "IK_TOL_ROT",
    "SWEEP_DURATION_S",
    "SWEEP_SEGMENT_S",
    "SWEEP_PATTERN",
    "APPROACH_MIN_S",
    "APPROACH_SPEED_FRACTION",
    "MARGIN",
    "SWEEP_MAX_SWING",
    "ONE_JOINT_FRACTIONS",
    "ONE_JOINT_SPEED_FRACTION",
    "IK_GOAL_SHIFT",
    "IK_GOAL_MAX_SHIFT",
    "AXIS_NAMES",
    "usable_range",
    "sweep_table",
    "one_joint_default",
    "controllable_weights",
    "rotates_about_z_only",
    "position_weights",
    "ik_goal",
    "describe_axes",
]

# Fixed defaults, the same for every robot.
SINGLE_DURATION_S = 5.0
ONE_JOINT_SPACING_S = 2.0
ONE_JOINT_HOLD_S = 1.0
IK_MOVE_TIME_S = 4.0
IK_HOLD_S = 1.0
IK_RESTARTS = 20
IK_SEED = 0
IK_TOL_POS = 1e-6  # m
IK_TOL_ROT = 1e-5  # rad
SWEEP_DURATION_S = 40.0
SWEEP_SEGMENT_S = 5.0
SWEEP_PATTERN = (0.0, 1.0, 0.0, -1.0, 0.0, -1.0, 0.0, 1.0, 0.0)  # multiples of A around c, one per 5 s
APPROACH_MIN_S = 2.0
APPROACH_SPEED_FRACTION = 0.5  # approach segments peak at no more than this fraction of the velocity limits

# What the computed defaults are made of.
MARGIN = 0.1
SWEEP_MAX_SWING = {"revolute": 0.5, "continuous": 0.5, "prismatic": 0.1}  # rad or m
SWEEP_SEGMENT_PEAK = 1.875 / 5.0  # a 5 s quintic from rest to rest peaks at 1.875·Δ/5
ONE_JOINT_FRACTIONS = (0.55, 0.7, 0.9, 0.75, 0.25, 0.1)
ONE_JOINT_SPEED_FRACTION = 0.8
IK_GOAL_SHIFT = 0.15
IK_GOAL_MAX_SHIFT = {"revolute": 0.5, "continuous": 0.5, "prismatic": 0.1}
AXIS_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")
_AXIS_ORDER = (0, 1, 2, 5, 3, 4)  # x, y, z, yaw, roll, pitch: yaw first, so a planar robot keeps x, y, yaw
_RANK_TOL = 1e-6


def usable_range(robot: RobotSpec) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) each joint may be moved over, a MARGIN inside its limits (continuous joints: ±π)."""
    continuous = np.array([kind == "continuous" for kind in robot.joint_types])
    lower = np.where(continuous, np.maximum(robot.lower, -math.pi), robot.lower)
    upper = np.where(continuous, np.minimum(robot.upper, math.pi), robot.upper)
    margin = MARGIN * (upper - lower)
    return lower + margin, upper - margin


def sweep_table(robot: RobotSpec) -> tuple[np.ndarray, np.ndarray]:
    """(centres, amplitudes) of the sweep, from the robot's YAML or computed (module docstring)."""
    own = robot.scenario_defaults
    if own.sweep_centres is not None and own.sweep_amplitudes is not None:
        return np.array(own.sweep_centres), np.array(own.sweep_amplitudes)
    lower, upper = usable_range(robot)
    centres, amplitudes = np.empty(robot.dof), np.empty(robot.dof)
    for j, kind in enumerate(robot.joint_types):
        low, high = float(lower[j]), float(upper[j])
        if low < 0.0 < high:  # keep to the larger side of 0
            low, high = (0.0, high) if high >= -low else (low, 0.0)
        centres[j] = (low + high) / 2.0
        slow_enough = 0.5 * robot.max_velocity[j] / SWEEP_SEGMENT_PEAK
        amplitudes[j] = min(0.3 * (high - low), SWEEP_MAX_SWING[kind], slow_enough)
    return centres, amplitudes


def one_joint_default(robot: RobotSpec) -> tuple[int, np.ndarray]:
    """(joint index, waypoints) of one_joint, from the robot's YAML or computed (module docstring; the computed
    waypoints are slowed down by sim.control.scenarios.joint_space where they would be too fast)."""
    own = robot.scenario_defaults
    if own.one_joint is not None and own.one_joint_waypoints is not None:
        return robot.joint_names.index(own.one_joint), np.array(own.one_joint_waypoints)
    lower, upper = usable_range(robot)
    return 0, lower[0] + np.array(ONE_JOINT_FRACTIONS) * (upper[0] - lower[0])


def _jacobians(chain: KinematicChain, home: np.ndarray, samples: int = 8) -> list[np.ndarray]:
    """The Jacobian at home and at `samples` seeded configurations inside the limits."""
    rng = np.random.default_rng(0)
    lower = np.where(np.isfinite(chain.lower), chain.lower, -math.pi)
    upper = np.where(np.isfinite(chain.upper), chain.upper, math.pi)
    configurations = [np.clip(home, lower, upper)] + [rng.uniform(lower, upper) for _ in range(samples)]
    return [chain.jacobian(q) for q in configurations]


def rotates_about_z_only(chain: KinematicChain, home: np.ndarray) -> bool:
    """Whether the end effector can never roll or pitch (like the igt): the ω_x, ω_y rows vanish everywhere."""
    return all(np.abs(jac[3:5]).max() < _RANK_TOL for jac in _jacobians(chain, home))


def controllable_weights(chain: KinematicChain, home: np.ndarray) -> tuple[float, ...]:
    """IK weights (x, y, z, roll, pitch, yaw; 1 or 0) of the axes the chain can control (module docstring)."""
    jacobians = _jacobians(chain, home)
    best = max(jacobians, key=lambda jac: np.linalg.matrix_rank(jac, tol=_RANK_TOL))
    # Rows as (v, ω) in the base frame; ω's components are roll, pitch, yaw rates about x, y, z.
    selected: list[int] = []
    for axis in _AXIS_ORDER:
        trial = selected + [axis]
        if np.linalg.matrix_rank(best[trial], tol=_RANK_TOL) == len(trial):
            selected = trial
    return tuple(1.0 if axis in selected else 0.0 for axis in range(6))


def position_weights(weights: tuple[float, ...]) -> tuple[float, ...]:
    """The position part of `weights` when it holds all of x, y, z; otherwise `weights` itself (a planar robot's
    position goal needs its yaw too, to be one solution rather than a circle of them)."""
    if all(weights[:3]):
        return (*weights[:3], 0.0, 0.0, 0.0)
    return weights


def ik_goal(robot: RobotSpec, chain: KinematicChain, orientation: bool) -> tuple[np.ndarray, np.ndarray]:
    """(position, rpy) of a goal the robot reaches: FK of home shifted per joint (module docstring)."""
    lower, upper = usable_range(robot)
    home = np.clip(robot.home, lower, upper)
    room_up, room_down = upper - home, home - lower
    direction = np.where(room_up >= room_down, 1.0, -1.0) * (-1.0 if orientation else 1.0)
    shift = np.minimum(IK_GOAL_SHIFT * (upper - lower), [IK_GOAL_MAX_SHIFT[kind] for kind in robot.joint_types])
    goal = np.clip(home + direction * shift, lower, upper)
    pose = chain.fk(goal)
    return pose[:3, 3].copy(), np.array(matrix_to_rpy(pose[:3, :3]))


def describe_axes(weights: tuple[float, ...]) -> str:
    """'x, y and yaw' for the weights (1, 1, 0, 0, 0, 1)."""
    names = [AXIS_NAMES[axis] for axis in range(6) if weights[axis]]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"
