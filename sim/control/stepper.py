"""The controller's side of the timing contract, once: fixed steps of dt, in lockstep or paced by the wall clock.

The commander and the study runner both step the robot through this.
  lockstep: a step publishes the command stamped t+dt, then /clock = t+dt, and waits for the engine's joint state
      stamped >= t+dt. The engine steps once per /clock value, so the run goes as fast as the engine does.
      With a lockstep_rate, a step goes out no sooner than 1 / rate s after the one before: bystanders that cannot
      hold up the run (a rosbag recorder, whose queue per topic is fixed) get that much time per step.
  realtime: the step that starts at controller time t is due at wall time t / time_scale from the start. It
      publishes /clock = t and the command stamped t+dt (the engine extrapolates along the velocity) and takes the
      latest joint state, with no waiting.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from sim.control.controller_node import ControllerError, ControllerNode, ReceivedJointState
from sim.wire.contract import STEP_S

__all__ = ["Pacing", "Stepper"]


@dataclass(frozen=True)
class Pacing:
    """How the controller steps: dt, lockstep or real time, and how long a lockstep answer may take."""

    dt: float = STEP_S
    realtime: bool = False
    time_scale: float = 1.0  # realtime: controller seconds per wall second (the engine needs the same)
    step_timeout: float = 5.0  # lockstep: the longest wait for the engine's answer to a step, in s
    lockstep_rate: float | None = None  # lockstep: at most this many steps per wall second (None: unpaced)


class Stepper:
    """Steps a robot through `node` as `pacing` says; `clock` is the controller's time (the last step's end)."""

    def __init__(self, node: ControllerNode, pacing: Pacing) -> None:
        self.node = node
        self.pacing = pacing
        self.clock = 0.0
        self._wall_start = 0.0
        self._last_step = 0.0  # monotonic: when the last lockstep step went out (lockstep_rate)
        self._started = False

    def start(self, timeout: float, need_state: bool = True) -> ReceivedJointState | None:
        """Publish /clock 0 and tell where the robot is (waited for at most `timeout` s).

        Lockstep: the engine anchors its step grid on /clock 0 and answers with its joint state stamped 0; only
        then may /clock move on (a later value seen first would become the anchor and the lockstep would stall).
        Realtime: the paced steps count from /clock 0; then comes the engine's first joint state (when
        `need_state`), of any stamp: an engine on its own wall clock may have published before, and one stepping
        on /clock answers this /clock 0.
        """
        self.clock = 0.0
        self._wall_start = self._last_step = time.monotonic()
        self._started = True
        self.node.publish_clock(0.0)
        if not self.pacing.realtime:
            return self.node.state_or_fail(0.0, timeout, self.pacing.dt)
        return self.node.state_or_fail(-math.inf, timeout, self.pacing.dt) if need_state else None

    def hold(self) -> ReceivedJointState:
        """Lockstep only: one step with no new command (the engine holds its target); the joint state after it."""
        if self.pacing.realtime:
            raise ControllerError("a step without a command is a lockstep step")
        end = self._next_end()
        self._keep_lockstep_rate()
        self.node.publish_clock(end)
        state = self.node.state_or_fail(end, self.pacing.step_timeout, self.pacing.dt)
        self.clock = end
        return state

    def step(self, positions: np.ndarray, velocities: np.ndarray) -> ReceivedJointState | None:
        """Command the target for the end of the next step and let the step happen.

        Lockstep: the engine's joint state stamped at the step's end (ControllerError when it does not come in time).
        Realtime: the latest joint state (None before the first one). ControllerError when stopped while waiting.
        """
        end = self._next_end()
        if not self.pacing.realtime:
            self._keep_lockstep_rate()
            self.node.publish_command(end, positions, velocities)
            self.node.publish_clock(end)
            state = self.node.state_or_fail(end, self.pacing.step_timeout, self.pacing.dt)
            self.clock = end
            return state
        self._wait_until(self.clock)
        if self.clock > 0:  # /clock 0 went out at the start
            self.node.publish_clock(self.clock)
        self.node.publish_command(end, positions, velocities)
        self.clock = end
        return self.node.states.latest

    def finish(self) -> None:
        """Realtime: at the last step's end, /clock reaches it (lockstep is there already)."""
        if self.pacing.realtime and self.clock > 0:
            self._wait_until(self.clock)
            self.node.publish_clock(self.clock)

    def now(self) -> float:
        """The controller's time now, from any thread (NaN before the start). Lockstep: the clock, which stands still
        between steps. Realtime: the wall clock's time since the start, scaled, which /clock follows step by step
        (each value is published when its time comes)."""
        if not self._started:
            return math.nan
        if not self.pacing.realtime:
            return self.clock
        return (time.monotonic() - self._wall_start) * self.pacing.time_scale

    def _next_end(self) -> float:
        return round(self.clock + self.pacing.dt, 9)

    def _keep_lockstep_rate(self) -> None:
        """Lockstep: wait until 1 / lockstep_rate s after the step before went out. From that step, not from the
        start: steps held up by a slow answer are not made up for in a burst faster than the rate."""
        if self.pacing.lockstep_rate is not None:
            self._wait_for(self._last_step + 1.0 / self.pacing.lockstep_rate)
            self._last_step = time.monotonic()

    def _wait_until(self, controller_time: float) -> None:
        self._wait_for(self._wall_start + controller_time / self.pacing.time_scale)

    def _wait_for(self, wall_time: float) -> None:
        """Until monotonic `wall_time`; ControllerError when stopped."""
        delay = wall_time - time.monotonic()
        if (delay > 0 and self.node.stop.wait(delay)) or self.node.stop.is_set():
            raise ControllerError("interrupted")
