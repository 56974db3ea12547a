"""The trajectory-controller link's clock: wall time (what a driver stamps with, and what goals are stamped on)
carried forward by the monotonic clock. No ROS.

The system's wall clock can step (an NTP correction, an operator's `date`): a stale feed measured on it would look
fresh for the step's length, a lead measured across it negative, and a stop stamped on it seconds off. The link
therefore reads the wall clock once, when it anchors, and counts on from there by the monotonic clock. Between
motions it anchors again (so the monotonic clock's drift from the wall clock, a few hundred ppm at most while NTP
slews, never builds up); during a motion, the wall clock's distance from the link's clock is the step, and one
beyond STEP_LIMIT stops the arm: the controller's clock and the runner's no longer agree on when a stop begins.

The robot's clock (its joint states' stamps) must agree with this one. The states' arrival minus their stamps is
the robot's clock behind this machine's plus each state's delivery; a delivery only ever adds, so the least of the
last states' offsets is the clock's (NTP's minimum filter), and a starved machine or a slow network that delays
some states does not move it. At connect the least of the first states must be within SKEW_LIMIT of zero; through
the session, within SKEW_LIMIT of what it was at connect: a state stamped ahead of that at once, the least of the
last states behind it (a robot clock stepped back).

Within those bounds the offset is applied, not only watched: the controller starts a goal at its stamp on the robot's
clock, so the arm begins to move at the goal's stamp plus the robot's offset on this machine's clock, where presses
and poses are stamped. An approach takes the least offset as it starts (RobotClockSpan) and places its start, its
press and its measures on this machine's clock by it; the joint states keep the robot's stamps, on which they and
the goal agree. The least offset counts the quickest delivery too (one-way, it cannot be told apart from the clock's
own offset): on a LAN some 0.1-1 ms, 0.2 mm at 0.2 m/s.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

__all__ = ["STEP_LIMIT", "SKEW_LIMIT", "LinkClock", "RobotClockSpan"]

STEP_LIMIT = 0.05  # s: a wall clock this far from the link's has stepped (drift is ~0.1 ms in the longest motion)
# s: the most the robot's joint states may arrive after (or before) their stamps, the least of 15: the robot PC's
# clock off this machine's by more (or a feed delayed by more) makes stamped goals and tracking wrong
SKEW_LIMIT = 0.05


class LinkClock:
    def __init__(self, wall: Callable[[], float] = time.time, monotonic: Callable[[], float] = time.monotonic) -> None:
        self._wall, self._monotonic = wall, monotonic
        self._offset = 0.0
        self.anchor()

    def anchor(self) -> None:
        """Take the wall clock's time as the link's from now on."""
        self._offset = self._wall() - self._monotonic()

    def __call__(self) -> float:
        """s: the wall time as the link keeps it."""
        return self._monotonic() + self._offset

    def step(self) -> float:
        """s the system's wall clock now is ahead of the link's (negative: behind)."""
        return self._wall() - self()


@dataclass
class RobotClockSpan:
    """The robot's clock over one motion: its offset as the motion began (s: the least arrival minus stamp of the last
    joint states, applied to the motion's times) and the range of the least offsets looked at during it."""

    offset: float
    low: float = field(init=False)
    high: float = field(init=False)

    def __post_init__(self) -> None:
        self.low = self.high = self.offset

    def looked(self, least_offset: float | None) -> None:
        if least_offset is not None and math.isfinite(least_offset):
            self.low, self.high = min(self.low, least_offset), max(self.high, least_offset)

    @property
    def drift(self) -> float:
        """s: how far the least offset moved during the motion (its range)."""
        return self.high - self.low

    def on_robot_clock(self, time_s: float) -> float:
        """A time on this machine's clock (a press) as the robot's clock tells it."""
        return time_s - self.offset
