"""`python -m sim.physics_node`: the engine's stepping on plain rospy topics (no endpoint), against a real roscore."""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from sim.engine.physics import Mode
from sim.robots import load_robot
from tests.integration.sim_helpers import DT, Controller, reference_run, sine_motion, start_physics_node
from tests.rosenv import ManagedProcess, wait_for

pytestmark = pytest.mark.lane("alone", on=("noetic",))

PANDA = load_robot("panda")
IGT = load_robot("igt")
PRIMING = 3


@pytest.fixture
def node_and_controller(roscore, ros_node, tmp_path: Path) -> Iterator:
    """start(robot, *extra) -> (physics node process, Controller talking to it); both stopped/closed afterwards."""
    made: list[tuple[ManagedProcess, Controller]] = []

    def start(robot, *extra: str) -> tuple[ManagedProcess, Controller]:
        process = start_physics_node(roscore, tmp_path, robot.name, *extra)
        controller = Controller(ros_node, robot, f"/{robot.name}_physics")
        made.append((process, controller))
        return process, controller

    yield start
    for process, controller in made:
        controller.close()
        process.stop()


@pytest.mark.parametrize("robot", [PANDA, IGT], ids=lambda r: r.name)
def test_lockstep_on_rospy_is_the_same_physics_with_well_formed_joint_states(node_and_controller, robot):
    _, controller = node_and_controller(robot, "--no-auto-simulate", "--mode", "physics")
    controller.wait_ready()
    anchor = controller.start_lockstep(PRIMING)
    np.testing.assert_array_equal(anchor.position, robot.home)
    positions, velocities = sine_motion(robot, 40)
    run = controller.lockstep(positions, velocities)

    states = controller.snapshot()
    assert len(states) == 1 + PRIMING + 40  # the anchor answer, then one state per step
    assert [s.header.seq for s in states] == list(range(1, len(states) + 1))
    np.testing.assert_allclose([s.header.stamp.to_sec() for s in states], DT * np.arange(len(states)), atol=1e-6)
    assert all(tuple(s.name) == robot.joint_names for s in states)
    assert np.abs(run.positions - run.commanded).max() < 1.5e-3
    assert np.abs(run.positions - robot.home).max() > 0.03
    assert np.all(np.abs(run.efforts) <= robot.max_effort + 1e-9)
    np.testing.assert_array_equal(run.positions, reference_run(robot, Mode.PHYSICS, positions, velocities, PRIMING))


def test_bad_commands_are_logged_and_the_node_follows_the_next_valid_one_then_stops_cleanly(node_and_controller):
    node, controller = node_and_controller(PANDA, "--no-auto-simulate", "--mode", "no_physics")
    controller.wait_ready()
    controller.start_lockstep(PRIMING)

    controller.command(controller.clock_time, [0.1, 0.2], names=["panda_joint1", "wrist"])
    node.wait_for_output("unknown joint(s) ['wrist']", timeout=5)
    controller.command(controller.clock_time, [0.1] * 3)
    node.wait_for_output("7 joint names but 3 positions", timeout=5)
    assert node.process.poll() is None

    goal = PANDA.home + 0.3
    velocity = np.full(PANDA.dof, 0.5)
    run = controller.lockstep(np.array([goal]), np.array([velocity]))
    np.testing.assert_array_equal(run.positions[0], goal)
    np.testing.assert_array_equal(run.velocities[0], velocity)
    state = controller.step(controller.clock_time + DT, [-1.0, 0.4], names=["panda_joint4", "panda_joint2"])
    expected = goal.copy()
    expected[[3, 1]] = [-1.0, 0.4]
    np.testing.assert_array_equal(state.position, expected)

    os.kill(node.pid, signal.SIGTERM)
    assert node.wait(timeout=15) == 0, node.output()[-2000:]
    assert f"physics node: stopped after {PRIMING + 2} steps" in node.output()
    assert "Traceback" not in node.output()


def test_auto_simulate_on_rospy_steps_without_clock(node_and_controller):
    _, controller = node_and_controller(IGT, "--mode", "no_physics", "--time-scale", "2")
    controller.wait_ready(publishers=("command",))
    states = controller.wait_count(20)
    stamps = np.array([s.header.stamp.to_sec() for s in states])
    np.testing.assert_allclose(np.diff(stamps), DT, atol=1e-6)
    goal = IGT.home + np.array([0.05, -0.2, 0.3])
    count = len(controller.snapshot())
    controller.command(0.0, goal)
    wait_for(
        lambda: any(np.array_equal(s.position, goal) for s in controller.snapshot()[count:]), 5, "the commanded pose"
    )
