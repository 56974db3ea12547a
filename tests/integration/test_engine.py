"""The game-engine stand-in end to end: real roscore, real endpoint (`python -m bridge`), engine subprocess
(`python -m sim.engine`), and the test process as the controller on plain rospy topics.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from sim.engine.physics import Mode
from sim.robots import load_robot
from tests.integration.sim_helpers import DT, Controller, reference_run, sine_motion, start_engine
from tests.rosenv import EndpointProcess, ManagedProcess, free_port, wait_for

pytestmark = pytest.mark.lane("alone", on=("noetic", "jammy"))

PANDA = load_robot("panda")
IGT = load_robot("igt")
PRIMING = 3


@pytest.fixture
def spawn(roscore, tmp_path: Path) -> Iterator:
    """start(robot, port, *extra) -> a running engine subprocess; every one is stopped (by PID) afterwards."""
    processes: list[ManagedProcess] = []

    def start(robot: str, port: int, *extra: str) -> ManagedProcess:
        process = start_engine(roscore, tmp_path, robot, port, *extra, name=f"engine_{robot}_{len(processes)}")
        processes.append(process)
        return process

    yield start
    for process in reversed(processes):
        process.stop()


@pytest.fixture
def controllers(ros_node) -> Iterator:
    """make(robot, peer) -> a Controller of `robot` talking to the ROS node `peer`; all closed afterwards."""
    made: list[Controller] = []

    def make(robot, peer: str) -> Controller:
        controller = Controller(ros_node, robot, peer)
        made.append(controller)
        return controller

    yield make
    for controller in made:
        controller.close()


def lockstep_engine(spawn, controllers, endpoint, robot, mode: Mode) -> tuple[ManagedProcess, Controller]:
    engine = spawn(robot.name, endpoint.port, "--no-auto-simulate", "--mode", mode.value)
    controller = controllers(robot, endpoint.name)
    controller.wait_ready()
    controller.start_lockstep(PRIMING)
    return engine, controller


def assert_joint_states_well_formed(controller: Controller, robot, steps: int) -> None:
    """The anchor state (stamped 0), then one state per step: names in the robot's order, stamps = step ends,
    seq 1, 2, 3, ... without gaps."""
    states = controller.snapshot()
    assert len(states) == steps + 1, f"{len(states)} joint states for the anchor and {steps} steps"
    for k, state in enumerate(states):
        assert tuple(state.name) == robot.joint_names
        assert len(state.position) == len(state.velocity) == len(state.effort) == robot.dof
        assert abs(state.header.stamp.to_sec() - k * DT) < 1e-6, f"state {k} stamped {state.header.stamp.to_sec()}"
    assert [state.header.seq for state in states] == list(range(1, steps + 2))
    np.testing.assert_array_equal(states[0].position, robot.home)  # the anchor state: where the robot starts


# --- modes ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("robot", [PANDA, IGT], ids=lambda r: r.name)
def test_physics_mode_tracks_a_trajectory_and_reports_well_formed_joint_states(spawn, controllers, endpoint, robot):
    _, controller = lockstep_engine(spawn, controllers, endpoint, robot, Mode.PHYSICS)
    positions, velocities = sine_motion(robot, 50)
    run = controller.lockstep(positions, velocities)
    assert_joint_states_well_formed(controller, robot, PRIMING + 50)

    # the commanded motion moved the simulated joints, and they track it closely (rad and m)
    assert np.abs(run.positions - robot.home).max() > 0.1 * (0.1 if robot.name == "igt" else 1.0)
    error = np.abs(run.positions - run.commanded)
    assert error.max() < 1.5e-3, f"max tracking error {error.max():.2e}"
    # velocities in rad/s (m/s): the step's velocity of the semi-implicit integration, q⁺ = q + dt·v⁺, i.e. the
    # mean velocity over the step, which follows the commanded motion's mean velocity over the step
    np.testing.assert_allclose(run.velocities[1:], np.diff(run.positions, axis=0) / DT, rtol=0, atol=1e-9)
    commanded_mean = np.diff(run.commanded, axis=0) / DT
    assert np.abs(run.velocities[1:] - commanded_mean).max() < 0.02 * np.abs(commanded_mean).max()
    # efforts are the drive's force/torque: inside the limits, and holding the arm up against gravity
    assert np.all(np.abs(run.efforts) <= robot.max_effort + 1e-9)
    assert np.abs(run.efforts).max() > 1.0
    # exactly the physics of an in-process world fed the same targets: each command is the target for the end
    # of the step its stamp names (no extrapolation, no one-step lag), and nothing is lost on the way
    np.testing.assert_array_equal(run.positions, reference_run(robot, Mode.PHYSICS, positions, velocities, PRIMING))


@pytest.mark.parametrize("robot", [PANDA, IGT], ids=lambda r: r.name)
def test_physics_mode_converges_to_a_far_step_with_force_limited_efforts(spawn, controllers, endpoint, robot):
    _, controller = lockstep_engine(spawn, controllers, endpoint, robot, Mode.PHYSICS)
    goal = robot.home.copy()
    goal[0] += 0.2 if robot.joint_types[0] == "prismatic" else 1.0
    steps = 150  # the Panda's wrist (12 N·m) rings, saturated both ways, for ~2.5 s after the base's swing
    run = controller.lockstep(np.tile(goal, (steps, 1)), np.zeros((steps, robot.dof)))
    assert abs(run.positions[0, 0] - goal[0]) > 0.1 * abs(goal[0] - robot.home[0])  # it cannot jump there
    np.testing.assert_allclose(run.positions[-1], goal, rtol=0, atol=1e-3)
    efforts = np.abs(run.efforts)
    assert np.all(efforts <= robot.max_effort * (1 + 1e-12))
    assert efforts[:, 0].max() == pytest.approx(robot.max_effort[0], rel=1e-9)  # the drive saturated on the way


@pytest.mark.parametrize("robot", [PANDA, IGT], ids=lambda r: r.name)
def test_no_physics_achieved_equals_commanded_exactly(spawn, controllers, endpoint, robot):
    _, controller = lockstep_engine(spawn, controllers, endpoint, robot, Mode.NO_PHYSICS)
    positions, velocities = sine_motion(robot, 30, amplitude=0.5)
    positions[10] += 0.3  # a jump as well: no dynamics at all
    run = controller.lockstep(positions, velocities)
    np.testing.assert_array_equal(run.positions, positions)
    np.testing.assert_array_equal(run.velocities, velocities)
    np.testing.assert_array_equal(run.efforts, np.zeros_like(positions))
    assert_joint_states_well_formed(controller, robot, PRIMING + 30)


def test_infinite_stiffness_reaches_a_step_target_within_one_step(spawn, controllers, endpoint):
    _, controller = lockstep_engine(spawn, controllers, endpoint, PANDA, Mode.INFINITE_STIFFNESS)
    goal = PANDA.home + np.array([0.8, -0.3, 0.5, 0.4, -0.6, 0.3, 1.0])
    run = controller.lockstep(np.array([goal, goal, goal]), np.zeros((3, PANDA.dof)))
    np.testing.assert_array_equal(run.positions, [goal, goal, goal])
    np.testing.assert_allclose(run.velocities[0], (goal - PANDA.home) / DT, rtol=1e-9)
    np.testing.assert_array_equal(run.velocities[1:], np.zeros((2, PANDA.dof)))
    # unlimited force: the one-step jump takes far more torque than the physics mode's drive may apply
    assert np.all(np.isfinite(run.efforts))
    assert np.any(np.abs(run.efforts[0]) > PANDA.max_effort)


def test_clock_driven_stepping_is_deterministic_across_runs(spawn, controllers, endpoint, roscore, tmp_path):
    positions, velocities = sine_motion(PANDA, 40, amplitude=0.4, period_s=0.8)
    positions[25:] = PANDA.home + 0.7  # ends with a far step: the force-limited (Newton) branch of the drive
    velocities[25:] = 0.0
    runs = []
    for attempt in range(2):
        server = endpoint if attempt == 0 else EndpointProcess(roscore.env, tmp_path, name=f"ep_det_{os.getpid()}")
        try:
            engine, controller = lockstep_engine(spawn, controllers, server, PANDA, Mode.PHYSICS)
            runs.append(controller.lockstep(positions, velocities))
            engine.stop()
            controller.close()
        finally:
            if server is not endpoint:
                server.stop()
    first, second = runs
    assert np.abs(first.positions - PANDA.home).max() > 0.3
    np.testing.assert_array_equal(first.positions, second.positions)
    np.testing.assert_array_equal(first.velocities, second.velocities)
    np.testing.assert_array_equal(first.efforts, second.efforts)
    np.testing.assert_array_equal(first.stamps, second.stamps)


def test_commands_that_lose_their_race_against_the_tick_are_still_their_steps_targets(spawn, controllers, endpoint):
    """Command and /clock travel on two topics over two connections, so a tick can arrive before its step's command
    (beside two CPU burners, the first five did once, and the run lagged a step). Here every tick is sent first and
    its command only after the engine has had a second to step without it: the first step after the anchor waits
    for its command, and once one has come, so does every step after it (a grace of 60 s, to rule the clock out)."""
    spawn(IGT.name, endpoint.port, "--no-auto-simulate", "--command-grace", "60")
    controller = controllers(IGT, endpoint.name)
    controller.wait_ready()
    controller.clock(0.0)
    controller.wait_state(0.0, timeout=10.0)
    goals = IGT.home + np.array([[0.05, 0.3, -0.3], [0.1, 0.6, -0.6]])
    at_rest = np.zeros_like(goals)
    for k, goal in enumerate(goals, start=1):
        controller.clock(k * DT)
        with pytest.raises(TimeoutError):
            controller.wait_state(k * DT, timeout=1.0)
        controller.command(k * DT, goal, at_rest[0])
        controller.wait_state(k * DT)
    reached = np.array([controller.wait_state(k * DT).position for k in (1, 2)])
    np.testing.assert_array_equal(reached, reference_run(IGT, Mode.PHYSICS, goals, at_rest, priming_steps=0))


# --- auto-simulate --------------------------------------------------------------------------------------------


def test_auto_simulate_steps_on_its_own_and_time_scale_speeds_it_up(spawn, controllers, endpoint):
    """panda at time scale 1 and igt at time scale 4 run side by side on one endpoint, without any /clock."""
    spawn("panda", endpoint.port, "--mode", "no_physics")
    spawn("igt", endpoint.port, "--mode", "no_physics", "--time-scale", "4")
    panda = controllers(PANDA, endpoint.name)
    igt = controllers(IGT, endpoint.name)
    panda.wait_ready(publishers=("command",))
    igt.wait_ready(publishers=("command",))

    panda_start, igt_start = len(panda.wait_count(1)), len(igt.wait_count(1))
    wait_for(lambda: panda.arrivals[-1] - panda.arrivals[panda_start - 1] > 1.0, 10, "1 s of panda states")

    def sim_seconds_per_wall_second(controller: Controller, start: int) -> float:
        states, arrivals = controller.snapshot_with_arrivals()
        states, arrivals = states[start - 1 :], arrivals[start - 1 :]
        sim = states[-1].header.stamp.to_sec() - states[0].header.stamp.to_sec()
        return sim / (arrivals[-1] - arrivals[0])

    panda_rate = sim_seconds_per_wall_second(panda, panda_start)
    igt_rate = sim_seconds_per_wall_second(igt, igt_start)
    assert 0.8 < panda_rate < 1.2, f"panda: {panda_rate:.2f} sim s per wall s"
    assert 3.0 < igt_rate / panda_rate < 5.0, f"igt at --time-scale 4: {igt_rate:.2f} vs panda {panda_rate:.2f}"
    # its own time base without /clock: consecutive stamps one dt apart, seq without gaps
    states = panda.snapshot()
    stamps = np.array([s.header.stamp.to_sec() for s in states])
    np.testing.assert_allclose(np.diff(stamps), DT, atol=1e-6)
    assert [s.header.seq for s in states] == list(range(states[0].header.seq, states[0].header.seq + len(states)))

    # an (unstamped) command moves the joints at the next steps
    goal = PANDA.home + 0.25
    count = len(panda.snapshot())
    panda.command(0.0, goal)
    reached = wait_for(
        lambda: next((s for s in panda.snapshot()[count:] if np.array_equal(s.position, goal)), None),
        5,
        "the commanded pose in auto-simulate mode",
    )
    assert tuple(reached.name) == PANDA.joint_names


# --- bad and partial commands -----------------------------------------------------------------------------------


BAD_COMMANDS = [
    # (names, positions, what the engine's error says)
    (["panda_joint1", "elbow"], [0.1, 0.2], "unknown joint(s) ['elbow']"),
    (list(PANDA.joint_names), [0.1] * 6, "7 joint names but 6 positions"),
    (list(PANDA.joint_names), [0.1, 0.1, float("nan"), 0.1, 0.1, 0.1, 0.1], "positions must be finite"),
    (["panda_joint2", "panda_joint2"], [0.1, 0.2], "names a joint twice"),
]


def test_bad_commands_are_logged_and_rejected_and_the_engine_follows_the_next_valid_one(spawn, controllers, endpoint):
    engine, controller = lockstep_engine(spawn, controllers, endpoint, PANDA, Mode.NO_PHYSICS)
    first = controller.lockstep(np.array([PANDA.home + 0.1]), np.zeros((1, PANDA.dof)))
    for names, positions, message in BAD_COMMANDS:
        controller.command(controller.clock_time, positions, names=names)
        engine.wait_for_output(message, timeout=5)
    assert "no points" not in engine.output()
    from trajectory_msgs.msg import JointTrajectory

    controller.command_pub.publish(JointTrajectory(joint_names=list(PANDA.joint_names)))  # no points at all
    engine.wait_for_output("JointTrajectory has no points", timeout=5)
    assert engine.process.poll() is None
    assert engine.output().count("[ERROR]") == len(BAD_COMMANDS) + 1

    goal = PANDA.home - 0.2
    run = controller.lockstep(np.array([goal, goal + 0.01]), np.zeros((2, PANDA.dof)))
    np.testing.assert_array_equal(run.positions, [goal, goal + 0.01])
    np.testing.assert_array_equal(first.positions[0], PANDA.home + 0.1)
    assert engine.stop() == 0
    assert f"{len(BAD_COMMANDS) + 1} rejected" in engine.output()


def test_commands_may_name_a_subset_of_joints_in_any_order(spawn, controllers, endpoint):
    _, controller = lockstep_engine(spawn, controllers, endpoint, PANDA, Mode.NO_PHYSICS)
    target = PANDA.home + np.arange(1, 8) * 0.05
    reverse = list(reversed(PANDA.joint_names))
    t = controller.clock_time
    state = controller.step(t + DT, target[::-1], names=reverse)
    np.testing.assert_array_equal(state.position, target)  # mapped by name, reported in the robot's order
    assert tuple(state.name) == PANDA.joint_names

    state = controller.step(t + 2 * DT, [-1.5, 0.3], velocities=[0.0, 0.5], names=["panda_joint4", "panda_joint1"])
    expected = target.copy()
    expected[[3, 0]] = [-1.5, 0.3]
    np.testing.assert_array_equal(state.position, expected)  # the other five hold their targets
    np.testing.assert_array_equal(state.velocity, [0.5, 0, 0, 0, 0, 0, 0])

    state = controller.step(t + 3 * DT, [0.9], names=["panda_joint7"])
    expected[6] = 0.9
    np.testing.assert_array_equal(state.position, expected)


# --- pose topic -----------------------------------------------------------------------------------------------


def test_the_pose_topic_sets_the_target_marker_in_both_conventions(ros_node, controllers, endpoint):
    """In-process EngineStandIn instances on real TCP connections to the endpoint (the marker is engine state)."""
    from bridge.client import TcpClient
    from sim.engine.stand_in import EngineOptions, EngineStandIn
    from sim.geometry import frames
    from sim.wire.contract import PoseConvention

    POSE_QUATERNION, POSE_EULER = PoseConvention.QUATERNION, PoseConvention.EULER

    engines = {}
    try:
        for convention in (POSE_QUATERNION, POSE_EULER):
            client = TcpClient("127.0.0.1", endpoint.port, reconnect=False)
            engines[convention] = EngineStandIn(PANDA, client, EngineOptions(pose_convention=convention))
            engines[convention].attach()
            client.connect(timeout=10)
        controller = controllers(PANDA, endpoint.name)
        wait_for(lambda: controller.pose_pub.impl.has_connection(controller.peer), 10, "the endpoint on /panda/pose")

        position = np.array([0.4, -0.1, 0.5])
        angles = np.array([0.3, -0.2, 0.9])
        quaternion = frames.euler_xyz_to_quat(*angles)
        unity_position = frames.ros_to_unity_point(position)

        def shows(convention: str, orientation_unity) -> bool:
            marker = engines[convention].marker
            return (
                marker is not None
                and np.allclose(marker.position_unity, unity_position, atol=1e-12)
                and np.allclose(marker.orientation_unity, orientation_unity, atol=1e-12)
            )

        def publish_until(fields, done) -> None:  # resend: the second client may register after the first pose
            wait_for(
                lambda: controller.pose(position, fields) or done(), 10, f"the markers for {fields}", interval=0.05
            )

        # a real quaternion; the Euler engine reads its x, y, z as angles
        as_euler = frames.ros_to_unity_quat(frames.euler_xyz_to_quat(*quaternion[:3]))
        publish_until(
            quaternion,
            lambda: shows(POSE_QUATERNION, frames.ros_to_unity_quat(quaternion)) and shows(POSE_EULER, as_euler),
        )

        # the thesis's convention: XYZ Euler angles in x, y, z (w = 0); the quaternion engine normalises the fields
        thesis_fields = np.array([*angles, 0.0])
        publish_until(
            thesis_fields,
            lambda: (
                shows(POSE_EULER, frames.ros_to_unity_quat(quaternion))
                and shows(POSE_QUATERNION, frames.ros_to_unity_quat(thesis_fields / np.linalg.norm(thesis_fields)))
            ),
        )

        # a zero quaternion is refused (the marker stays); the Euler engine reads it as angles 0, 0, 0
        kept = engines[POSE_QUATERNION].marker
        publish_until(
            [0.0, 0.0, 0.0, 0.0], lambda: shows(POSE_EULER, frames.ros_to_unity_quat(np.array([0.0, 0.0, 0.0, 1.0])))
        )
        np.testing.assert_array_equal(engines[POSE_QUATERNION].marker.orientation_unity, kept.orientation_unity)
    finally:
        for engine in engines.values():
            engine.client.close()
            engine.close()


# --- endpoint restart, SIGTERM, render ----------------------------------------------------------------------


def test_the_engine_reconnects_when_the_endpoint_restarts_on_the_same_port(spawn, controllers, roscore, tmp_path):
    port = free_port()
    names = iter(range(2))
    servers: list[EndpointProcess] = []

    def start_server() -> EndpointProcess:
        server = EndpointProcess(
            roscore.env, tmp_path, name=f"ep_restart_{os.getpid()}_{next(names)}", extra=("--tcp-port", str(port))
        )
        servers.append(server)
        assert server.port == port
        return server

    try:
        first = start_server()
        engine = spawn("panda", port, "--mode", "no_physics")  # auto-simulate: publishes on its own
        controller = controllers(PANDA, first.name)
        controller.wait_ready(publishers=("command",))
        controller.wait_count(3)

        assert first.stop() is not None and first.process.poll() is not None
        old = controller.snapshot()
        second = start_server()
        controller.peer = f"/{second.name}"
        controller.wait_ready(timeout=20, publishers=("command",))  # the old endpoint is gone: all news is new
        count = len(controller.snapshot())
        new = controller.wait_count(count + 5)[count:]
        # the same engine process, still stepping: its seq and stamps carry on past the outage
        assert engine.process.poll() is None
        assert new[0].header.seq > old[-1].header.seq
        assert new[0].header.stamp.to_sec() > old[-1].header.stamp.to_sec()
        assert [s.header.seq for s in new] == list(range(new[0].header.seq, new[0].header.seq + len(new)))

        goal = PANDA.home - 0.3  # and commands reach it through the new endpoint too
        count = len(controller.snapshot())
        controller.command(0.0, goal)
        wait_for(
            lambda: any(np.array_equal(s.position, goal) for s in controller.snapshot()[count:]),
            5,
            "the command through the new endpoint",
        )
    finally:
        for server in servers:
            server.stop()


def test_sigterm_stops_the_engine_cleanly_and_render_writes_a_png(spawn, controllers, endpoint, tmp_path):
    picture = tmp_path / "pictures" / "final.png"
    engine = spawn("panda", endpoint.port, "--no-auto-simulate", "--mode", "no_physics", "--render", str(picture))
    controller = controllers(PANDA, endpoint.name)
    controller.wait_ready()
    controller.start_lockstep(PRIMING)
    controller.lockstep(np.array([PANDA.home + 0.4]), np.zeros((1, PANDA.dof)))

    os.kill(engine.pid, signal.SIGTERM)
    assert engine.wait(timeout=15) == 0, engine.output()[-2000:]
    assert f"stopped after {PRIMING + 1} steps; {PRIMING + 1} commands, 0 rejected" in engine.output()
    assert "Traceback" not in engine.output()

    from PIL import Image

    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(picture) as image:
        assert image.size == (640, 480)
        pixels = np.asarray(image.convert("RGB"))
    assert pixels.std() > 5.0, "the picture is blank"
