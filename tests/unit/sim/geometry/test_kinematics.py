"""URDF kinematics against pybullet and Franka's DH table, the Jacobian against finite differences, and IK."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

from sim.geometry.frames import quat_to_matrix
from sim.geometry.kinematics import (
    PLANAR_WEIGHTS,
    KinematicChain,
    KinematicsError,
    chain_for,
    planar_pose,
    pose_matrix,
    solve_ik,
    solve_path_ik,
)
from sim.robots import load_robot

# Franka Emika Panda, modified (Craig) DH parameters as published by Franka: (a_{i-1}, d_i, alpha_{i-1}).
PANDA_DH = (
    (0.0, 0.333, 0.0),
    (0.0, 0.0, -math.pi / 2),
    (0.0, 0.316, math.pi / 2),
    (0.0825, 0.0, math.pi / 2),
    (-0.0825, 0.384, -math.pi / 2),
    (0.0, 0.0, math.pi / 2),
    (0.088, 0.0, math.pi / 2),
    (0.0, 0.107, 0.0),  # flange (panda_link8), theta = 0
)


def panda_dh_fk(q: np.ndarray) -> np.ndarray:
    """Panda flange pose (base → panda_link8) from Franka's modified DH table; an independent check of the URDF."""
    q_arr = np.asarray(q, dtype=float)
    if q_arr.shape != (7,):
        raise ValueError(f"panda q must have shape (7,), got {q_arr.shape}")
    pose = np.eye(4)
    for (a, d, alpha), theta in zip(PANDA_DH, (*q_arr, 0.0)):
        ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
        # T = RotX(alpha) · TransX(a) · RotZ(theta) · TransZ(d)
        link = np.array(
            [
                [ct, -st, 0.0, a],
                [st * ca, ct * ca, -sa, -d * sa],
                [st * sa, ct * sa, ca, d * ca],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )
        pose = pose @ link
    return pose


POS_TOL, ROT_TOL = 1e-6, 1e-5  # m, rad: the agreement bounds
N_CONFIGS = 500


def _rotation_angle(r_a: np.ndarray, r_b: np.ndarray) -> float:
    cos = (np.trace(r_a @ r_b.T) - 1.0) / 2.0
    return math.acos(max(-1.0, min(1.0, cos)))


def _rotvec(r: np.ndarray) -> np.ndarray:
    angle = _rotation_angle(r, np.eye(3))
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return axis / 2.0 if angle < 1e-9 else axis * angle / (2.0 * math.sin(angle))


def _random_configs(robot, n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(robot.lower, robot.upper, size=(n, robot.dof))


@pytest.fixture(scope="module")
def bullet():
    client = p.connect(p.DIRECT)
    yield client
    p.disconnect(client)


@pytest.mark.parametrize("name", ["panda", "igt"])
def test_chain_matches_the_registry(name):
    robot = load_robot(name)
    chain = chain_for(robot)
    assert chain.joint_names == robot.joint_names and chain.dof == robot.dof
    np.testing.assert_array_equal(chain.lower, robot.lower)  # the datasheet limits, not the URDF's
    np.testing.assert_array_equal(chain.upper, robot.upper)
    assert chain_for(robot) is chain  # cached


def test_two_urdfs_with_one_name_never_share_a_chain():
    import dataclasses

    panda, igt = load_robot("panda"), load_robot("igt")
    impostor = dataclasses.replace(igt, name="panda")  # igt's URDF under panda's name
    assert chain_for(impostor).joint_names == igt.joint_names
    assert chain_for(panda).joint_names == panda.joint_names
    narrower = dataclasses.replace(panda, upper=panda.upper - 0.1)  # same URDF, other limits: another chain
    np.testing.assert_array_equal(chain_for(narrower).upper, panda.upper - 0.1)


@pytest.mark.parametrize("name", ["panda", "igt"])
def test_fk_matches_pybullet_link_frames(bullet, name):
    robot = load_robot(name)
    chain = chain_for(robot)
    body = p.loadURDF(str(robot.urdf_path), useFixedBase=True, physicsClientId=bullet)
    joint_index, link_index = {}, {}
    for i in range(p.getNumJoints(body, physicsClientId=bullet)):
        info = p.getJointInfo(body, i, physicsClientId=bullet)
        joint_index[info[1].decode()] = i
        link_index[info[12].decode()] = i  # pybullet: link i is the child of joint i
    movable_links = [joint_index[name] for name in robot.joint_names]
    worst_pos = worst_rot = 0.0
    for q in _random_configs(robot, N_CONFIGS, seed=11):
        for name_j, value in zip(robot.joint_names, q):
            p.resetJointState(body, joint_index[name_j], value, physicsClientId=bullet)
        ours = chain.fk_link_frames(q) + [chain.fk(q)]
        for frame, link in zip(ours, movable_links + [link_index[robot.ee_link]]):
            # [4:6] is the URDF link frame; [0:2] would be the centre of mass.
            pos, quat = p.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=bullet)[4:6]
            worst_pos = max(worst_pos, float(np.abs(frame[:3, 3] - pos).max()))
            worst_rot = max(worst_rot, _rotation_angle(frame[:3, :3], quat_to_matrix(quat)))
    p.removeBody(body, physicsClientId=bullet)
    assert worst_pos <= POS_TOL and worst_rot <= ROT_TOL, (worst_pos, worst_rot)


def test_panda_fk_matches_franka_dh_table():
    robot = load_robot("panda")
    chain = chain_for(robot)
    for q in _random_configs(robot, N_CONFIGS, seed=12):
        ours, dh = chain.fk(q), panda_dh_fk(q)
        assert np.abs(ours[:3, 3] - dh[:3, 3]).max() <= POS_TOL
        assert _rotation_angle(ours[:3, :3], dh[:3, :3]) <= ROT_TOL
    # A known pose: all zeros puts the flange at x = 0.088, z = 0.333 + 0.316 + 0.384 - 0.107, pointing down.
    np.testing.assert_allclose(chain.fk(np.zeros(7))[:3, 3], [0.088, 0.0, 0.926], atol=1e-12)


@pytest.mark.parametrize("name", ["panda", "igt"])
def test_jacobian_matches_finite_differences(name):
    robot = load_robot(name)
    chain = chain_for(robot)
    h = 1e-6
    for q in _random_configs(robot, 50, seed=13):
        jac = chain.jacobian(q)
        assert jac.shape == (6, robot.dof)
        for i in range(robot.dof):
            dq = np.zeros(robot.dof)
            dq[i] = h
            plus, minus = chain.fk(q + dq), chain.fk(q - dq)
            np.testing.assert_allclose(jac[:3, i], (plus[:3, 3] - minus[:3, 3]) / (2 * h), atol=1e-7)
            np.testing.assert_allclose(jac[3:, i], _rotvec(plus[:3, :3] @ minus[:3, :3].T) / (2 * h), atol=1e-7)


def _near_seed_round_trip(robot, n: int, seed: int, **ik_kwargs) -> tuple[float, list]:
    chain = chain_for(robot)
    rng = np.random.default_rng(seed)
    results = []
    for q_true in _random_configs(robot, n, seed):
        seed_q = robot.clip(q_true + rng.uniform(-0.1, 0.1, robot.dof))
        results.append((q_true, solve_ik(chain, chain.fk(q_true), seed_q, **ik_kwargs)))
    return float(np.mean([r.success for _, r in results])), results


def test_panda_ik_full_pose_round_trip_from_a_near_seed():
    robot = load_robot("panda")
    rate, results = _near_seed_round_trip(robot, 1000, seed=21)
    assert rate >= 0.995
    for q_true, result in results:
        assert robot.within_limits(result.q)
        if result.success:
            reached = chain_for(robot).fk(result.q)
            target = chain_for(robot).fk(q_true)
            assert np.abs(reached[:3, 3] - target[:3, 3]).max() <= 1e-6
            assert _rotation_angle(reached[:3, :3], target[:3, :3]) <= 1e-5
            assert result.position_error <= 1e-6 and result.orientation_error <= 1e-5
        else:
            assert result.position_error > 1e-6 or result.orientation_error > 1e-5


def test_panda_ik_position_only_round_trip_always_succeeds():
    robot = load_robot("panda")
    rate, results = _near_seed_round_trip(robot, 500, seed=22, position_only=True)
    assert rate == 1.0
    assert all(robot.within_limits(r.q) for _, r in results)
    assert all(r.orientation_error == 0.0 for _, r in results)  # orientation not asked for, not reported


def test_panda_ik_from_a_cold_start_uses_restarts():
    robot = load_robot("panda")
    chain = chain_for(robot)
    rng = np.random.default_rng(23)
    results = [
        solve_ik(chain, chain.fk(q), robot.home, restarts=20, rng=rng) for q in _random_configs(robot, 200, seed=23)
    ]
    assert np.mean([r.success for r in results]) >= 0.995
    assert any(r.restarts > 0 for r in results)
    assert all(robot.within_limits(r.q) for r in results)


def test_ik_respects_tighter_limits_given_per_call():
    robot = load_robot("panda")
    chain = chain_for(robot)
    lower, upper = robot.home - 0.3, robot.home + 0.3
    target = chain.fk(robot.home + 0.2)
    result = solve_ik(chain, target, robot.home, lower=lower, upper=upper)
    assert result.success and np.all(result.q >= lower) and np.all(result.q <= upper)
    blocked = solve_ik(chain, chain.fk(robot.home + 0.5), robot.home, lower=lower, upper=upper)
    assert not blocked.success and np.all(blocked.q >= lower) and np.all(blocked.q <= upper)


def test_unreachable_panda_target_is_an_explicit_failure_with_its_residual():
    robot = load_robot("panda")
    result = solve_ik(chain_for(robot), pose_matrix((2.0, 0.0, 0.5)), robot.home, restarts=2, rng=0)
    assert not result.success
    assert result.position_error > 0.8  # the Panda reaches ~0.86 m from the shoulder
    assert result.restarts == 2 and "unreachable" in result.message
    assert robot.within_limits(result.q)


def test_igt_reaches_planar_targets_and_reports_only_x_y_yaw_errors():
    robot = load_robot("igt")
    chain = chain_for(robot)
    rng = np.random.default_rng(31)
    for q_true in _random_configs(robot, 300, seed=31):
        pose = chain.fk(q_true)
        yaw = math.atan2(pose[1, 0], pose[0, 0])
        target = planar_pose(pose[0, 3], pose[1, 3], yaw, z=5.0)  # z is not controllable and not weighted
        result = solve_ik(chain, target, robot.clip(q_true + rng.uniform(-0.1, 0.1, 3)), weights=PLANAR_WEIGHTS)
        assert result.success, result
        reached = chain.fk(result.q)
        assert np.abs(reached[:2, 3] - pose[:2, 3]).max() <= 1e-6
        yaw_error = math.remainder(math.atan2(reached[1, 0], reached[0, 0]) - yaw, 2 * math.pi)
        assert abs(yaw_error) <= 1e-5
        assert robot.within_limits(result.q)


def test_igt_cold_start_with_restarts():
    robot = load_robot("igt")
    chain = chain_for(robot)
    successes = 0
    for q_true in _random_configs(robot, 200, seed=32):
        pose = chain.fk(q_true)
        target = planar_pose(pose[0, 3], pose[1, 3], math.atan2(pose[1, 0], pose[0, 0]))
        successes += solve_ik(chain, target, robot.home, weights=PLANAR_WEIGHTS, restarts=30, rng=32).success
    assert successes / 200 >= 0.99


def test_igt_unreachable_target_fails_with_the_residual():
    robot = load_robot("igt")
    chain = chain_for(robot)
    result = solve_ik(chain, planar_pose(2.0, 0.0, 0.0), robot.home, weights=PLANAR_WEIGHTS, restarts=3, rng=0)
    assert not result.success
    # Furthest x: rail 0.25 + arm 0.35 + tool 0.25 = 0.85 m, so at least 1.15 m short.
    assert result.position_error == pytest.approx(2.0 - 0.85, abs=1e-3)
    assert robot.within_limits(result.q)
    reached = chain.fk(result.q)
    assert result.position_error == pytest.approx(np.hypot(2.0 - reached[0, 3], reached[1, 3]), abs=1e-12)


def test_yaw_error_is_wrapped():
    robot = load_robot("igt")
    chain = chain_for(robot)
    pose = chain.fk(np.array([0.0, 2.0, 2.0]))  # yaw 4 rad ≡ 4 - 2π
    target = planar_pose(pose[0, 3], pose[1, 3], 4.0 - 2 * math.pi)
    assert solve_ik(chain, target, np.array([0.0, 1.9, 2.1]), weights=PLANAR_WEIGHTS).success


def test_path_ik_along_a_straight_line_is_smooth():
    robot = load_robot("panda")
    chain = chain_for(robot)
    start = chain.fk(robot.home)
    targets = []
    for s in np.linspace(0.0, 1.0, 250):
        pose = start.copy()
        pose[:3, 3] += s * np.array([0.0, 0.3, -0.2])
        targets.append(pose)
    path = solve_path_ik(chain, targets, robot.home)
    assert path.q.shape == (250, 7) and path.success.shape == (250,)
    assert path.success.all()
    assert path.max_joint_jump < 0.05
    assert path.max_joint_jump == pytest.approx(np.abs(np.diff(path.q, axis=0)).max())


def test_bad_inputs_are_rejected_naming_the_value():
    robot = load_robot("panda")
    chain = chain_for(robot)
    with pytest.raises(KinematicsError, match=r"shape \(7,\)"):
        chain.fk(np.zeros(6))
    with pytest.raises(KinematicsError, match="4x4"):
        solve_ik(chain, np.eye(3), robot.home)
    with pytest.raises(KinematicsError, match="weights"):
        solve_ik(chain, np.eye(4), robot.home, weights=(0, 0, 0, 0, 0, 0))
    with pytest.raises(KinematicsError, match="has no link .no_such_link."):
        KinematicChain.from_urdf(robot.urdf_path, "panda_link0", "no_such_link")
    with pytest.raises(KinematicsError, match="differ from the movable joints"):
        KinematicChain.from_urdf(robot.urdf_path, "panda_link0", "panda_link8", joint_names=["panda_joint1"])


def test_pose_matrix_from_quaternion_or_rpy():
    np.testing.assert_allclose(
        pose_matrix((1, 2, 3), rpy=(0, 0, math.pi / 2))[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12
    )
    np.testing.assert_allclose(pose_matrix((1, 2, 3), quat_xyzw=(0, 0, 1, 0))[:3, :3], np.diag([-1, -1, 1]), atol=1e-12)
    assert pose_matrix((1, 2, 3))[:3, 3].tolist() == [1, 2, 3]
    with pytest.raises(KinematicsError, match="not both"):
        pose_matrix((0, 0, 0), quat_xyzw=(0, 0, 0, 1), rpy=(0, 0, 0))
