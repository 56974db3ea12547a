"""The stream link: the stand-in's. The runner owns /clock and commands one point per step on
`<robot>/arm_controller/command` (sim.control's ControllerNode and Stepper): in lockstep the engine steps once per
/clock value; with --realtime the steps are paced by the wall clock. A press streams the stop of sim.study.run.stop,
point by point."""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any

import numpy as np

from sim.control.controller_node import ControllerError, ControllerNode
from sim.control.scenarios import approach
from sim.control.stepper import Pacing, Stepper
from sim.robots import RobotSpec
from sim.study.run.links.base import AppliedPress, ApproachOutcome, TakePress
from sim.study.run.trial import TrialRun

__all__ = ["StreamLink"]


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

    @property
    def clock(self) -> float:
        """The controller's ROS time: the last step's end."""
        return self.stepper.clock

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
        self.positions = state.positions
        return state.positions

    def move_to(self, positions: np.ndarray) -> np.ndarray:
        to_start, speeds = approach(self.robot, self.positions, positions, self.pacing.dt)
        for k in range(1, len(to_start)):
            self.step(to_start[k], speeds[k])
        return self.positions

    def idle(self, seconds: float = 0.0) -> None:
        """Hold the target for `seconds` (at least one step)."""
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
        return ApproachOutcome(motion_start=start, press=applied)
