"""sim.engine.physics: the three modes, the implicit drive, input checks, determinism. Fast, no ROS."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from sim.engine.physics import (
    DEFAULT_STIFFNESS,
    DriveParams,
    Mode,
    PhysicsError,
    PhysicsWorld,
    implicit_drive_step,
    render_gif,
)
from sim.robots import load_robot
from tests.robot_files import LIFT_ARM, THIRD_PARTY_URDFS

DT = 0.02
ROBOTS = ["panda", "igt"]


def offset_target(robot_name: str) -> np.ndarray:
    """A target a little away from home in every joint (within the limits)."""
    robot = load_robot(robot_name)
    return robot.home + np.where(np.array(robot.joint_types) == "prismatic", 0.05, 0.3)


# --- modes --------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ROBOTS)
def test_no_physics_sets_the_targets_exactly(name):
    robot = load_robot(name)
    with PhysicsWorld(robot, mode=Mode.NO_PHYSICS) as world:
        target, velocity = offset_target(name), np.linspace(0.1, 0.3, robot.dof)
        world.set_targets(target, velocity)
        sample = world.step()
        np.testing.assert_array_equal(sample.positions, target)
        np.testing.assert_array_equal(sample.velocities, velocity)
        np.testing.assert_array_equal(sample.efforts, np.zeros(robot.dof))
        assert sample.time == pytest.approx(DT)


@pytest.mark.parametrize("name", ROBOTS)
def test_infinite_stiffness_reaches_a_step_target_within_one_step(name):
    robot = load_robot(name)
    with PhysicsWorld(robot, mode=Mode.INFINITE_STIFFNESS) as world:
        target = offset_target(name)
        world.set_targets(target)
        sample = world.step()
        np.testing.assert_allclose(sample.positions, target, atol=1e-12)
        np.testing.assert_allclose(sample.velocities, (target - robot.home) / DT, rtol=1e-12)
        assert np.all(np.abs(sample.efforts) > 0)  # the (unlimited) torque that jump took
        sample = world.step()  # and it stays there
        np.testing.assert_allclose(sample.positions, target, atol=1e-12)


@pytest.mark.parametrize("name", ROBOTS)
def test_physics_converges_to_a_constant_target(name):
    robot = load_robot(name)
    target = offset_target(name)
    with PhysicsWorld(robot, gravity=False) as world:
        world.set_targets(target)
        for _ in range(100):  # 2 s
            sample = world.step()
        np.testing.assert_allclose(sample.positions, target, atol=1e-9)
        np.testing.assert_allclose(sample.velocities, 0.0, atol=1e-8)
    with PhysicsWorld(robot) as world:  # with gravity: a PD drive keeps an offset of gravity torque / stiffness
        world.set_targets(target)
        for _ in range(100):
            sample = world.step()
        np.testing.assert_allclose(sample.positions, target, atol=1e-3)
        np.testing.assert_allclose(sample.velocities, 0.0, atol=1e-6)


@pytest.mark.parametrize("name", ROBOTS)
def test_physics_follows_a_moving_target(name):
    robot = load_robot(name)
    amplitude = np.where(np.array(robot.joint_types) == "prismatic", 0.05, 0.4)
    omega = 2.0
    with PhysicsWorld(robot) as world:
        errors = []
        for k in range(1, 151):
            t = k * DT  # targets for the END of the step, with velocity feed-forward
            world.set_targets(robot.home + amplitude * np.sin(omega * t), amplitude * omega * np.cos(omega * t))
            errors.append(world.step().positions - (robot.home + amplitude * np.sin(omega * t)))
    # after the start-up transient (it starts at rest, the target does not)
    assert np.max(np.abs(errors[25:])) < 1e-3


def test_targets_for_the_start_of_the_step_lag_one_step():
    """The timing convention: the same ramp passed one step early lags by ~ one step of motion."""
    robot = load_robot("panda")
    rate = 0.5  # rad/s on joint 1
    results = {}
    for convention, shift in (("end", 0), ("start", -1)):
        with PhysicsWorld(robot, gravity=False) as world:
            for k in range(1, 51):
                target = robot.home.copy()
                target[0] += rate * (k + shift) * DT
                world.set_targets(target, np.r_[rate, np.zeros(6)])
                sample = world.step()
        results[convention] = robot.home[0] + rate * 50 * DT - sample.positions[0]
    assert abs(results["end"]) < 1e-9
    assert results["start"] == pytest.approx(rate * DT, rel=1e-3)


@pytest.mark.parametrize("name", ROBOTS)
def test_efforts_stay_within_the_force_limits(name):
    robot = load_robot(name)
    far = robot.home + np.where(np.array(robot.joint_types) == "prismatic", 0.2, 2.0)
    with PhysicsWorld(robot) as world:
        drive = world.drive
        world.set_targets(far)
        efforts = np.array([world.step().efforts for _ in range(50)])
    assert np.all(np.isfinite(efforts))
    assert np.all(np.abs(efforts) <= drive.force_limit * (1 + 1e-12))
    np.testing.assert_allclose(np.abs(efforts[0]), drive.force_limit)  # a far step saturates every drive at once


def test_a_far_step_target_settles_under_force_limits():
    robot = load_robot("igt")
    target = np.array([0.2, -2.0, 2.0])
    with PhysicsWorld(robot) as world:
        world.set_targets(target)
        samples = [world.step() for _ in range(250)]
    assert max(np.max(np.abs(s.velocities)) for s in samples) < 100.0
    np.testing.assert_allclose(samples[-1].positions, target, atol=1e-6)


def test_the_clamped_drive_step_is_consistent_with_newtons_law():
    mass = np.array([[2.0, 0.3], [0.3, 0.5]])
    bias = np.array([1.0, -0.5])
    drive = DriveParams(np.array([1e5, 1e5]), np.array([500.0, 100.0]), np.array([10.0, 1e9]))
    q, v = np.zeros(2), np.array([0.1, 0.0])
    v_next, force = implicit_drive_step(mass, bias, q, v, np.array([1.0, 0.01]), np.zeros(2), drive, DT)
    assert force[0] == pytest.approx(10.0)  # clamped
    np.testing.assert_allclose(mass @ (v_next - v) / DT, force - bias, atol=1e-9)
    # the free joint's force is still the drive law evaluated at the end of the step
    expected = 1e5 * (0.01 - DT * v_next[1]) - 100.0 * v_next[1]
    assert force[1] == pytest.approx(expected)


def test_implicit_drive_is_stable_where_an_explicit_pd_diverges():
    """Panda joint 1 (M ≈ 1.24 kg·m²), K = 1e5: dt·sqrt(K/M) ≈ 5.7 > 2, so the explicit PD blows up at 0.02 s."""
    mass, stiffness = np.array([[1.24]]), 1e5
    damping = 2 * np.sqrt(stiffness * mass[0, 0])
    drive = DriveParams(np.array([stiffness]), np.array([damping]), np.array([np.inf]))
    target = np.array([0.5])
    q_exp, v_exp = np.zeros(1), np.zeros(1)
    q_imp, v_imp = np.zeros(1), np.zeros(1)
    for _ in range(50):
        force = stiffness * (target - q_exp) - damping * v_exp  # explicit: evaluated at the start of the step
        v_exp = v_exp + DT * force / mass[0, 0]
        q_exp = q_exp + DT * v_exp
        v_imp, _ = implicit_drive_step(mass, np.zeros(1), q_imp, v_imp, target, np.zeros(1), drive, DT)
        q_imp = q_imp + DT * v_imp
    assert abs(q_exp[0]) > 1e6  # diverged
    assert q_imp[0] == pytest.approx(0.5, abs=1e-9)
    # and the full Panda world with these gains settles too, with no force limit to help it
    robot = load_robot("panda")
    with PhysicsWorld(robot, gravity=False) as world:
        world.set_drive(world.drive.with_overrides(force_limit=float("inf")))
        world.set_targets(offset_target("panda"))
        for _ in range(50):
            sample = world.step()
    np.testing.assert_allclose(sample.positions, offset_target("panda"), atol=1e-6)


def test_substeps_follow_the_same_target():
    robot = load_robot("igt")
    with PhysicsWorld(robot, substeps=5, gravity=False) as world:
        world.set_targets(offset_target("igt"))
        for _ in range(100):
            sample = world.step()
        assert sample.time == pytest.approx(100 * DT)
        np.testing.assert_allclose(sample.positions, offset_target("igt"), atol=1e-7)


# --- inputs, determinism, life cycle ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("positions", "velocities", "message"),
    [
        (np.zeros(6), None, r"shape \(6,\)"),
        (np.zeros((7, 1)), None, r"shape \(7, 1\)"),
        ([0, 0, np.nan, 0, 0, 0, 0], None, "panda_joint3"),
        (np.zeros(7), [0, 0, 0, 0, 0, 0, np.inf], "target velocities.*panda_joint7"),
        (["a"] * 7, None, "7 numbers"),
    ],
)
def test_invalid_targets_are_refused_by_name(positions, velocities, message):
    with PhysicsWorld(load_robot("panda")) as world:
        with pytest.raises(PhysicsError, match=message):
            world.set_targets(positions, velocities)
        np.testing.assert_array_equal(world.step().positions.shape, (7,))  # the old targets still hold


def test_invalid_construction_is_refused():
    robot = load_robot("igt")
    with pytest.raises(PhysicsError, match="dt"):
        PhysicsWorld(robot, dt=0.0)
    with pytest.raises(PhysicsError, match="substeps"):
        PhysicsWorld(robot, substeps=0)
    with pytest.raises(PhysicsError, match="stiffness has shape"):
        PhysicsWorld(robot, drive=DriveParams(np.ones(2), np.ones(3), np.ones(3)))
    with pytest.raises(PhysicsError, match="damping must be >= 0"):
        PhysicsWorld(robot, drive=DriveParams(np.full(3, 1e5), np.full(3, -1.0), np.ones(3)))
    with pytest.raises(PhysicsError, match="q0"):
        PhysicsWorld(robot, q0=[0.0, np.nan, 0.0])


@pytest.mark.parametrize("mode", list(Mode))
def test_two_worlds_with_the_same_inputs_are_identical(mode):
    robot = load_robot("panda")
    with PhysicsWorld(robot, mode=mode) as first, PhysicsWorld(robot, mode=mode) as second:
        for k in range(1, 60):
            target = robot.home + 0.5 * np.sin(0.1 * k)
            for world in (first, second):
                world.set_targets(target, np.full(7, 0.05 * np.cos(0.1 * k)))
            a, b = first.step(), second.step()
            np.testing.assert_array_equal(a.positions, b.positions)
            np.testing.assert_array_equal(a.velocities, b.velocities)
            np.testing.assert_array_equal(a.efforts, b.efforts)


def test_reset_teleports_and_holds():
    robot = load_robot("panda")
    with PhysicsWorld(robot) as world:
        world.step()
        world.reset(offset_target("panda"))
        state = world.state()
        np.testing.assert_array_equal(state.positions, offset_target("panda"))
        np.testing.assert_array_equal(state.velocities, np.zeros(7))
        assert state.time == pytest.approx(DT)
        with pytest.raises(PhysicsError, match="reset positions"):
            world.reset(np.zeros(3))


def test_closed_world_refuses_to_step():
    world = PhysicsWorld(load_robot("igt"))
    world.close()
    world.close()  # twice is fine
    with pytest.raises(PhysicsError, match="closed"):
        world.step()


# --- kinematics and pictures --------------------------------------------------------------------------------------


def test_ee_pose_is_the_link_frame_not_the_centre_of_mass():
    robot = load_robot("igt")
    with PhysicsWorld(robot, mode=Mode.NO_PHYSICS, q0=np.zeros(3)) as world:
        position, orientation = world.ee_pose()
        np.testing.assert_allclose(position, [0.6, 0.0, 0.28], atol=1e-9)  # rail 0 + 0.35 + 0.25 along x
        np.testing.assert_allclose(np.abs(orientation), [0, 0, 0, 1], atol=1e-9)
        world.set_targets([0.1, np.pi / 2, 0.0])
        world.step()
        position, orientation = world.ee_pose()
        np.testing.assert_allclose(position, [0.1, 0.6, 0.28], atol=1e-9)
        np.testing.assert_allclose(np.abs(orientation), [0, 0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-9)


def test_panda_flange_is_where_franka_says_at_zero():
    with PhysicsWorld(load_robot("panda"), mode=Mode.NO_PHYSICS, q0=np.zeros(7)) as world:
        position, _ = world.ee_pose()
    # DH: x = a4 - a5... at q = 0: x = 0.0825 - 0.0825 + 0.088 = 0.088, z = 0.333 + 0.316 + 0.384 - 0.107 = 0.926
    np.testing.assert_allclose(position, [0.088, 0.0, 0.926], atol=1e-6)


def test_render_writes_a_png_and_a_gif(tmp_path):
    with PhysicsWorld(load_robot("igt")) as bare:
        with pytest.raises(PhysicsError, match="made without shapes"):
            bare.capture(32, 24)
    with PhysicsWorld(load_robot("igt"), shapes=True) as world:
        path = world.render(tmp_path / "igt.png", width=64, height=48)
        frames = [world.capture(32, 24)]
        world.set_targets(offset_target("igt"))
        world.step()
        frames.append(world.capture(32, 24))
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert frames[0].shape == (24, 32, 3) and frames[0].dtype == np.uint8
    assert frames[0].std() > 0  # not a blank picture
    gif = render_gif(frames, tmp_path / "igt.gif")
    assert gif.read_bytes()[:6] == b"GIF89a"


# ---------------------------------------------------------------------------------------- defaults from the model
def test_default_damping_is_critical_from_the_mass_matrix_at_home():
    robot = load_robot("panda")
    with PhysicsWorld(robot) as world:
        inertia, drive = world.home_inertia(), world.drive
    np.testing.assert_allclose(drive.stiffness, DEFAULT_STIFFNESS)
    np.testing.assert_allclose(drive.damping, 2 * np.sqrt(DEFAULT_STIFFNESS * inertia))
    # the values the Panda was tuned with by hand before they were computed
    np.testing.assert_allclose(drive.damping, [790.0, 970.0, 840.0, 810.0, 580.0, 540.0, 490.0], rtol=0.02)
    np.testing.assert_allclose(drive.force_limit, robot.max_effort)


def test_gravity_feedforward_keeps_a_heavy_lift_from_sagging():
    arm = load_robot(str(LIFT_ARM))
    settled = {}
    for feedforward in (True, False):
        with PhysicsWorld(arm, gravity_feedforward=feedforward) as world:
            for _ in range(200):
                sample = world.step()
            settled[feedforward] = sample.positions - arm.home
    assert np.abs(settled[True]).max() < 1e-9
    carried = 12.0 + 0.5 + 3.0 + 1.5 + 1.0 + 0.6 + 0.01 + 2 * 0.05  # every link above the lift; the camera: 1 kg
    assert settled[False][0] == pytest.approx(-carried * 9.81 / DEFAULT_STIFFNESS, rel=0.01)


def test_links_without_inertia_are_warned_about(caplog):
    with caplog.at_level(logging.WARNING, logger="sim.engine.physics"):
        PhysicsWorld(load_robot(str(LIFT_ARM))).close()
    assert "link(s) camera have no <inertial>" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="sim.engine.physics"):
        PhysicsWorld(load_robot(str(THIRD_PARTY_URDFS["xarm6"]))).close()
    assert "link(s) link2, link3 have inertia tensors that are not physical" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="sim.engine.physics"):
        PhysicsWorld(load_robot("panda")).close()
    assert "inertia" not in caplog.text
