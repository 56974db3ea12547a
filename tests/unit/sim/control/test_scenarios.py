"""sim.control.scenarios without ROS: shapes and grids, defaults, limits, IK goals reached (FK of the desired joints),
unreachable goals reported, CSV export format."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from sim.control.scenario_defaults import trial_table
from sim.control.scenarios import (
    IK_SCENARIOS,
    SCENARIOS,
    ScenarioConfig,
    ScenarioError,
    UnreachableGoalError,
    approach,
    build_motion,
    fk_path,
    joint_index,
    pose_errors,
    sample_times,
    write_engine_csv,
)
from sim.geometry.frames import rpy_to_matrix
from sim.geometry.kinematics import chain_for
from sim.robots import load_robot

ROBOTS = ("panda", "igt")


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    return load_robot(request.param)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_every_scenario_builds_on_the_dt_grid_inside_limits_from_rest(robot, scenario):
    motion = build_motion(robot, scenario, ScenarioConfig(dt=0.02))
    n = len(motion.times)
    assert motion.positions.shape == motion.velocities.shape == (n, robot.dof)
    np.testing.assert_array_equal(motion.times, np.arange(n) * 0.02)
    assert robot.within_limits(motion.positions.min(axis=0)) and robot.within_limits(motion.positions.max(axis=0))
    np.testing.assert_allclose(motion.velocities[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(motion.velocities[-1], 0.0, atol=1e-9)
    # Velocities are consistent with the positions (central differences, interior samples).
    finite = (motion.positions[2:] - motion.positions[:-2]) / (2 * 0.02)
    np.testing.assert_allclose(motion.velocities[1:-1], finite, atol=0.02 * max(1.0, np.abs(finite).max()))


def test_single_holds_given_positions_for_duration(robot):
    q = (robot.lower + robot.upper) / 2
    motion = build_motion(robot, "single", ScenarioConfig(positions=q, duration=1.0))
    assert motion.duration == pytest.approx(1.0)
    np.testing.assert_array_equal(motion.positions, np.tile(q, (51, 1)))
    np.testing.assert_array_equal(build_motion(robot, "single").positions[0], robot.home)


def test_single_rejects_wrong_count_and_out_of_limit_positions(robot):
    with pytest.raises(ScenarioError, match=f"needs {robot.dof} values, got 2"):
        build_motion(robot, "single", ScenarioConfig(positions=[0.1, 0.2]))
    q = robot.home.copy()
    q[0] = robot.upper[0] + 0.1
    with pytest.raises(ScenarioError, match=f"{robot.joint_names[0]} = .* outside its limits"):
        build_motion(robot, "single", ScenarioConfig(positions=q))


def test_one_joint_panda_default_is_the_seeds_joint1_test():
    robot = load_robot("panda")
    motion = build_motion(robot, "one_joint")
    at = [round(t / 0.02) for t in (0, 2, 4, 6, 8, 10)]
    np.testing.assert_allclose(motion.positions[at, 0], [0.25, 1.0, 2.75, 1.5, -2.0, -2.45])
    np.testing.assert_array_equal(motion.positions[:, 1:], np.tile(robot.home[1:], (len(motion.times), 1)))
    assert motion.duration == pytest.approx(11.0)
    # The thesis's 3.5 rad in 2 s exceeds Franka's joint-1 velocity limit: reported, not hidden.
    assert any("panda_joint1 peaks at 3.281 rad/s" in w for w in motion.warnings)


def test_one_joint_options_joint_waypoints_times_order(robot):
    config = ScenarioConfig(
        joint="2", waypoints=[robot.home[1], robot.home[1] + 0.2], times=[0.5, 1.5], order="cubic", duration=2.0
    )
    motion = build_motion(robot, "one_joint", config)
    k = lambda t: round(t / 0.02)  # noqa: E731
    assert motion.positions[k(0.0), 1] == pytest.approx(robot.home[1])  # held before the first time
    assert motion.positions[k(1.5), 1] == pytest.approx(robot.home[1] + 0.2)
    assert motion.positions[k(1.0), 1] == pytest.approx(robot.home[1] + 0.1)  # cubic midpoint
    assert motion.duration == pytest.approx(2.0)
    assert joint_index(robot, robot.joint_names[2]) == 2


@pytest.mark.parametrize(
    "config, message",
    [
        (ScenarioConfig(joint="9", waypoints=[0, 0.1]), "unknown joint '9'"),
        (ScenarioConfig(waypoints=[0.0, 0.1], times=[0.0]), "times .* needs 2 values, got 1"),
        (ScenarioConfig(waypoints=[0.0, 0.1], times=[1.0, 1.0]), "increase strictly"),
        (ScenarioConfig(waypoints=[0.0, 9.0]), "waypoint 9.0 of .* outside its limits"),
        (ScenarioConfig(order="septic"), "order must be one of"),
        (ScenarioConfig(dt=0.0), "dt must be"),
        (ScenarioConfig(duration=-1.0), "duration must be"),
    ],
)
def test_bad_one_joint_options_name_the_problem(robot, config, message):
    with pytest.raises(ScenarioError, match=message):
        build_motion(robot, "one_joint", config)


def test_unknown_scenario_is_named(robot):
    with pytest.raises(ScenarioError, match="unknown scenario 'dance'"):
        build_motion(robot, "dance")


def test_trial_is_40s_symmetric_all_joints_moving_and_never_crossing_zero(robot):
    motion = build_motion(robot, "trial")
    assert motion.duration == pytest.approx(40.0)
    centres, amplitudes = trial_table(robot)
    np.testing.assert_allclose(motion.positions.max(axis=0), centres + amplitudes, atol=1e-9)
    np.testing.assert_allclose(motion.positions.min(axis=0), centres - amplitudes, atol=1e-9)
    assert np.all(np.sign(motion.positions) == np.sign(centres))  # MAPE stays meaningful
    # Time-symmetric about 20 s, amplitude-antisymmetric within each half.
    np.testing.assert_allclose(motion.positions, motion.positions[::-1], atol=1e-9)
    assert not motion.warnings
    assert np.all(np.abs(motion.velocities).max(axis=0) < 0.5 * robot.max_velocity)
    if robot.name == "panda":  # the flange stays well above the table
        assert fk_path(chain_for(robot), motion.positions[::25])[:, 2, 3].min() > 0.1


def test_trial_duration_cuts_the_motion(robot):
    motion = build_motion(robot, "trial", ScenarioConfig(duration=2.0))
    np.testing.assert_allclose(motion.positions, build_motion(robot, "trial").positions[:101])


@pytest.mark.parametrize("scenario", IK_SCENARIOS)
def test_ik_scenarios_reach_their_goal_by_fk_of_the_desired_joints(robot, scenario):
    motion = build_motion(robot, scenario)
    chain = chain_for(robot)
    assert motion.ik is not None and motion.ik.success and not motion.ik.fallback
    assert motion.goal is not None and motion.reference_path is not None
    final = chain.fk(motion.positions[-1])
    pos_err, rot_err = pose_errors(final[None], motion.goal[None], motion.ik.weights)
    assert pos_err[0] < 1e-5 and rot_err[0] < 1e-4
    # The motion starts at the start pose: home for the defaults.
    np.testing.assert_allclose(chain.fk(motion.positions[0])[:3, 3], chain.fk(robot.home)[:3, 3], atol=1e-6)
    # The desired joints follow the reference path all along.
    pos_path, rot_path = pose_errors(fk_path(chain, motion.positions), motion.reference_path, motion.ik.weights)
    assert pos_path.max() < 1e-5 and rot_path.max() < 1e-4


def test_panda_goals_and_weights():
    panda = load_robot("panda")
    position_only = build_motion(panda, "ik_joints")
    np.testing.assert_allclose(position_only.goal[:3, 3], [0.5, 0.375, 0.75])
    assert position_only.ik.weights == (1, 1, 1, 0, 0, 0)
    oriented = build_motion(panda, "ik_orientation")
    np.testing.assert_allclose(oriented.goal[:3, 3], [0.3, 0.5, 0.75])
    np.testing.assert_allclose(oriented.goal[:3, :3], rpy_to_matrix(math.pi / 4, math.pi / 5, math.pi / 3))
    assert oriented.ik.weights == (1, 1, 1, 1, 1, 1)
    np.testing.assert_allclose(chain_for(panda).fk(oriented.positions[-1]), oriented.goal, atol=1e-6)


def test_ik_cartesian_is_a_straight_line_and_reports_the_joint_jump():
    panda = load_robot("panda")
    motion = build_motion(panda, "ik_cartesian")
    path = fk_path(chain_for(panda), motion.positions)[:, :3, 3]
    start, goal = path[0], motion.goal[:3, 3]
    direction = (goal - start) / np.linalg.norm(goal - start)
    off_line = path - start - np.outer((path - start) @ direction, direction)
    assert np.abs(off_line).max() < 1e-5
    assert 0 < motion.ik.max_joint_jump < 0.05


@pytest.mark.parametrize("scenario", ["ik_joints", "ik_cartesian", "ik_orientation"])
def test_unreachable_goal_is_reported_with_the_residual(robot, scenario):
    far = (1.5, 0.0, 0.5) if robot.name == "panda" else (1.2, 0.3)
    with pytest.raises(UnreachableGoalError, match="unreachable: best residual") as info:
        build_motion(robot, scenario, ScenarioConfig(goal=far, ik_restarts=3))
    assert info.value.position_error > 0.1


def test_nearest_fallback_is_explicit_and_heads_for_a_reachable_pose(robot):
    far = (1.5, 0.0, 0.5) if robot.name == "panda" else (1.2, 0.3)
    motion = build_motion(robot, "ik_cartesian", ScenarioConfig(goal=far, nearest=True, ik_restarts=3))
    assert motion.ik.fallback and not motion.ik.success
    assert motion.ik.goal_position_error > 0.1
    assert any(w.startswith("FALLBACK: goal unreachable") for w in motion.warnings)
    assert motion.ik.failed_samples == 0  # the path to the nearest pose itself is feasible


def test_igt_rejects_roll_and_pitch():
    with pytest.raises(ScenarioError, match="igt can only reach x, y and yaw: goal rpy"):
        build_motion(load_robot("igt"), "ik_joints", ScenarioConfig(goal_rpy=(0.1, 0.0, 0.5)))


def test_approach_reaches_target_within_speed_fraction(robot):
    q_to = robot.home + 0.1 * (robot.upper - robot.home)
    positions, velocities = approach(robot, robot.home, q_to, 0.02)
    np.testing.assert_array_equal(positions[0], robot.home)
    np.testing.assert_allclose(positions[-1], q_to)
    assert np.all(np.abs(velocities).max(axis=0) <= 0.5 * robot.max_velocity + 1e-9)
    assert len(positions) >= 101  # at least 2 s


def test_sample_times_are_exact_multiples():
    times = sample_times(40.0, 0.02)
    assert len(times) == 2001 and times[-1] == 2000 * 0.02
    assert len(sample_times(0.05, 0.02)) == 4  # rounded up to whole steps


def test_engine_csv_export_round_trips_exactly(robot, tmp_path):
    motion = build_motion(robot, "trial", ScenarioConfig(duration=1.0))
    path = tmp_path / "desired.csv"
    write_engine_csv(path, motion)
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["time", *robot.joint_names]
    data = np.array(rows[1:], dtype=float)
    np.testing.assert_array_equal(data[:, 0], motion.times)
    np.testing.assert_array_equal(data[:, 1:], motion.positions)


def test_schedule_prepends_an_approach_only_when_needed(robot):
    from sim.control.scenarios import build_schedule

    motion = build_motion(robot, "trial", ScenarioConfig(duration=1.0))
    direct = build_schedule(motion, motion.positions[0])
    assert direct.approach_steps == 0 and len(direct.positions) == len(motion.times)
    assert build_schedule(motion, None).approach_steps == 0
    assert build_schedule(motion, robot.home, approach_min_s=0.0).approach_steps == 0
    schedule = build_schedule(motion, robot.home)
    m = schedule.approach_steps
    assert m >= 100
    np.testing.assert_array_equal(schedule.positions[0], robot.home)
    np.testing.assert_array_equal(schedule.positions[m:], motion.positions)
    np.testing.assert_array_equal(schedule.motion_index[m:], np.arange(len(motion.times)))
    assert np.all(schedule.motion_index[:m] == -1)
    # Continuous at the joint between approach and motion (both at rest there).
    assert np.abs(np.diff(schedule.positions, axis=0)).max() < 0.05
