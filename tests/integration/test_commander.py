"""sim.commander against the real partner: a session roscore and `python -m sim.physics_node --no-auto-simulate`.

The test process is a rospy node (`ros_node`) that records what the commander publishes; the commander is told
to wait for it (--wait-for) so that nothing is missed. Scenarios run with short durations to keep this quick.
"""

from __future__ import annotations

import csv
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from sim.control.scenarios import ScenarioConfig, build_motion, pose_errors
from sim.geometry.frames import matrix_to_quat
from sim.geometry.kinematics import chain_for
from sim.launchers import PhysicsNode, start, wait_ready
from sim.robots import load_robot
from tests.rosenv import PYTHON, REPO, wait_for

# The commander's runs against the engines alone (test.sh); a refused command line and the CSV export, which run
# no robot through ROS, in the beside lane.
pytestmark = pytest.mark.lane("alone", on=("noetic",))

DT = 0.02


class Probe:
    """Records the commander's topics and the engine's joint states in the test process."""

    def __init__(self, rospy, robot) -> None:
        from geometry_msgs.msg import Pose
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import JointState
        from trajectory_msgs.msg import JointTrajectory

        self.lock = threading.Lock()
        self.commands: list = []
        self.clocks: list[float] = []
        self.poses: list = []
        self.states: list = []
        self.subscribers = [
            rospy.Subscriber(robot.command_topic, JointTrajectory, self._add(self.commands), queue_size=10000),
            rospy.Subscriber("/clock", Clock, self._add(self.clocks, lambda m: m.clock.to_sec()), queue_size=10000),
            rospy.Subscriber(robot.pose_topic, Pose, self._add(self.poses), queue_size=10),
            rospy.Subscriber(robot.joint_states_topic, JointState, self._add(self.states), queue_size=10000),
        ]

    def _add(self, target: list, convert=lambda m: m):
        def callback(message) -> None:
            with self.lock:
                target.append(convert(message))

        return callback

    def clear(self) -> None:
        with self.lock:
            for record in (self.commands, self.clocks, self.poses, self.states):
                record.clear()

    def close(self) -> None:
        for subscriber in self.subscribers:
            subscriber.unregister()


@pytest.fixture(scope="module")
def engines(roscore, ros_node, tmp_path_factory):
    """One /clock-driven physics node per robot (commander runs reuse them: /clock restarting at 0 re-anchors)."""
    log_dir = tmp_path_factory.mktemp("engines")
    launchers = {name: PhysicsNode(("--robot", name), auto_simulate=False) for name in ("panda", "igt")}
    nodes = {name: start(node, roscore.env, log_dir, f"physics_{name}", wait=False) for name, node in launchers.items()}
    try:
        for name, node in nodes.items():
            wait_ready(node, launchers[name], timeout=30)
        yield nodes
    finally:
        for node in nodes.values():
            node.stop()


@pytest.fixture(scope="module")
def probes(ros_node, engines):
    made = {name: Probe(ros_node, load_robot(name)) for name in ("panda", "igt")}
    yield made
    for probe in made.values():
        probe.close()


def run_commander(
    roscore, ros_node, args: list[str], log: Path | None = None, timeout: float = 60.0
) -> subprocess.CompletedProcess:
    command = [PYTHON, "-m", "sim.commander", *args, "--wait-for", ros_node.get_name()]
    if log is not None:
        command += ["--log", str(log)]
    return subprocess.run(command, env=roscore.env, cwd=REPO, capture_output=True, text=True, timeout=timeout)


def read_log(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        return list(reader.fieldnames or []), list(reader)


def columns(rows: list[dict[str, str]], prefix: str, names) -> np.ndarray:
    return np.array([[float(row[f"{prefix}{name}"]) for name in names] for row in rows])


def wait_for_counts(probe: Probe, commands: int, clocks: int) -> None:
    wait_for(
        lambda: len(probe.commands) >= commands and len(probe.clocks) >= clocks,
        10,
        f"{commands} commands and {clocks} /clock messages (have {len(probe.commands)}, {len(probe.clocks)})",
    )


def check_stream(probe: Probe, robot, rows: list[dict[str, str]], priming: int) -> None:
    """The contract: one point with positions and velocities per step, stamped at the step's end, /clock strictly
    increasing from 0 through every stamp, a joint state per step; the log's desired = what was commanded."""
    steps = len(rows)
    wait_for_counts(probe, steps, steps + 1 + priming)
    expected = (np.arange(1, steps + 1) + priming) * DT
    stamps = np.array([c.header.stamp.to_sec() for c in probe.commands])
    np.testing.assert_allclose(stamps, expected, atol=1e-9)
    for command in probe.commands:
        assert list(command.joint_names) == list(robot.joint_names)
        assert len(command.points) == 1
        assert len(command.points[0].positions) == len(command.points[0].velocities) == robot.dof
    clocks = np.array(probe.clocks)
    assert clocks[0] == 0.0 and np.all(np.diff(clocks) > 0)
    np.testing.assert_allclose(clocks, np.arange(steps + 1 + priming) * DT, atol=1e-9)
    commanded = np.array([c.points[0].positions for c in probe.commands])
    np.testing.assert_allclose(columns(rows, "desired_", robot.joint_names), commanded, atol=1e-9)
    np.testing.assert_allclose([float(r["time"]) for r in rows], expected, atol=1e-6)
    np.testing.assert_allclose([float(r["achieved_stamp"]) for r in rows], expected, atol=1e-6)
    wait_for(lambda: len(probe.states) >= steps + priming, 10, "a joint state per step")


# ------------------------------------------------------------------------------------------------------ tests
def test_trial_lockstep_stream_log_and_summary(roscore, ros_node, probes, tmp_path):
    robot = load_robot("panda")
    probe = probes["panda"]
    probe.clear()
    log = tmp_path / "trial.csv"
    started = time.monotonic()
    done = run_commander(roscore, ros_node, ["--robot", "panda", "--scenario", "sweep", "--duration", "1"], log)
    assert done.returncode == 0, done.stderr
    header, rows = read_log(log)
    assert header[:3] == ["time", "scenario_time", "phase"]
    assert [f"achieved_{n}" for n in robot.joint_names] == header[3 + robot.dof : 3 + 2 * robot.dof]
    check_stream(probe, robot, rows, priming=1)
    phases = [r["phase"] for r in rows]
    assert phases[0] == "approach" and phases.count("scenario") == 51  # 1 s of trial: samples 0..50
    scenario = [r for r in rows if r["phase"] == "scenario"]
    motion = build_motion(robot, "sweep", ScenarioConfig(duration=1.0))
    np.testing.assert_allclose(columns(scenario, "desired_", robot.joint_names), motion.positions, atol=1e-9)
    achieved = columns(scenario, "achieved_", robot.joint_names)
    assert np.abs(achieved - motion.positions).max() < 1e-3  # end-of-step targets track closely
    assert f"log: {log}" in done.stdout and "panda_joint7" in done.stdout and "MAPE %" in done.stdout
    assert time.monotonic() - started < 20


@pytest.mark.parametrize("robot_name", ["panda", "igt"])
@pytest.mark.parametrize("scenario, options", [("single", ["--duration", "0.3"]), ("one_joint", ["--duration", "0.6"])])
def test_joint_scenarios_publish_their_motion(roscore, ros_node, probes, tmp_path, robot_name, scenario, options):
    robot = load_robot(robot_name)
    probe = probes[robot_name]
    probe.clear()
    log = tmp_path / "run.csv"
    done = run_commander(roscore, ros_node, ["--robot", robot_name, "--scenario", scenario, *options], log)
    assert done.returncode == 0, done.stderr
    _, rows = read_log(log)
    check_stream(probe, robot, rows, priming=1)
    motion = build_motion(robot, scenario, ScenarioConfig(duration=float(options[1])))
    scenario_rows = [r for r in rows if r["phase"] == "scenario"]
    desired = columns(scenario_rows, "desired_", robot.joint_names)
    np.testing.assert_allclose(desired, motion.positions[-len(scenario_rows) :], atol=1e-9)
    assert not probe.poses  # no end-effector goal in joint scenarios


IK_CASES = [
    ("panda", "ik_joints"),
    ("panda", "ik_cartesian"),
    ("panda", "ik_orientation"),
    ("panda", "fk_confirm"),
    ("igt", "ik_joints"),
    ("igt", "ik_orientation"),
]


@pytest.mark.parametrize("robot_name, scenario", IK_CASES)
def test_ik_scenarios_reach_their_goals(roscore, ros_node, probes, tmp_path, robot_name, scenario):
    robot = load_robot(robot_name)
    chain = chain_for(robot)
    probe = probes[robot_name]
    probe.clear()
    log = tmp_path / "ik.csv"
    options = ["--move-time", "2", "--hold", "0.3"]  # slower would only take longer; faster exceeds velocity limits
    done = run_commander(roscore, ros_node, ["--robot", robot_name, "--scenario", scenario, *options], log)
    assert done.returncode == 0, done.stderr
    header, rows = read_log(log)
    check_stream(probe, robot, rows, priming=1)
    assert "warning" not in done.stderr
    motion = build_motion(robot, scenario, ScenarioConfig(move_time=2.0, hold=0.3))
    # FK of the last commanded joints is at the goal.
    final_command = np.array(probe.commands[-1].points[0].positions)
    pos_err, rot_err = pose_errors(chain.fk(final_command)[None], motion.goal[None], motion.ik.weights)
    assert pos_err[0] < 1e-5 and rot_err[0] < 1e-4
    # The goal went out on the pose topic as a real quaternion.
    wait_for(lambda: probe.poses, 5, "the goal pose")
    pose = probe.poses[-1]
    np.testing.assert_allclose([pose.position.x, pose.position.y, pose.position.z], motion.goal[:3, 3], atol=1e-9)
    quaternion = np.array([pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w])
    assert abs(abs(quaternion @ matrix_to_quat(motion.goal[:3, :3])) - 1.0) < 1e-9
    # FK of the achieved joints (log) ends near the goal; the physics sags a little under gravity.
    assert {"ref_x", "ee_x", "ee_pos_err", "ee_rot_err"} <= set(header)
    assert float(rows[-1]["ee_pos_err"]) < 2e-3 and float(rows[-1]["ee_rot_err"]) < 5e-3
    assert "FK(achieved) at the end vs goal" in done.stdout
    if scenario == "fk_confirm":
        assert "fk_confirm: FK(achieved) vs reference path" in done.stdout
    if scenario == "ik_cartesian":
        assert "max joint jump" in done.stdout


def test_the_euler_pose_convention_sends_the_thesis_convention(roscore, ros_node, probes, tmp_path):
    probe = probes["panda"]
    probe.clear()
    done = run_commander(
        roscore,
        ros_node,
        [
            "--robot",
            "panda",
            "--scenario",
            "ik_orientation",
            "--pose-convention",
            "euler",
            "--move-time",
            "0.2",
            "--hold",
            "0",
            "--approach",
            "0",
        ],
        tmp_path / "e.csv",
    )
    assert done.returncode == 0, done.stderr
    wait_for(lambda: probe.poses, 5, "the goal pose")
    orientation = probe.poses[-1].orientation
    np.testing.assert_allclose(
        [orientation.x, orientation.y, orientation.z, orientation.w], [np.pi / 4, np.pi / 5, np.pi / 3, 0.0], atol=1e-9
    )


def test_unreachable_goal_is_reported_and_nothing_is_commanded(roscore, ros_node, probes, tmp_path):
    probe = probes["panda"]
    probe.clear()
    done = run_commander(roscore, ros_node, ["--robot", "panda", "--scenario", "ik_joints", "--goal", "2", "0", "0.5"])
    assert done.returncode == 3
    assert "UNREACHABLE" in done.stderr and "best residual 1.1" in done.stderr and "--nearest" in done.stderr
    assert not probe.commands


def test_nearest_fallback_is_printed_and_commanded(roscore, ros_node, probes, tmp_path):
    robot = load_robot("igt")
    probe = probes["igt"]
    probe.clear()
    done = run_commander(
        roscore,
        ros_node,
        [
            "--robot",
            "igt",
            "--scenario",
            "ik_joints",
            "--goal",
            "1.2",
            "0.3",
            "--nearest",
            "--move-time",
            "0.4",
            "--hold",
            "0",
        ],
        tmp_path / "n.csv",
    )
    assert done.returncode == 3, done.stderr
    assert "FALLBACK: goal unreachable, commanding the nearest pose found" in done.stderr
    assert "nearest pose found was commanded" in done.stdout
    wait_for(lambda: probe.commands, 5, "commands")
    final = chain_for(robot).fk(np.array(probe.commands[-1].points[0].positions))
    assert np.linalg.norm(final[:2, 3] - [1.2, 0.3]) > 0.3  # not at the (unreachable) goal, but as near as found


def test_realtime_is_paced_by_the_wall_clock(roscore, ros_node, probes, tmp_path):
    robot = load_robot("panda")
    probe = probes["panda"]
    probe.clear()
    log = tmp_path / "rt.csv"
    done = run_commander(
        roscore,
        ros_node,
        ["--robot", "panda", "--scenario", "single", "--realtime", "--duration", "0.4", "--approach", "0"],
        log,
    )
    assert done.returncode == 0, done.stderr
    _, rows = read_log(log)
    steps = len(rows)
    assert steps == 20
    wait_for_counts(probe, steps, steps + 1)
    clocks = np.array(probe.clocks)
    np.testing.assert_allclose(clocks, np.arange(steps + 1) * DT, atol=1e-9)  # 0 (start) .. t_N, strictly rising
    stamps = np.array([c.header.stamp.to_sec() for c in probe.commands])
    np.testing.assert_allclose(stamps, np.arange(1, steps + 1) * DT, atol=1e-9)  # t_k+1 published with /clock t_k
    wall = float(done.stdout.split(" s wall")[0].rsplit(" in ", 1)[1])
    assert 0.35 < wall < 1.0
    np.testing.assert_allclose(columns(rows, "desired_", robot.joint_names)[-1], robot.home)


def test_missing_partner_is_a_clear_error(roscore, ros_node, engines):
    done = run_commander(
        roscore,
        ros_node,
        [
            "--robot",
            "panda",
            "--scenario",
            "single",
            "--duration",
            "0.1",
            "--wait-for",
            "/nobody_here",
            "--connect-timeout",
            "1",
        ],
    )
    assert done.returncode == 4
    assert "no engine after 1 s" in done.stderr and "/nobody_here (not registered)" in done.stderr


@pytest.mark.lane("beside", on=("noetic",))
def test_bad_input_names_the_problem(roscore, ros_node):
    done = run_commander(roscore, ros_node, ["--robot", "panda", "--scenario", "single", "--positions", "1", "2"])
    assert done.returncode == 2
    assert "needs 7 values, got 2" in done.stderr


@pytest.mark.lane("beside", on=("noetic",))
@pytest.mark.parametrize("robot_name, scenario", [("panda", "one_joint"), ("igt", "sweep"), ("panda", "ik_cartesian")])
def test_export_round_trips_through_the_engines_csv_mode(tmp_path, robot_name, scenario):
    robot = load_robot(robot_name)
    exported, replayed = tmp_path / "desired.csv", tmp_path / "achieved.csv"
    done = subprocess.run(
        [
            PYTHON,
            "-m",
            "sim.commander",
            "--robot",
            robot_name,
            "--scenario",
            scenario,
            "--duration",
            "3",
            "--export-csv",
            str(exported),
            "--export-only",
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    engine = subprocess.run(
        [
            PYTHON,
            "-m",
            "sim.engine",
            "--robot",
            robot_name,
            "--csv",
            str(exported),
            "--log",
            str(replayed),
            "--mode",
            "no_physics",
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert engine.returncode == 0, engine.stderr
    desired = np.loadtxt(exported, delimiter=",", skiprows=1)
    achieved = np.loadtxt(replayed, delimiter=",", skiprows=1)
    assert open(replayed).readline().strip() == ",".join(["time", *robot.joint_names])
    # The engine steps to t = dt, 2dt, ... and writes 9 decimals: every row equals the export to that precision.
    np.testing.assert_allclose(achieved[:, 0], desired[1:, 0], atol=1e-6)
    np.testing.assert_allclose(achieved[:, 1:], desired[1:, 1:], atol=1e-9)
