"""sim.commander through a trajectory controller (a real arm's interface): the physics node as the Panda's franka_ros
driver on wall time, the commander's sweep sent as follow_joint_trajectory goals that replace each other. The test
process hears the action's goals and results and the joint states, as a rosbag would; the commander's log gives the
tracking (the accuracy campaign's base case keeps its MAPE: README's base case is <= 0.03 % per joint)."""

from __future__ import annotations

import csv
import subprocess
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sim.control.scenarios import ScenarioConfig, build_motion
from sim.robots import load_robot
from tests.integration.sim_helpers import start_physics_node
from tests.rosenv import PYTHON, REPO, wait_for

pytestmark = pytest.mark.lane("realtime", on=("project",))

NS = "/panda/position_joint_trajectory_controller"
JOINT_STATES = "/franka_state_controller/joint_states"


def test_the_sweep_through_a_trajectory_controller_tracks_as_the_stream_does(roscore, ros_node, tmp_path: Path):
    from sensor_msgs.msg import JointState

    from sim.wire.control_types import control_types

    robot = load_robot("panda")
    types = control_types()
    lock = threading.Lock()
    goals: list[Any] = []
    results: list[Any] = []
    states: list[Any] = []

    def keep(into: list[Any]):  # type: ignore[no-untyped-def]
        def callback(message: Any) -> None:
            with lock:
                into.append(message)

        return callback

    subscribers = [
        ros_node.Subscriber(f"{NS}/follow_joint_trajectory/goal", types.action_goal, keep(goals), queue_size=1000),
        ros_node.Subscriber(
            f"{NS}/follow_joint_trajectory/result", types.action_result, keep(results), queue_size=1000
        ),
        ros_node.Subscriber(JOINT_STATES, JointState, keep(states), queue_size=10000),
    ]
    node = start_physics_node(
        roscore, tmp_path, "panda", "--trajectory-controller", NS, "--joint-states-topic", JOINT_STATES
    )
    log = tmp_path / "sweep.csv"
    try:
        wait_for(lambda: states, 20, "the driver's joint states")
        done = subprocess.run(
            [PYTHON, "-m", "sim.commander", "--robot", "panda", "--scenario", "sweep", "--duration", "2"]
            + ["--trajectory-controller", NS, "--joint-states-topic", JOINT_STATES, "--log", str(log)],
            cwd=tmp_path,
            env={**roscore.env, "PYTHONPATH": str(REPO)},
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert done.returncode == 0, done.stdout + done.stderr
        wait_for(lambda: len(results) >= len(goals) > 1, 10, "every goal's result")
    finally:
        for subscriber in subscribers:
            subscriber.unregister()
        node.stop()
    # No /clock and no stream: goals, each stamped with the wall time of the schedule's start.
    stamps = {goal.goal.trajectory.header.stamp.to_sec() for goal in goals}
    assert len(stamps) == 1 and abs(stamps.pop() - states[0].header.stamp.to_sec()) < 600
    assert all(tuple(goal.goal.trajectory.joint_names) == robot.joint_names for goal in goals)
    # Each goal replaced the one before; the last ran to its end.
    by_id = {result.status.goal_id.id: result.status.status for result in results}
    ids = [goal.goal_id.id for goal in goals]
    assert [by_id[i] for i in ids[:-1]] == [2] * (len(ids) - 1)  # PREEMPTED
    assert by_id[ids[-1]] == 3  # SUCCEEDED

    with log.open() as f:
        rows = [row for row in csv.DictReader(f) if row["phase"] == "scenario"]
    motion = build_motion(robot, "sweep", ScenarioConfig(duration=2.0))
    desired = np.array([[float(row[f"desired_{n}"]) for n in robot.joint_names] for row in rows])
    achieved = np.array([[float(row[f"achieved_{n}"]) for n in robot.joint_names] for row in rows])
    np.testing.assert_allclose(desired, motion.positions, atol=1e-9)
    # The achieved joints at the schedule's times: as close as the stream's base case (README: <= 0.03 % MAPE).
    mape = 100 * np.mean(np.abs(achieved - desired) / np.abs(desired), axis=0)
    assert np.all(mape < 0.03), mape
    assert "MAPE %" in done.stdout and "panda_joint7" in done.stdout
