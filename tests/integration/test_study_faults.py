"""Faults injected into the reality condition, one test each, with real parts: the runner (`python -m sim.study run
--realtime --link ...`) drives the physics node's ros_control trajectory controller (franka_ros's topics), and the
test process breaks one thing mid-approach: a signal to the runner, the controller's query_state gone, restarted or
answering late, a malformed or non-finite joint state, a step of the runner's wall clock, a stale feed while braking,
a braking the controller aborts, the tracked hand lost. Each ends with the arm braked to rest well
short of its stand-off, and what the controller executed (every goal it was sent, replayed through ros_control's
semantics at 1 kHz) within the Panda's acceleration and jerk limits. Some run on a controller set up otherwise: a
cancel that takes 0.5 s to rest, joint states at 500 Hz as ur_robot_driver publishes them."""

from __future__ import annotations

import math
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.fault_relays import RELAYED_STATES, StateRelay
from tests.integration.reality_helpers import (
    ABORTED,
    JOINT_STATES,
    NS,
    RELAY,
    ROBOT,
    SCENE,
    ControllerRelay,
    Executed,
    ExecutedWatch,
    QueryNode,
    Watch,
    hand_distance,
    read_csv,
    start_arm,
    start_runner,
    type_line,
)
from tests.integration.study_helpers import trial, write_plan
from tests.rosenv import kill_process

pytestmark = pytest.mark.lane("realtime", on=("project",))

STANDOFF = 0.06  # m: the approach's end, which an arm not braked would reach
SPEED = 0.2  # m/s


@dataclass(frozen=True)
class Arm:
    watch: Watch
    stop_trajectory_duration: float


ARMS = {  # the controller as franka_ros sets it up, and as a UR's driver does (500 Hz, a cancel that eases to rest)
    "franka": ("--joint-states-rate", "30"),
    "ur_like": ("--joint-states-rate", "500", "--stop-trajectory-duration", "0.5"),
}


@pytest.fixture(params=["franka"])
def arm(request, roscore, ros_node, tmp_path: Path) -> Iterator[Arm]:
    options = ARMS[request.param]
    duration = float(options[options.index("--stop-trajectory-duration") + 1]) if len(options) > 2 else 0.0
    for watch in start_arm(roscore, ros_node, tmp_path, "panda", NS, JOINT_STATES, *options):
        yield Arm(watch, duration)


BOTH_ARMS = pytest.mark.parametrize("arm", list(ARMS), indirect=True)


@dataclass(frozen=True)
class Ended:
    code: int
    output: str
    row: dict[str, str] | None
    rest: float  # m, the arm's distance to the hand once at rest
    executed: Executed


def approach_with_fault(
    roscore,
    ros_node,
    arm: Arm,
    tmp_path: Path,
    participant: int,
    fault: Callable[[Any], None],
    link: str = "franka_ros",
    trials: int = 1,
    stepped_clock: bool = False,
    into: float = 0.75,  # s: well into the approach, which starts START_FLOOR (0.25 s) after "moving"
    between: Callable[[], None] = lambda: None,
) -> Ended:
    """The plan's last approach (of `trials`, each vertical to STANDOFF at SPEED) with `fault(runner)` `into` s after
    it began; each trial's distance answered, after `between()` when a trial follows. What the session ended with."""
    watch = arm.watch
    executed = ExecutedWatch(ros_node, NS, arm.stop_trajectory_duration)
    plan = [trial(k, "reality", 1, "vertical", STANDOFF, SPEED) for k in range(1, trials + 1)]
    plan_path = write_plan(tmp_path / "plan.yaml", participant, "reality", plan)
    out = tmp_path / "out"
    home = watch.resting_positions()  # where the controller holds the arm before the first goal
    runner = start_runner(roscore, plan_path, out, ["--link", f"reality={link}"], stepped_clock=stepped_clock)
    try:
        for k in range(1, trials):
            watch.wait((k, "distance"), runner)
            between()
            type_line(runner, "20 cm\n")
        watch.wait((trials, "moving"), runner)
        time.sleep(into)
        fault(runner)
        deadline = time.monotonic() + 60
        while runner.poll() is None and time.monotonic() < deadline:  # bounded: the runner ends or is killed
            with watch.changed:
                asked = (trials, "distance") in watch.phases
            if asked:
                type_line(runner, "20 cm\n")
                break
            time.sleep(0.05)
        output, _ = runner.communicate(timeout=60)
        rest = watch.resting_positions()
        until = time.time()
    finally:
        kill_process(runner)
        executed.close()
    records = out / f"participant_{participant:02d}.csv"
    rows = read_csv(records) if records.exists() else []
    row = rows[trials - 1] if len(rows) >= trials else None
    return Ended(runner.returncode, output, row, hand_distance(rest), executed.extremes(home, until))


def assert_braked(ended: Ended) -> None:
    """The arm braked to rest well short of its stand-off, the controller's motion within the Panda's limits, the
    separation never under the floor (the runner's default) while the arm moved."""
    assert ended.rest > STANDOFF + 0.03, ended.output
    stops = [line for line in ended.output.splitlines() if " stamped " in line]  # how each stop was timed
    assert ended.executed.acceleration <= 1.0 and ended.executed.jerk <= 1.0, (ended.executed.describe(), stops)
    if ended.row is not None and ended.row["least_separation"]:
        assert float(ended.row["least_separation"]) > 0.01


@BOTH_ARMS
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_to_the_runner_mid_approach_brakes_the_arm_before_it_exits(
    roscore, ros_node, arm: Arm, tmp_path: Path, signum: int
) -> None:
    ended = approach_with_fault(roscore, ros_node, arm, tmp_path, 21, lambda runner: os.kill(runner.pid, signum))
    assert ended.code == 130, ended.output
    assert "the approach left (ControllerError: interrupted): braking" in ended.output, ended.output
    assert "the approach: the arm braked to rest" in ended.output, ended.output
    assert_braked(ended)


@BOTH_ARMS
def test_a_press_with_query_state_gone_brakes_along_the_commanded_path(
    roscore, ros_node, arm: Arm, tmp_path: Path
) -> None:
    # The controller's query_state is served by a node of its own, killed mid-approach: its connections close.
    relay, queries = ControllerRelay(ros_node, query=False), QueryNode(roscore, ros_node)

    def gone_then_press(runner: Any) -> None:
        queries.stop()
        type_line(runner, "s\n")

    try:
        ended = approach_with_fault(roscore, ros_node, arm, tmp_path, 22, gone_then_press, f"{RELAY},{JOINT_STATES}")
    finally:
        queries.stop()
        relay.close()
    assert ended.code == 0, ended.output
    assert "from the commanded path (" in ended.output and "query_state failed" in ended.output, ended.output
    assert ended.row is not None and (ended.row["pressed"], ended.row["goal_result"]) == ("true", "SUCCEEDED")
    assert_braked(ended)


def test_a_press_after_the_controller_restarted_between_trials_brakes_from_its_desired_state(
    roscore, ros_node, arm: Arm, tmp_path: Path
) -> None:
    # The runner's query_state connection, made at connect, is broken by the restart between the trials; the second
    # trial's motion finds the service anew, and its press brakes from the controller's answer (not the commanded
    # path's fallback).
    relay, queries = ControllerRelay(ros_node, query=False), QueryNode(roscore, ros_node)

    def restart() -> None:
        queries.stop()
        queries.start()

    try:
        ended = approach_with_fault(
            roscore, ros_node, arm, tmp_path, 23, lambda runner: type_line(runner, "s\n"), f"{RELAY},{JOINT_STATES}",
            trials=2, between=restart,
        )  # fmt: skip
    finally:
        queries.stop()
        relay.close()
    assert ended.code == 0, ended.output
    stops = [line for line in ended.output.splitlines() if ": a stop stamped " in line]
    assert len(stops) == 1 and "from the commanded path" not in stops[0], ended.output
    assert_braked(ended)


@BOTH_ARMS
def test_a_press_with_query_state_answering_late_is_stopped_in_time_from_the_commanded_path(
    roscore, ros_node, arm: Arm, tmp_path: Path
) -> None:
    # query_state answers 0.2 s late (a loaded robot PC), longer than the stop's lead (10-30 ms here): waited for, the
    # stop would reach the controller after its braking was due and be bridged to with a jerk past the limits. The
    # runner waits only what the lead leaves it, and brakes from the commanded path, on time.
    relay = ControllerRelay(ros_node)

    def slow_then_press(runner: Any) -> None:
        relay.query_delay = 0.2
        type_line(runner, "s\n")

    try:
        ended = approach_with_fault(roscore, ros_node, arm, tmp_path, 28, slow_then_press, f"{RELAY},{JOINT_STATES}")
    finally:
        relay.close()
    assert ended.code == 0, ended.output
    stops = [line for line in ended.output.splitlines() if ": a stop stamped " in line]
    assert len(stops) == 1 and "from the commanded path (" in stops[0] and "no answer within" in stops[0], stops
    assert "(before its stamp)" in stops[0], stops
    assert ended.row is not None and (ended.row["pressed"], ended.row["goal_result"]) == ("true", "SUCCEEDED")
    assert_braked(ended)


@contextmanager
def relayed_states(roscore: Any, tmp_path: Path, fault: str, from_start: bool = False) -> Iterator[StateRelay]:
    """While inside: the arm's joint states relayed on RELAYED_STATES by a node of its own, `fault` injected on its
    inject() (bench.fault_state_relay)."""
    relay = StateRelay(dict(roscore.env), tmp_path / "state_relay.log", fault, from_start)
    try:
        yield relay
    finally:
        relay.close()


@pytest.mark.parametrize(
    "fault,said",
    [("six-positions", "positions, not covering"), ("nan", "non-finite position of panda_joint1")],
    ids=["six_positions", "nan"],
)
def test_a_malformed_joint_state_mid_approach_brakes_the_arm(
    roscore, ros_node, arm: Arm, tmp_path: Path, fault: str, said: str
) -> None:
    with relayed_states(roscore, tmp_path, fault) as states:
        ended = approach_with_fault(
            roscore, ros_node, arm, tmp_path, 24, lambda runner: states.inject(), f"{NS},{RELAYED_STATES}"
        )
    assert ended.code == 5, ended.output
    assert "the arm was stopped: a malformed joint state: " in ended.output and said in ended.output, ended.output
    assert_braked(ended)


@pytest.mark.parametrize("signum,step", [(signal.SIGUSR1, "+2.000"), (signal.SIGUSR2, "-2.000")])
def test_a_step_of_the_runners_wall_clock_mid_approach_brakes_the_arm(
    roscore, ros_node, arm: Arm, tmp_path: Path, signum: int, step: str
) -> None:
    ended = approach_with_fault(
        roscore, ros_node, arm, tmp_path, 25, lambda runner: os.kill(runner.pid, signum), stepped_clock=True
    )
    assert ended.code == 5, ended.output
    assert f"the arm was stopped: the wall clock stepped {step} s during the motion" in ended.output, ended.output
    assert_braked(ended)


def test_a_feed_gone_stale_while_braking_ends_the_session_with_the_arm_braked(
    roscore, ros_node, arm: Arm, tmp_path: Path
) -> None:
    with relayed_states(roscore, tmp_path, "silence") as states:

        def press_then_stale(runner: Any) -> None:
            type_line(runner, "s\n")
            time.sleep(0.05)  # the stop on its way: the feed ends as the arm brakes
            states.inject()

        ended = approach_with_fault(roscore, ros_node, arm, tmp_path, 26, press_then_stale, f"{NS},{RELAYED_STATES}")
    assert ended.code == 5, ended.output
    assert "while the approach was stopping: joint states stale" in ended.output, ended.output
    assert ended.row is not None and ended.row["safety_stop"].startswith("then joint states stale")
    assert_braked(ended)


def test_a_braking_the_controller_aborts_ends_the_session(roscore, ros_node, arm: Arm, tmp_path: Path) -> None:
    # The relay gives the braking replacement (the third goal) a path tolerance of 1 µrad: the stand-in aborts it as
    # it starts, its trajectory running on (as ros_control's does), and the runner ends the session.
    from sim.wire.control_types import control_types

    tolerance = control_types().joint_tolerance

    def tight(number: int, goal: Any) -> float:
        if number == 3:  # 1: the move to the path's start, 2: the approach, 3: the stop
            goal.goal.path_tolerance = [tolerance(name=name, position=1e-6) for name in ROBOT.joint_names]
        return 0.0

    relay = ControllerRelay(ros_node, tight)
    try:
        ended = approach_with_fault(
            roscore, ros_node, arm, tmp_path, 27, lambda runner: type_line(runner, "s\n"), f"{RELAY},{JOINT_STATES}"
        )
    finally:
        relay.close()
    assert relay.status(3) == ABORTED
    assert ended.code == 5, ended.output
    assert "the braking replacement ended ABORTED" in ended.output, ended.output
    assert_braked(ended)


def test_a_tracking_gap_mid_approach_brakes_the_arm(roscore, ros_node, arm: Arm, tmp_path: Path) -> None:
    # A tracker follows the participant's right hand at 60 Hz, at rest on the scene's hand, and loses it mid-approach.
    from geometry_msgs.msg import PoseStamped

    from sim.study.run.protocol import POSE_FRAME, POSE_TOPICS

    tracking, running = threading.Event(), threading.Event()
    tracking.set()
    running.set()
    tracker = ros_node.Publisher(POSE_TOPICS["right_hand"], PoseStamped, queue_size=10)
    place = SCENE.hand.top

    def track() -> None:
        while running.is_set():  # bounded: cleared in every case
            if tracking.is_set():
                pose = PoseStamped()
                pose.header.stamp = ros_node.Time.from_sec(time.time())
                pose.header.frame_id = POSE_FRAME
                pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = place
                pose.pose.orientation.w = 1.0
                tracker.publish(pose)
            time.sleep(1 / 60)

    thread = threading.Thread(target=track, name="tracker", daemon=True)
    thread.start()
    try:
        ended = approach_with_fault(roscore, ros_node, arm, tmp_path, 29, lambda runner: tracking.clear())
    finally:
        running.clear()
        thread.join(timeout=5)
        tracker.unregister()
    # the hand unseen may have come on at a reach's speed: its possible places grow until they would reach the arm
    # within the stop, or the gap passes its bound
    assert ended.code == 5, ended.output
    reason = ended.row["safety_stop"] if ended.row is not None else ""
    assert ", unseen 0." in reason or reason.startswith("the hand untracked for "), ended.output
    assert ended.row is not None and ended.row["hand_monitored"] == "tracked"
    assert_braked(ended)


def test_a_tracked_hand_rising_towards_the_arm_on_its_move_to_a_start_stops_the_move_before_the_floor(
    roscore, ros_node, arm: Arm, tmp_path: Path
) -> None:
    # A tracker follows the participant's right hand at 60 Hz, at rest on the scene's hand, 0.41 m under the arm at
    # home. As the arm sets off to the path's start, the hand rises towards it at 0.5 m/s by up to 0.38 m, which it
    # reaches while the move would still run: the move is monitored like an approach, the hand's closing speed against
    # the move's own braking, and stopped before the separation falls under the floor (0.05 m). The session ends
    # there (a stopped move has no trial to record).
    from geometry_msgs.msg import PoseStamped

    from sim.study.design.world import SceneWorld
    from sim.study.run.protocol import POSE_FRAME, POSE_TOPICS
    from sim.wire.contract import positions_by_name

    watch, floor, speed, rise = arm.watch, 0.05, 0.5, 0.38
    rises_from = [math.inf]  # wall time
    published: list[float] = []  # monotonic: when the tracker sent each pose, for a failure's message
    running = threading.Event()
    running.set()
    tracker = ros_node.Publisher(POSE_TOPICS["right_hand"], PoseStamped, queue_size=10)

    def risen(at: float) -> float:
        return min(max(at - rises_from[0], 0.0) * speed, rise)

    def track() -> None:
        while running.is_set():  # bounded: cleared in every case
            now = time.time()
            pose = PoseStamped()
            pose.header.stamp = ros_node.Time.from_sec(now)
            pose.header.frame_id = POSE_FRAME
            x, y, z = SCENE.hand.top
            pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = x, y, z + risen(now)
            pose.pose.orientation.w = 1.0
            tracker.publish(pose)
            published.append(time.monotonic())
            time.sleep(1 / 60)

    thread = threading.Thread(target=track, name="tracker", daemon=True)
    thread.start()
    executed = ExecutedWatch(ros_node, NS, arm.stop_trajectory_duration)
    plan = write_plan(tmp_path / "plan.yaml", 33, "reality", [trial(1, "reality", 1, "vertical", STANDOFF, SPEED)])
    home = watch.resting_positions()
    runner = start_runner(roscore, plan, tmp_path / "out", ["--link", "reality=franka_ros", "--floor", str(floor)])
    try:
        watch.wait((1, "to_start"), runner)
        rises_from[0] = time.time() + 0.3  # the move's goal starts START_FLOOR (0.25 s) or more after it is sent
        output, _ = runner.communicate(timeout=60)
        watch.resting_positions()
        extremes = executed.extremes(home, time.time())
    finally:
        kill_process(runner)
        executed.close()
        running.clear()
        thread.join(timeout=5)
        tracker.unregister()
    # (a gap in the tracker's own poses, its thread held up, makes the monitor take the hand at 2.0 m/s: S_p over 1 m)
    longest = max(np.diff(published), default=math.nan)
    assert runner.returncode == 5, output
    stopped = "the move to the path's start was stopped: separation " in output and "(S_p 0." in output
    assert stopped, f"{output}\nthe tracker's longest gap between poses: {1000 * longest:.1f} ms"
    assert extremes.acceleration <= 1.0 and extremes.jerk <= 1.0, extremes.describe()
    with watch.changed:
        states = list(watch.states)
    moving = [s for s in states if np.abs(s.velocity).max() > 1e-3 and s.header.stamp.to_sec() >= rises_from[0]]
    assert moving, "the arm did not move once the hand rose"
    with SceneWorld(ROBOT, SCENE) as world:  # the arm's distance to the hand where it had risen to
        separations = [
            world.hand_distance(positions_by_name(s.name, s.position, ROBOT.joint_names), np.array([0, 0, risen(t)]))
            for s, t in ((s, s.header.stamp.to_sec()) for s in moving)
        ]
    assert min(separations) >= floor, (min(separations), output)  # while the arm moved; the hand rose on after it
    assert risen(states[-1].header.stamp.to_sec()) == rise  # and it rose far enough to cross the floor had it not


def test_a_robot_clock_off_the_runners_at_connect_refuses_the_session_in_one_line(
    roscore, ros_node, arm: Arm, tmp_path: Path
) -> None:
    plan = write_plan(tmp_path / "plan.yaml", 30, "reality", [trial(1, "reality", 1, "vertical", STANDOFF, SPEED)])
    with relayed_states(roscore, tmp_path, "restamp", from_start=True):
        runner = start_runner(roscore, plan, tmp_path / "out", ["--link", f"reality={NS},{RELAYED_STATES}"])
        try:
            output, _ = runner.communicate(timeout=90)
        finally:
            kill_process(runner)
    assert runner.returncode == 4, output
    said = [line for line in output.splitlines() if "clock and this machine's disagree" in line]
    assert len(said) == 1 and "limit 0.05 s" in said[0], output
    assert float(said[0].split(" arrive ")[1].split(" s ")[0]) == pytest.approx(-0.5, abs=0.02)
    assert "Enter to start" not in output  # nothing moved


def test_a_robot_clock_that_steps_mid_approach_brakes_the_arm(roscore, ros_node, arm: Arm, tmp_path: Path) -> None:
    with relayed_states(roscore, tmp_path, "restamp") as states:
        ended = approach_with_fault(
            roscore, ros_node, arm, tmp_path, 31, lambda runner: states.inject(), f"{NS},{RELAYED_STATES}"
        )
    assert ended.code == 5, ended.output
    assert "the robot's clock and the runner's no longer agree" in ended.output, ended.output
    assert_braked(ended)


def test_a_sweep_of_presses_over_an_approach_is_executed_within_the_limits(
    roscore, ros_node, arm: Arm, tmp_path: Path
) -> None:
    # One press per trial, each later into its approach, from its slow start to its decelerating end: every stop is
    # executed (replayed at 1 kHz as the controller runs it) within the Panda's acceleration and jerk limits.
    watch = arm.watch
    executed = ExecutedWatch(ros_node, NS, arm.stop_trajectory_duration)
    presses = (0.1, 0.5, 0.9, 1.3, 1.7)  # s into the approach (2.3 s long at 0.2 m/s to 0.06 m)
    plan = [trial(k, "reality", 1, "vertical", STANDOFF, SPEED) for k in range(1, len(presses) + 1)]
    plan_path = write_plan(tmp_path / "plan.yaml", 32, "reality", plan)
    home = watch.resting_positions()
    runner = start_runner(roscore, plan_path, tmp_path / "out", ["--link", "reality=franka_ros"])
    try:
        for k, into in enumerate(presses, start=1):
            watch.wait((k, "moving"), runner)
            time.sleep(into)
            type_line(runner, "s\n")
            watch.wait((k, "distance"), runner)
            type_line(runner, "20 cm\n")
        output, _ = runner.communicate(timeout=60)
        watch.resting_positions()
        extremes = executed.extremes(home, time.time())
    finally:
        kill_process(runner)
        executed.close()
    assert runner.returncode == 0, output
    rows = read_csv(tmp_path / "out" / "participant_32.csv")
    assert [(row["pressed"], row["goal_result"]) for row in rows] == [("true", "SUCCEEDED")] * len(presses)
    assert extremes.acceleration <= 1.0 and extremes.jerk <= 1.0, extremes.describe()
