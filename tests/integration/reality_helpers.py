"""Helpers for the reality condition's integration tests: the Panda's stand-in as franka_ros shows it (the physics
node's trajectory controller on wall time), what the test process sees of it (the runner's phases, the arm's joint
states, and what the controller executes), the runner as a subprocess, and a relay of the controller's topics that
can hold back or change a goal."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.fault_relays import HeardGoals
from sim.engine.executed import Executed, executed_extremes
from sim.launchers import Launcher, PhysicsNode, start
from sim.study.design.feasibility import Approaches
from sim.study.design.fit import scene_for
from sim.study.design.scene import load_scene, scene_robot
from sim.study.run.protocol import STATUS_TOPIC, status_from_json
from sim.study.safety.limits import PANDA_LIMITS
from tests.integration.sim_helpers import start_physics_node
from tests.rosenv import PYTHON, REPO, kill_process, wait_for
from tests.study_arms import study_arm

SCENE = load_scene()
ROBOT = scene_robot(SCENE)
NS = "/position_joint_trajectory_controller"  # franka_ros's, as its preset says
JOINT_STATES = "/franka_state_controller/joint_states"
PREEMPTED, SUCCEEDED, ABORTED, REJECTED = 2, 3, 4, 5  # actionlib_msgs/GoalStatus


class Watch:
    """The runner's phases (its status topic) and the arm's joint states, as the test process hears them."""

    def __init__(self, rospy: Any, joint_states: str = JOINT_STATES) -> None:
        from sensor_msgs.msg import JointState
        from std_msgs.msg import String

        self.phases: list[tuple[int, str]] = []
        self.states: list[Any] = []
        self.changed = threading.Condition()
        self.out = ""  # the runner's --out
        self.on_phase: Any = None  # called with each (index, phase) the runner says, after it is kept
        self._subscribers = [
            rospy.Subscriber(STATUS_TOPIC, String, self._on_status),
            rospy.Subscriber(joint_states, JointState, self._on_state),
        ]

    def _on_status(self, message: Any) -> None:
        status = status_from_json(message.data)
        with self.changed:
            self.phases.append((status.index, status.phase))
            self.changed.notify_all()
            on_phase = self.on_phase
        if on_phase is not None:
            on_phase((status.index, status.phase))

    def _on_state(self, message: Any) -> None:
        with self.changed:
            self.states.append(message)

    def wait(self, phase: tuple[int, str], runner: subprocess.Popen, timeout: float = 60) -> None:
        """Until the runner says `phase`; a runner that ends first fails the test with what it printed."""
        deadline = time.monotonic() + timeout
        with self.changed:
            while phase not in self.phases and runner.poll() is None and time.monotonic() < deadline:
                self.changed.wait(0.2)
            if phase in self.phases:
                return
        output = runner.communicate(timeout=10)[0] if runner.poll() is not None else "(still running)"
        raise AssertionError(f"no {phase} in {self.phases}; the runner: {output}")

    def resting_positions(self) -> np.ndarray:
        """The arm's positions once it has rested for 15 joint states (half a second at 30 Hz)."""

        def resting() -> list[float] | None:
            with self.changed:
                recent = self.states[-15:]
            if len(recent) < 15:
                return None
            positions = np.array([s.position for s in recent])
            speeds = np.abs(np.array([s.velocity for s in recent]))
            return positions[-1].tolist() if np.ptp(positions, axis=0).max() < 1e-4 and speeds.max() < 1e-3 else None

        return np.array(wait_for(resting, 30, "the arm at rest"))

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()


OFFSET_CLOCK = REPO / "bench" / "offset_clock.py"  # a process whose wall clock is off this machine's


@dataclass(frozen=True)
class _OffsetClock:
    """A program's launcher run with its wall clock `offset` s off (bench/offset_clock.py)."""

    program: Launcher
    offset: float

    @property
    def ready(self) -> str | None:
        return self.program.ready

    def argv(self) -> list[str]:
        argv = self.program.argv()
        module = argv.index("-m")
        return [argv[0], str(OFFSET_CLOCK), repr(self.offset), *argv[module + 1 :]]


def start_arm(
    roscore,
    ros_node,
    tmp_path: Path,
    robot: str,
    namespace: str,
    joint_states: str,
    *options: str,
    clock_offset: float = 0.0,
) -> Iterator[Watch]:
    """The stand-in's trajectory controller; `clock_offset` s: its wall clock off this machine's (its goals started
    and its joint states stamped on it), as a robot PC's that is not synchronised."""
    args = (
        "--mode", "physics", "--trajectory-controller", namespace,
        "--joint-states-topic", joint_states, "--joint-states-rate", "30", *options,
    )  # fmt: skip
    if clock_offset == 0.0:
        node = start_physics_node(roscore, tmp_path, robot, *args)
    else:
        program = _OffsetClock(PhysicsNode(("--robot", robot), extra=args), clock_offset)
        node = start(program, roscore.env, tmp_path, f"{robot}_physics", timeout=30)
    watch = Watch(ros_node, joint_states)
    try:
        yield watch
    finally:
        watch.close()
        node.stop()


@pytest.fixture
def arm(roscore, ros_node, tmp_path: Path) -> Iterator[tuple[None, Watch]]:
    """The Panda's stand-in as franka_ros shows it."""
    for watch in start_arm(roscore, ros_node, tmp_path, "panda", NS, JOINT_STATES):
        yield None, watch


BUILT_ARM = "meshed_arm7"  # one the tests build (tests/study_arms.py), with the scene proposed for it


@pytest.fixture
def built_arm(roscore, ros_node, tmp_path: Path, monkeypatch) -> Iterator[tuple[Path, Watch]]:
    """The built arm's stand-in under a namespace of the lab's choosing, its drives 10^4 times softer than the
    stand-in's (--stiffness 10 against 1e5 N·m/rad): it lags its commanded path by ~7 mrad on the test's approach,
    where the stiff drives lag by ~0.03 mrad. Its scene proposed (and cached for the runner: the suite's cache where
    test.sh gives one)."""
    cache = os.environ.get("VR_SIM_CACHE") or str(tmp_path / "cache")
    monkeypatch.setenv("VR_SIM_CACHE", cache)  # this process's and the runner's (start_runner passes it on)
    urdf = study_arm(tmp_path / "arms", BUILT_ARM)
    soft = ("--stiffness", "10")
    for watch in start_arm(roscore, ros_node, tmp_path, str(urdf), "/arm/traj_controller", "/arm/joint_states", *soft):
        yield urdf, watch


STEPPED_CLOCK = REPO / "bench" / "stepped_clock.py"  # the fault bench's, which the tests share


def start_runner(
    roscore, plan: Path, out: Path, extra: Sequence[str] = (), auto_go: bool = True, stepped_clock: bool = False
) -> subprocess.Popen:
    """The runner on the plan, the observer at its keyboard; `stepped_clock`: its wall clock steps on SIGUSR1 (+2 s)
    and SIGUSR2 (-2 s), as an NTP step on the runner's machine would (bench/stepped_clock.py)."""
    env = dict(roscore.env)
    if "VR_SIM_CACHE" in os.environ:
        env["VR_SIM_CACHE"] = os.environ["VR_SIM_CACHE"]
    program = [str(STEPPED_CLOCK)] if stepped_clock else ["-m", "sim.study"]
    command = [PYTHON, *program, "run", "--plan", str(plan), "--out", str(out), "--keyboard", "--realtime"]
    return subprocess.Popen(
        command + ["--no-record", *(["--auto-go"] if auto_go else []), "--connect-timeout", "30", *extra],
        env=env, cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, start_new_session=True,
    )  # fmt: skip


def type_line(runner: subprocess.Popen, line: str) -> None:
    assert runner.stdin is not None
    runner.stdin.write(line)
    runner.stdin.flush()


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as source:
        return list(csv.DictReader(source))


def hand_distance(positions: np.ndarray, robot: Path | None = None) -> float:
    """The distance to the hand of the Panda (the default scene) or of the arm at `robot` (its proposed scene)."""
    scene, spec = (SCENE, ROBOT) if robot is None else scene_for(None, str(robot), None)
    with Approaches(spec, scene, 0.01) as approaches:
        return approaches.hand_distance(np.asarray(positions, dtype=float))


RELAY = "/relayed_controller"  # the namespace the runner talks to, relayed by the test process to the stand-in's


class ControllerRelay:
    """The stand-in's controller as the runner sees it under RELAY: its action's five topics and query_state relayed
    by the test process, each goal passed through `on_goal(number, action_goal)` (1 for the first goal), which may
    change it and returns how long to hold it back (s)."""

    def __init__(self, rospy: Any, on_goal: Any = None, query: bool = True) -> None:
        from actionlib_msgs.msg import GoalID, GoalStatusArray

        from sim.wire.control_types import control_types

        types = control_types()
        self.on_goal = on_goal or (lambda number, goal: 0.0)
        self.goals: list[Any] = []
        self.statuses: dict[str, int] = {}  # the stand-in's last status of each goal, by its id
        self.lock = threading.Lock()
        self.timers: list[threading.Timer] = []
        here, there = f"{RELAY}/follow_joint_trajectory", f"{NS}/follow_joint_trajectory"
        self.outgoing = {  # to the stand-in
            "goal": rospy.Publisher(f"{there}/goal", types.action_goal, queue_size=10),
            "cancel": rospy.Publisher(f"{there}/cancel", GoalID, queue_size=10),
        }
        self.incoming = {  # to the runner
            "status": rospy.Publisher(f"{here}/status", GoalStatusArray, queue_size=10),
            "feedback": rospy.Publisher(f"{here}/feedback", types.action_feedback, queue_size=10),
            "result": rospy.Publisher(f"{here}/result", types.action_result, queue_size=10),
        }
        self.query = rospy.ServiceProxy(f"{NS}/query_state", types.query_state, persistent=True)
        self.endpoints: list[Any] = [
            rospy.Subscriber(f"{here}/goal", types.action_goal, self._on_goal),
            rospy.Subscriber(f"{here}/cancel", GoalID, self.outgoing["cancel"].publish),
            rospy.Subscriber(f"{there}/status", GoalStatusArray, self._on_status),
            rospy.Subscriber(f"{there}/feedback", types.action_feedback, self.incoming["feedback"].publish),
            rospy.Subscriber(f"{there}/result", types.action_result, self._on_result),
            *self.outgoing.values(),
            *self.incoming.values(),
        ]

        self.rospy, self.types = rospy, types
        self.query_delay = 0.0  # s each query_state answer is held back
        # s a refusal's result is held back behind its status, as a loaded machine may deliver them: actionlib's server
        # sends them on topics of their own, and the client's goal is done only once the result has come
        self.refusal_result_delay = 0.0
        self.query_service: Any = None
        if query:
            self.restart_query()

    def restart_query(self) -> None:
        """query_state offered anew (a controller restarted): a client's connection to the old one is broken."""
        self.drop_query()
        self.query_service = self.rospy.Service(f"{RELAY}/query_state", self.types.query_state, self._on_query)

    def _on_query(self, request: Any) -> Any:
        if self.query_delay > 0:
            time.sleep(self.query_delay)
        return self.query(request.time)

    def drop_query(self) -> None:
        """query_state gone (its node's service shut down)."""
        if self.query_service is not None:
            self.query_service.shutdown()
            self.query_service = None

    def _on_goal(self, goal: Any) -> None:
        with self.lock:
            self.goals.append(goal)
            number = len(self.goals)
        hold = self.on_goal(number, goal)
        if hold > 0:
            timer = threading.Timer(hold, self.outgoing["goal"].publish, (goal,))
            self.timers.append(timer)
            timer.start()
        else:
            self.outgoing["goal"].publish(goal)

    def _on_result(self, message: Any) -> None:
        from actionlib_msgs.msg import GoalStatus

        if message.status.status == GoalStatus.REJECTED and self.refusal_result_delay > 0:
            timer = threading.Timer(self.refusal_result_delay, self.incoming["result"].publish, (message,))
            self.timers.append(timer)
            timer.start()
        else:
            self.incoming["result"].publish(message)

    def _on_status(self, message: Any) -> None:
        with self.lock:
            for status in message.status_list:
                self.statuses[status.goal_id.id] = status.status
        self.incoming["status"].publish(message)

    def status(self, number: int) -> int | None:
        """The stand-in's last status of goal `number` (None while it has not said)."""
        with self.lock:
            return self.statuses.get(self.goals[number - 1].goal_id.id) if len(self.goals) >= number else None

    def close(self) -> None:
        for timer in self.timers:
            timer.cancel()
        self.query.close()
        self.drop_query()
        for endpoint in self.endpoints:
            endpoint.shutdown() if hasattr(endpoint, "shutdown") else endpoint.unregister()


class ExecutedWatch:
    """What the controller executes: every goal and cancel sent to it, as a listener beside it hears them
    (bench.fault_relays.HeardGoals, the fault bench's), replayed through ros_control's semantics at 1 kHz
    (sim.engine.executed). A bridge the controller makes from a late replacement, or a hold's step, shows there; the
    goals as sent do not show them."""

    def __init__(self, rospy: Any, namespace: str, stop_trajectory_duration: float = 0.0) -> None:
        from sim.wire.control_types import control_types

        self.goals = HeardGoals(rospy, control_types(), namespace)
        self.stop_trajectory_duration = stop_trajectory_duration

    def extremes(self, start: np.ndarray, until: float) -> Executed:
        """The executed motion from the first goal heard to wall time `until`, the arm resting at `start` before,
        against the Panda's limits."""
        return executed_extremes(
            self.goals.taken(), ROBOT.joint_names, start, until, PANDA_LIMITS.acceleration, PANDA_LIMITS.jerk,
            self.stop_trajectory_duration,
        )  # fmt: skip

    def close(self) -> None:
        self.goals.close()


class QueryNode:
    """The controller's query_state offered under RELAY by a node of its own (bench.fault_query_relay, the fault
    bench's), which a test can kill (the service gone, its connections closed) and start anew (a controller
    restarted)."""

    def __init__(self, roscore: Any, rospy: Any) -> None:
        self.roscore, self.rospy = roscore, rospy
        self.process: subprocess.Popen | None = None
        self.start()

    def start(self) -> None:
        self.process = subprocess.Popen(
            [PYTHON, "-m", "bench.fault_query_relay", NS, RELAY], env=dict(self.roscore.env), cwd=REPO,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
        )  # fmt: skip
        assert self.process.stdout is not None and self.process.stdout.readline().strip() == "ready"
        self.rospy.wait_for_service(f"{RELAY}/query_state", 30)

    def stop(self) -> None:
        if self.process is not None:
            kill_process(self.process, first_signal=signal.SIGKILL)
            self.process = None
