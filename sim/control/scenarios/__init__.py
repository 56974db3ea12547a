"""The commander's scenarios as pure data: scenario name + options -> desired joint trajectory sampled at dt.

No ROS here (sim.commander streams what this package builds). Every scenario yields a `Motion`: samples at
t_k = k·dt, k = 0..N-1, of joint positions and velocities (robot joint order, rad or m), starting at rest. For the
IK scenarios also the end-effector goal (4x4, base frame, ROS RH z-up), the Cartesian reference path (one 4x4 per
sample), the IK weights and a goal report.

Scenarios (defaults in brackets; "home" = the robot's home configuration). Defaults not stated for a robot are
computed from its limits and its chain (sim.control.scenarios.defaults); the Panda's and the igt's below are kept in
their robot YAML (`scenario_defaults:` in sim/robots/*.yaml) so that they stay the motions the README documents:

  single          constant joint positions [home]; runs `duration` [5 s]. Like the thesis's a_SingleInput.
  one_joint       one joint through waypoints at times, polynomial (`order` [quintic]), others hold home.
                  [computed: the first joint through fractions of its range, slowed to 0.8 of its velocity limit];
                  panda [joint 1 through 0.25, 1, 2.75, 1.5, -2, -2.45 rad at t = 0, 2, ..., 10 s];
                  igt [the rail through 0.05, 0.2, 0, -0.2, 0.05, -0.15 m at t = 0, 2, ..., 10 s];
                  `duration` [last waypoint time + 1 s]. (The thesis held the other Panda joints at 0, but 0 is
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
  sweep           the accuracy trials' motion (formerly `trial`), `duration` [40 s]: every joint
                  at once follows c -> c+A -> c -> c-A -> c -> c-A -> c -> c+A -> c in eight quintic segments of
                  5 s (time-symmetric, amplitude-antisymmetric), with per-joint centres c and amplitudes A
                  (`sweep_table`): inside the limits with margin, and of one sign over the whole swing
                  (c ± A ≠ 0) so that MAPE, which divides by the reference, stays meaningful. Peak speeds are well
                  below the limits.

Unreachable IK goals raise `UnreachableGoalError` with the best residual, unless `nearest=True`: then the best
configuration found is used and the motion says so (`Motion.ik.fallback`).

The package by concern: `motion` (options, Motion, errors, checks), `defaults` (every default), `joint_space` and
`ik` (the builders by kind), `build` (by name), `schedule` (the approach and what is streamed), `engine_csv`.
"""

from sim.control.scenarios.build import OLD_SCENARIO_NAMES, SCENARIOS, build_motion
from sim.control.scenarios.defaults import APPROACH_MIN_S, IK_HOLD_S, IK_MOVE_TIME_S, IK_RESTARTS
from sim.control.scenarios.engine_csv import write_engine_csv
from sim.control.scenarios.ik import IK_SCENARIOS, SPACES, fk_path, pose_errors
from sim.control.scenarios.motion import (
    IKReport,
    Motion,
    ScenarioConfig,
    ScenarioError,
    UnreachableGoalError,
    joint_index,
    sample_times,
)
from sim.control.scenarios.schedule import Schedule, approach, build_schedule

__all__ = [
    "SCENARIOS",
    "OLD_SCENARIO_NAMES",
    "IK_SCENARIOS",
    "SPACES",
    "APPROACH_MIN_S",
    "IK_HOLD_S",
    "IK_MOVE_TIME_S",
    "IK_RESTARTS",
    "ScenarioError",
    "UnreachableGoalError",
    "ScenarioConfig",
    "IKReport",
    "Motion",
    "Schedule",
    "build_motion",
    "build_schedule",
    "approach",
    "joint_index",
    "sample_times",
    "pose_errors",
    "fk_path",
    "write_engine_csv",
]
