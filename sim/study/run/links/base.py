"""What the runner asks of a robot link, and what a link tells of an approach. Pure."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Protocol  # typing's: a module-level alias is evaluated, and 3.8's abc is not generic

import numpy as np

from sim.study.motion.measures import Window
from sim.study.run.errors import RunError
from sim.study.run.links.hand import HandWatch
from sim.study.run.trial import TrialRun

__all__ = ["Press", "AppliedPress", "ApproachOutcome", "RobotLink", "SafetyStopped", "TakePress"]


class SafetyStopped(RunError):
    """The runner stopped the arm on its own: the session ends (after that trial's record, when the stop came in its
    approach; at once, when it came on the move to a path's start)."""


@dataclass(frozen=True)
class Press:
    stamp: float  # s on the link's clock (ROS time); 0: when it arrived
    source: str
    input_delay: float = math.nan  # s from the input's change to the stamp, as the client measured it; NaN: unsaid
    arrival: float = math.nan  # s on the link's clock when it reached the runner; NaN: not a message (the keyboard)

    @property
    def arrival_delay(self) -> float:
        """s from the stamp to the arrival; NaN for an unstamped press, whose time is its arrival by definition."""
        return self.arrival - self.stamp if self.stamp > 0 else math.nan


# the first press stamped at or before the given time on the link's clock (or unstamped), if one came
TakePress = Callable[[float], "Press | None"]


@dataclass(frozen=True)
class AppliedPress:
    source: str
    late: float  # s by which it came after its stamp had passed (applied at arrival)
    input_delay: float
    arrival_delay: float


@dataclass(frozen=True)
class ApproachOutcome:
    """What an approach did, beyond the TrialRun's own record. The trajectory controller's fields are NaN or empty
    on the stream, which has no goal and no replacement."""

    # s on the link's clock: when the arm began to move, the time every state and press of the approach is from (the
    # stream's clock at its first step; a trajectory controller's goal stamp, which it starts the arm at, a planning
    # and a start lead after the runner asked). NaN: a link that did not say, which no window can be placed on.
    motion_start: float = math.nan
    # the plan's seconds per second of the link's clock: the TrialRun's times (its states', its press's) are the
    # plan's, and the rehearsal runs the plan slower (--rehearsal-speed < 1)
    speed_scale: float = 1.0
    press: AppliedPress | None = None
    goal_result: str = ""  # the last goal's final status: SUCCEEDED, ABORTED, PREEMPTED, REJECTED...; "" stream
    error_code: int | None = None  # its result's control_msgs error code
    tracking_error: float = math.nan  # rad: the largest joint error of the achieved against the commanded path
    replacement_sent: float = math.nan  # s from the press (its applied time) to the braking replacement's sending
    braking_began: float = math.nan  # s from the press to the first joint state whose speed had fallen
    braking_planned: float = math.nan  # m along the path: the replacement's braking distance
    braking_achieved: float = math.nan  # m along the path: from the achieved state at the press to the achieved rest
    safety_stop: str = ""  # why the runner stopped the arm on its own ("" when it did not)
    start_lead: float = math.nan  # s the approach's goal was stamped ahead of its sending (sim.study.run.links.lead)
    stop_lead: float = math.nan  # s the (last) braking replacement was stamped ahead of its preparation; NaN: none
    hand_monitored: str = ""  # "tracked", "untracked" (the scene's hand taken at rest); "" on the stream
    least_separation_predicted: float = math.nan  # m (sim.study.safety.separation)
    least_separation: float = math.nan  # m, achieved, to the hand's live place while the arm moved
    # s: the robot's clock behind the runner's as the approach began (its joint states' least arrival minus stamp,
    # sim.study.run.links.clock), applied: motion_start and the press are on the runner's clock by it; and how far
    # that least offset moved during the approach. NaN on the stream, which has no clock of its own
    robot_clock_offset: float = math.nan
    robot_clock_drift: float = math.nan
    # m, likewise during the move to the path's start before the approach; NaN: no move (the arm was there), the stream
    move_least_separation: float = math.nan

    def window(self, end: float, press_time: float) -> Window:
        """The approach's motion window on the link's clock, placed on the arm's actual start: from it to `end`, the
        press `press_time` s of the plan after it (NaN: none). RunError when the link did not report its start."""
        if not math.isfinite(self.motion_start):
            raise RunError(f"the link did not report when its motion started (got {self.motion_start!r})")
        return Window(self.motion_start, end, self.motion_start + press_time / self.speed_scale)


class RobotLink(Protocol):
    """The robot side of the runner. `clock` is the link's time (s): the stream's ROS time, or the wall clock."""

    name: str
    realtime: bool

    @property
    def clock(self) -> float: ...

    @property
    def target(self) -> np.ndarray:
        """The joint positions last commanded to rest at."""
        ...

    @property
    def clock_offset(self) -> float:
        """s: the robot's clock behind the runner's as measured at connect; NaN: a link with no clock of its own."""
        ...

    def recorded_topics(self) -> list[str]: ...

    def connect(self, timeout: float, recorder: str | None) -> str:
        """Wait (at most `timeout` s) until the arm's side is there and linked; what it is, for the observer
        ("engine NODE", "trajectory controller NS ...")."""
        ...

    def start(self, timeout: float) -> np.ndarray:
        """Where the arm is, once its state comes."""
        ...

    def now(self) -> float:
        """The link's time from any thread (a press's arrival)."""
        ...

    def move_to(self, positions: np.ndarray, hand: HandWatch | None = None) -> np.ndarray:
        """Rest to rest to `positions`, supervised against the trial's `hand` (a real arm's link); where the arm
        ended."""
        ...

    def idle(self, seconds: float = 0.0) -> None:
        """Keep the arm at rest for `seconds` (the stream: at least one step; a controller holds on its own, and the
        link waits, watching its joint states)."""
        ...

    def approach(self, run: TrialRun, take_press: TakePress, settle: float) -> ApproachOutcome:
        """Run the planned approach from its start (the link's clock at the call), stopping on the first press;
        until `settle` s after the motion's end. Every achieved state goes to `run`."""
        ...

    def close(self) -> None: ...
