"""The controller's timing contract (sim.control.stepper) against a recording controller node: what goes out, in which
order, and what a step waits for."""

from __future__ import annotations

import math
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

from sim.control.controller_node import ControllerError, ReceivedJointState
from sim.control.stepper import Pacing, Stepper


class RecordingEvent(threading.Event):
    """A stop event that records how long each wait on it was asked to last (the stepper's paced waits)."""

    def __init__(self) -> None:
        super().__init__()
        self.waited: list[float | None] = []

    def wait(self, timeout: float | None = None) -> bool:
        self.waited.append(timeout)
        return super().wait(timeout)


class RecordingNode:
    """Answers every wait with a joint state of the stamp asked for; records what was published, with when."""

    def __init__(self) -> None:
        self.stop = RecordingEvent()
        self.sent: list[tuple[str, float, float]] = []  # (what, stamp or clock, monotonic time)
        self.waits: list[tuple[float, float]] = []  # (stamp, timeout)
        self.states = SimpleNamespace(latest=None)

    def publish_clock(self, seconds: float) -> None:
        self.sent.append(("clock", seconds, time.monotonic()))

    def publish_command(self, stamp: float, positions: np.ndarray, velocities: np.ndarray) -> None:
        self.sent.append(("command", stamp, time.monotonic()))
        self.states.latest = ReceivedJointState(stamp - 0.02, np.asarray(positions, dtype=float))

    def state_or_fail(self, stamp: float, timeout: float, dt: float) -> ReceivedJointState:
        self.waits.append((stamp, timeout))
        return ReceivedJointState(0.0 if stamp == -math.inf else stamp, np.zeros(2))


def _sent(node: RecordingNode) -> list[tuple[str, float]]:
    return [(what, round(value, 9)) for what, value, _ in node.sent]


def test_lockstep_sends_the_command_then_the_clock_and_waits_for_that_stamp() -> None:
    node = RecordingNode()
    stepper = Stepper(node, Pacing(dt=0.02, step_timeout=3.0))  # type: ignore[arg-type]
    assert stepper.start(timeout=9.0) is not None
    stepper.hold()
    state = stepper.step(np.ones(2), np.zeros(2))
    assert state is not None and state.stamp == pytest.approx(0.04)
    assert _sent(node) == [("clock", 0.0), ("clock", 0.02), ("command", 0.04), ("clock", 0.04)]
    assert node.waits == [(0.0, 9.0), (0.02, 3.0), (0.04, 3.0)]
    assert stepper.clock == pytest.approx(0.04)


def test_lockstep_step_ends_stay_on_the_grid_over_a_long_run() -> None:
    node = RecordingNode()
    stepper = Stepper(node, Pacing(dt=0.02))  # type: ignore[arg-type]
    stepper.start(timeout=1.0)
    for _ in range(10_000):
        stepper.step(np.zeros(2), np.zeros(2))
    assert stepper.clock == 200.0  # exactly: each end is rounded to the nanosecond
    assert node.stop.waited == []  # without a lockstep rate, each step goes out as soon as the last is answered


def test_a_lockstep_rate_spaces_the_steps_and_a_late_answer_is_not_made_up_in_a_burst() -> None:
    node = RecordingNode()
    answer = node.state_or_fail
    late = {0.06}  # the answer to the step that ends at 0.06 s comes 0.2 s late

    def slow_answer(stamp: float, timeout: float, dt: float) -> ReceivedJointState:
        if round(stamp, 9) in late:
            time.sleep(0.2)
        return answer(stamp, timeout, dt)

    node.state_or_fail = slow_answer  # type: ignore[method-assign]
    stepper = Stepper(node, Pacing(dt=0.02, lockstep_rate=20.0))  # type: ignore[arg-type]
    stepper.start(timeout=1.0)
    stepper.hold()
    for _ in range(4):
        stepper.step(np.zeros(2), np.zeros(2))
    # each step's first message: no sooner than 1/20 s after the step before's, also after the late answer
    firsts = [at for what, value, at in node.sent if what == "command" or (what == "clock" and value == 0.02)]
    gaps = np.diff(firsts)
    assert len(firsts) == 5 and np.all(gaps >= 0.05 - 1e-4), gaps
    assert gaps[2] >= 0.2  # the step after the late answer waited for it, and the next kept its spacing
    assert _sent(node)[-2:] == [("command", 0.1), ("clock", 0.1)]


def test_realtime_sends_the_clock_of_the_step_start_and_the_command_for_its_end_paced_by_the_wall() -> None:
    node = RecordingNode()
    stepper = Stepper(node, Pacing(dt=0.02, realtime=True, time_scale=2.0))  # type: ignore[arg-type]
    assert stepper.start(timeout=1.0, need_state=False) is None
    assert node.waits == []
    assert stepper.step(np.zeros(2), np.zeros(2)) is not None  # the latest state, no wait
    for _ in range(4):
        stepper.step(np.zeros(2), np.zeros(2))
    stepper.finish()
    assert _sent(node) == [
        ("clock", 0.0),
        ("command", 0.02),
        ("clock", 0.02),
        ("command", 0.04),
        ("clock", 0.04),
        ("command", 0.06),
        ("clock", 0.06),
        ("command", 0.08),
        ("clock", 0.08),
        ("command", 0.1),
        ("clock", 0.1),
    ]
    assert node.waits == []
    started = node.sent[0][2]
    for what, value, at in node.sent:
        if what == "clock":  # /clock t goes out at wall time t / time_scale, never before
            assert at - started >= value / 2.0 - 1e-4


def test_realtime_start_takes_the_first_joint_state_of_any_stamp_after_the_clock_starts() -> None:
    node = RecordingNode()
    stepper = Stepper(node, Pacing(realtime=True))  # type: ignore[arg-type]
    assert stepper.start(timeout=4.0) is not None
    assert _sent(node) == [("clock", 0.0)] and node.waits == [(-math.inf, 4.0)]


def test_a_step_without_a_command_is_lockstep_only() -> None:
    stepper = Stepper(RecordingNode(), Pacing(realtime=True))  # type: ignore[arg-type]
    stepper.start(timeout=1.0)
    with pytest.raises(ControllerError, match="lockstep"):
        stepper.hold()


def test_a_stop_ends_a_paced_wait_with_an_error() -> None:
    node = RecordingNode()
    stepper = Stepper(node, Pacing(dt=5.0, realtime=True))  # type: ignore[arg-type]
    stepper.start(timeout=1.0, need_state=False)
    stepper.step(np.zeros(2), np.zeros(2))
    threading.Timer(0.05, node.stop.set).start()
    began = time.monotonic()
    with pytest.raises(ControllerError, match="interrupted"):
        stepper.step(np.zeros(2), np.zeros(2))  # due 5 s after the start
    assert time.monotonic() - began < 2.0


def test_now_is_the_clock_in_lockstep_and_the_scaled_wall_clock_in_real_time() -> None:
    lockstep = Stepper(RecordingNode(), Pacing(dt=0.02))  # type: ignore[arg-type]
    assert math.isnan(lockstep.now())  # before the start
    lockstep.start(timeout=1.0)
    lockstep.step(np.zeros(2), np.zeros(2))
    time.sleep(0.05)
    assert lockstep.now() == lockstep.clock == pytest.approx(0.02)  # stands still between steps
    paced = Stepper(RecordingNode(), Pacing(dt=0.02, realtime=True, time_scale=2.0))  # type: ignore[arg-type]
    paced.start(timeout=1.0, need_state=False)
    began = time.monotonic()
    time.sleep(0.1)
    before = paced.now()
    elapsed = time.monotonic() - began
    assert 2.0 * 0.1 <= before <= 2.0 * elapsed + 0.01 and paced.clock == 0.0  # no step taken, time goes on
