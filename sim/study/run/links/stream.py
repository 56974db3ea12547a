"""The stream link: the stand-in's. The runner owns /clock and commands one point per step on
`<robot>/arm_controller/command` (sim.control's ControllerNode and Stepper): in lockstep the engine steps once per
/clock value; with --realtime the steps are paced by the wall clock. A press streams the stop of sim.study.run.stop,
point by point.

Its supervision is sim.study.run.links.supervision's, for what applies to a stand-in with no arm near anyone:
- Every motion (an approach, a move to a path's start) runs inside `brakes_on_exit`: an exit with the arm still
  commanded to move (an error, Ctrl-C or SIGTERM, a return before the motion's last step) commands a hold where the
  arm was last commanded to be, at zero velocity, so the engine does not extrapolate the last command's velocity
  (it would, for 0.1 s at most). A step to rest: the stand-in is a simulation, and nothing more can be streamed.
- The stale feed: a step that finds no new joint state for the pacing's step_timeout s raises ControllerError. In
  lockstep a step waits that long for its answer and raises on its own; with --realtime a step takes the latest
  state without waiting, and this watchdog is what notices an engine that has gone quiet.
The other watchdogs are the real arm's (docs/safety.md): the stream has no goal to fail, no robot clock of its own,
and its hand is the scene's, in VR; the VR condition's stops are the participant's presses alone.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from sim.control.controller_node import ControllerError, ControllerNode
from sim.control.scenarios import approach
from sim.control.stepper import Pacing, Stepper
from sim.robots import RobotSpec
from sim.study.run.console import say
from sim.study.run.links.base import AppliedPress, ApproachOutcome, TakePress
from sim.study.run.links.hand import HandWatch
from sim.study.run.links.supervision import LatestWatch, brakes_on_exit
from sim.study.run.trial import TrialRun

__all__ = ["StreamLink"]


class _Streamed:
    """A motion of the stream as brakes_on_exit sees it: settled once its code has commanded its last step (or
    while the last command rests); its fail-safe commands a hold where the arm was last commanded to be."""

    def __init__(self, link: StreamLink, what: str) -> None:
        self.link, self.what = link, what
        self.ended = False  # the motion's code commanded its last step

    def settled(self) -> bool:
        return self.ended or not np.any(self.link._target[1])

    def fail_safe(self, why: str) -> None:
        """Never raises: it says what it could not do."""
        link = self.link
        try:
            say(f"{link.name}: {self.what} left ({why}): holding where last commanded")
            link.hold()
        except BaseException as error:  # noqa: BLE001 — the exit goes on; the observer must know
            say(f"{link.name}: could not hold after {self.what}: {type(error).__name__}: {error}")


class StreamLink(ControllerNode):
    name = "stream"

    def __init__(
        self, robot: RobotSpec, pacing: Pacing, stop: threading.Event, watched: Sequence[tuple[str, Any]] = ()
    ) -> None:
        super().__init__(robot, stop)
        self.pacing = pacing
        self.realtime = pacing.realtime
        self.stepper = Stepper(self, pacing)
        # publishers of the runner's whose links to the engine (or the endpoint) must be up before the session
        self.watched_publishers.extend(watched)
        self._target = (robot.home.copy(), np.zeros(robot.dof))
        self.positions = robot.home.copy()
        self._states = LatestWatch(time.monotonic())  # the joint states the steps take, on the monotonic clock

    @property
    def clock(self) -> float:
        """The controller's ROS time: the last step's end."""
        return self.stepper.clock

    @property
    def clock_offset(self) -> float:
        """NaN: the stream's clock is the runner's own (its /clock)."""
        return math.nan

    @property
    def target(self) -> np.ndarray:
        return self._target[0]

    def recorded_topics(self) -> list[str]:
        return [self.robot.command_topic, self.robot.joint_states_topic, "/clock"]

    def connect(self, timeout: float, recorder: str | None) -> str:
        return f"engine {self.wait_for_partner(timeout, [recorder] if recorder else [])}"

    def start(self, timeout: float) -> np.ndarray:
        """/clock 0 and the engine's answer (lockstep), or its first joint state (realtime): where the robot is."""
        state = self.stepper.start(timeout)
        if state is None:  # cannot happen: a state was asked for
            raise ControllerError(f"no {self.robot.joint_states_topic} message received")
        self._target = (state.positions.copy(), np.zeros(self.robot.dof))
        self.positions = state.positions
        return state.positions

    def now(self) -> float:
        return self.stepper.now()

    def step(self, positions: np.ndarray, velocities: np.ndarray) -> np.ndarray:
        """Command the target for the end of the next step and let the step happen; the achieved positions."""
        self._target = (positions, velocities)
        state = self.stepper.step(positions, velocities)
        if state is None:
            raise ControllerError(f"no {self.robot.joint_states_topic} message received")
        why = self._states.took(state, time.monotonic(), self.pacing.step_timeout)
        if why:
            raise ControllerError(f"{self.robot.joint_states_topic}: {why}")
        self.positions = state.positions
        return state.positions

    def hold(self) -> None:
        """Command the last commanded positions at zero velocity, stamped at the last step's end (no step)."""
        positions = self._target[0]
        self._target = (positions, np.zeros(self.robot.dof))
        self.publish_command(self.clock, positions, self._target[1])

    def _watch_from_now(self) -> None:
        """The stale feed is judged from now: between the runner's calls it may wait long without a step, and an
        engine on /clock need not publish meanwhile."""
        self._states.restart(time.monotonic())

    def _begin(self, what: str) -> _Streamed:
        """A motion begins, watched from now."""
        self._watch_from_now()
        return _Streamed(self, what)

    def move_to(self, positions: np.ndarray, hand: HandWatch | None = None) -> np.ndarray:
        """Rest to rest to `positions`; the hand is virtual (no arm near anyone), so `hand` is not watched."""
        to_start, speeds = approach(self.robot, self.positions, positions, self.pacing.dt)
        motion = self._begin("the move to the path's start")
        with brakes_on_exit(motion):
            for k in range(1, len(to_start)):
                self.step(to_start[k], speeds[k])
            motion.ended = True
        return self.positions

    def idle(self, seconds: float = 0.0) -> None:
        """Hold the target for `seconds` (at least one step)."""
        self._watch_from_now()
        for _ in range(max(1, round(seconds / self.pacing.dt))):
            self.step(self._target[0], np.zeros(self.robot.dof))

    def approach(self, run: TrialRun, take_press: TakePress, settle: float) -> ApproachOutcome:
        """Sample by sample from the clock at the call (the motion's start: its first step begins there); a press (its
        stamp, or its arrival when unstamped, never before the last sample commanded) switches to the stop."""
        dt = self.pacing.dt
        start = self.clock
        run.record_state(0.0, self.positions)
        settle_steps = int(round(settle / dt))
        applied: AppliedPress | None = None
        k = 0
        motion = self._begin("the approach")
        with brakes_on_exit(motion):
            while k < run.steps - 1 + settle_steps:
                k += 1
                if run.stopped is None:
                    press = take_press(start + k * dt)
                    if press is not None:
                        when = press.stamp if press.stamp > 0 else self.clock
                        at = max(when, start + (k - 1) * dt)
                        applied = AppliedPress(press.source, at - when, press.input_delay, press.arrival_delay)
                        run.press(at - start)
                target, velocity = run.target(k)
                self.step(target, velocity)
                run.record_state(k * dt, self.positions)
            motion.ended = True
        return ApproachOutcome(motion_start=start, press=applied)
