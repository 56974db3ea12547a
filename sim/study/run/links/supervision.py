"""The supervision of a link's motions, once for both links: the brake on every exit of a motion, and the watchdogs
that tell why the arm must be stopped now. No ROS, no actionlib: the links do the I/O (they read their feeds, ask
the controller, send goals) and bring here what one look at a motion sees.

The brake on every exit. A link runs each motion it commands inside `brakes_on_exit`. However the motion's code is
left (an exception of any kind, the observer's Ctrl-C or a SIGTERM turned into an interruption, a return with the
arm still moving), the arm is braked before the exit goes on. The trajectory link sends a braking replacement, from
the controller's desired state when it answers, else along the path it commanded, and watches it to rest; the
stream link commands a hold where it last commanded the arm to be. An exit with the arm at rest, or with a stop
already in force, sends nothing more. So a new path through a motion's code cannot leave an approach running on to
its stand-off: only the loss of the runner's process itself (SIGKILL, a power cut) can, and then the trajectory
controller ends the goal at the stand-off at rest, as the plan does (the stream's engine extrapolates its last
command for 0.1 s at most).

The watchdogs (`Watchdogs.reason`), in the order they are judged, the first that fires being the reason:
a stale feed, a malformed joint state, a step of the wall clock, the robot's clock off the runner's, the tracking
error in joint space, the achieved distance to the hand off the commanded path's, the achieved distance to the hand
under the floor, speed and separation monitoring (sim.study.safety.separation; while no stop is in force), and the
goal in force ending otherwise than by success. The trajectory link runs them all, on every look until the arm
rests; the stream link runs the stale feed's alone (`LatestWatch`), the one that applies to a stand-in with no arm
near anyone (docs/safety.md says which link runs which).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from sim.study.run.links.clock import SKEW_LIMIT, STEP_LIMIT, RobotClockSpan
from sim.study.run.links.feed import FedState, FeedFault
from sim.study.run.links.goals import CommandedPath
from sim.study.run.links.joint_line import JointLine
from sim.study.safety.braking import Braking, PathGeometry
from sim.study.safety.separation import SeparationMonitor

__all__ = [
    "POLL",
    "RESULT_GRACE",
    "LatestWatch",
    "Look",
    "Motion",
    "Stoppable",
    "Tolerances",
    "Watchdogs",
    "brakes_on_exit",
    "stale",
    "watched_to_rest",
]

POLL = 0.01  # s: the longest wait for a joint state between looks at the presses and the goal
RESULT_GRACE = 5.0  # s after a motion's planned end that the controller may take to end its goal


# --- the brake on every exit -------------------------------------------------------------------------------------
class Stoppable(Protocol):
    def settled(self) -> bool:
        """The motion has ended at rest, or a stop is in force: nothing more need be sent."""
        ...

    def fail_safe(self, why: str) -> None:
        """Brake now and watch the arm to rest; never raises (it says what it could not do)."""
        ...


@contextmanager
def brakes_on_exit(motion: Stoppable) -> Iterator[None]:
    try:
        yield
    except BaseException as error:  # every exit: KeyboardInterrupt and SystemExit too
        if not motion.settled():
            motion.fail_safe(f"{type(error).__name__}: {error}" if str(error) else type(error).__name__)
        raise
    if not motion.settled():
        motion.fail_safe("the motion's code ended with the arm still commanded to move")


# --- a motion ----------------------------------------------------------------------------------------------------
@dataclass
class Motion:
    """One goal's motion, supervised from its sending until the arm rests: what was commanded and the goal in force,
    the stop once one is in force, and why the link stopped it on its own."""

    what: str  # "the approach", "the move to the path's start"
    geometry: PathGeometry | JointLine
    deceleration: float  # along the geometry's parameter (m/s² on a path, rad/s² on a joint line)
    jerk: float
    start: float  # the link's clock: the goal's stamp
    ends: float  # when the motion is watched to: its goal's last point, or a later stop's
    moves_until: float  # when the last point of the goal in force is due: the arm rests from then
    commanded: CommandedPath = field(default_factory=CommandedPath)
    handles: list[Any] = field(default_factory=list)  # the motion's goal first, then each stop sent
    stopped: bool = False  # a stop is in force (a replacement sent, or none needed: the plan rests sooner)
    braking: Braking | None = None
    stop_lead: float = math.nan
    stop_sent: float = math.nan  # the link's clock when the (last) replacement went
    reason: str = ""  # why the link stopped the arm on its own
    after_stop: str = ""  # a fault seen once the stop was in force: the session ends
    monitor: SeparationMonitor | None = None  # the speed and separation monitoring (an approach's, a move's)
    hand_seen: float = -math.inf  # the stamp of the last tracked place of the hand given to the monitor
    least_separation: float = math.inf  # m: the least achieved separation to the hand's live place while moving
    checked: float = math.nan  # the link's clock at the monitor's last check
    robot_clock: RobotClockSpan | None = None  # an approach's robot clock: its offset applied, its range watched
    speed_scale: float = 1.0  # the plan's seconds per second of the link's clock (an approach's in the rehearsal)

    @property
    def handle(self) -> Any:
        return self.handles[-1]

    @property
    def replaced(self) -> bool:
        """The goal in force is a replacement (a stop), not the motion's own goal."""
        return len(self.handles) > 1


def watched_to_rest(now: float, motion: Motion, settle: float, done: bool) -> bool:
    """The supervision of `motion` may end: `settle` s past its end, with the goal in force `done`, or RESULT_GRACE
    s past its end whether the controller has ended the goal or not."""
    return now >= motion.ends + settle and (done or now >= motion.ends + RESULT_GRACE)


# --- the watchdogs -----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Tolerances:
    stale_after: float  # s without a good joint state
    tracking: float  # rad of joint error against the commanded path
    surface: float  # m: the achieved state's distance to the hand off the commanded state's
    floor: float  # m: the least achieved distance to the hand


@dataclass(frozen=True)
class Look:
    """What the link sees at one look at a motion."""

    now: float  # the link's clock
    latest: FedState | None  # the latest good joint state
    faults: Sequence[FeedFault]  # the malformed states that came during the motion (from stale_after before it)
    clock_step: float  # s the system's wall clock is ahead of the link's (sim.study.run.links.clock)
    least_offset: float | None  # s: the least arrival minus stamp of the last states (JointFeed.least_offset)
    tracking: float  # rad: the largest tracking error so far in the motion
    surface_off: float  # m: the latest state's distance to the hand off the commanded path's; NaN: not judged
    distance: float  # m: the latest state's distance to the hand's live place while the arm moves; NaN: not judged
    hand_places: Sequence[tuple[float, np.ndarray]]  # the tracked hand's places stamped after motion.hand_seen
    stop_lead: float  # s: the lead a stop would be stamped now
    goal_failure: str  # how the goal in force ended, if not by success ("" while it runs or when it succeeded)


def stale(now: float, arrival: float | None, limit: float) -> str:
    """Why the feed is stale ("" when it is not): its latest state came at `arrival` (None: none came), `limit` s or
    more before `now`."""
    if arrival is None or now - arrival > limit:
        age = math.inf if arrival is None else now - arrival
        return f"joint states stale: none for {age:.3f} s (limit {limit:g} s)"
    return ""


class LatestWatch:
    """The stale feed's watchdog for a link that takes its feed's latest state without noting when it came (the
    stream's, with --realtime): a state is new when it is another than the last taken, and the feed is stale once
    none has been new for the limit. `restart` judges it from now on (a motion begins after a wait without steps)."""

    def __init__(self, now: float) -> None:
        self.since = now  # when the last new state was taken, or the watch restarted
        self._last: object | None = None

    def restart(self, now: float) -> None:
        self.since = now

    def took(self, state: object, now: float, limit: float) -> str:
        """`state` taken at `now`: why the feed is stale ("" when it is not)."""
        if state is not self._last:
            self._last, self.since = state, now
        return stale(now, self.since, limit)


class Watchdogs:
    """The trajectory link's watchdogs for its motions: the tolerances and the joint states' offset at connect
    (`skew`, s: sim.study.run.links.clock). `reason` keeps on the motion what the separation's monitoring needs from
    one look to the next."""

    def __init__(self, tolerances: Tolerances, skew: float) -> None:
        self.tolerances, self.skew = tolerances, skew

    def reason(self, look: Look, motion: Motion) -> str:
        """Why the arm must be stopped now ("" when it need not): the first watchdog that fires."""
        latest = look.latest
        why = stale(look.now, None if latest is None else latest.arrival, self.tolerances.stale_after)
        if why or latest is None:
            return why
        if not math.isnan(look.distance):  # kept while the arm moves, whichever check stops it
            motion.least_separation = min(motion.least_separation, look.distance)
        if look.faults:
            return f"a malformed joint state: {look.faults[-1].reason}"
        if abs(look.clock_step) > STEP_LIMIT:
            return f"the wall clock stepped {look.clock_step:+.3f} s during the motion (limit {STEP_LIMIT:g} s)"
        skew = self.clocks_disagree(latest.arrival - latest.stamp, look.least_offset)
        if skew:
            return skew
        if look.tracking > self.tolerances.tracking:
            return f"tracking error {look.tracking:.4f} rad over the tolerance {self.tolerances.tracking:g} rad"
        if look.surface_off > self.tolerances.surface:
            return (
                f"the arm's distance to the hand {look.surface_off * 1e3:.1f} mm off its commanded path's (tolerance "
                f"{self.tolerances.surface * 1e3:g} mm)"
            )
        if not math.isnan(look.distance):
            if look.distance < self.tolerances.floor:
                floor = self.tolerances.floor
                return f"achieved distance to the hand {look.distance:.4f} m under the floor {floor:g} m"
            if motion.monitor is not None and not motion.stopped:
                separation = self.separation(look, motion, motion.monitor)
                if separation:
                    return separation
        return look.goal_failure

    def clocks_disagree(self, latest_offset: float, least_offset: float | None) -> str:
        """Why the robot's clock and the runner's no longer agree ("" while they do). A state stamped ahead of what
        its arrival allows (`latest_offset` under the offset at connect) is the clocks' doing at once: a delivery
        only delays. One stamped further behind may be a late delivery, so the least offset of the last states is
        judged."""
        for offset, beyond in ((latest_offset, -1.0), (least_offset, 1.0)):  # ahead, then behind
            if offset is not None and (offset - self.skew) * beyond > SKEW_LIMIT:
                return (
                    f"the joint states arrive {offset:+.3f} s after their stamps, {self.skew:+.3f} s at connect "
                    f"(limit {SKEW_LIMIT:g} s): the robot's clock and the runner's no longer agree"
                )
        return ""

    def separation(self, look: Look, motion: Motion, monitor: SeparationMonitor) -> str:
        """The speed and separation monitor's reason to brake now ("" when none): the hand's places tracked since the
        last look, the separation `look.distance`. The reaction T_r is the lead a stop would be stamped now, plus the
        time to the next check (the loop looks at least every POLL s; longer, if its last look was longer ago): a
        hand that closes between two checks is seen only at the second."""
        for stamp, place in look.hand_places:
            monitor.hand_seen(stamp, place)
            motion.hand_seen = stamp
        now = look.now
        interval = POLL if math.isnan(motion.checked) else max(POLL, now - motion.checked)
        motion.checked = now
        scale = motion.speed_scale
        verdict = monitor.check(
            now, look.distance, (look.stop_lead + interval) * scale, plan_time=(now - motion.start) * scale
        )
        return verdict.reason if verdict.brake else ""
