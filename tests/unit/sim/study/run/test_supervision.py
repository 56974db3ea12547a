"""The supervision's rules, without ROS: each watchdog fires on its fault and not without it, the first in the order
is the reason, the separation's monitor is asked only while no earlier watchdog fired and no stop is in force, and
the watch of a motion ends at rest. The stream link's guard holds on an exit while its arm is commanded to move."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from sim.study.run.links.clock import SKEW_LIMIT, STEP_LIMIT
from sim.study.run.links.feed import FedState, FeedFault
from sim.study.run.links.joint_line import JointLine
from sim.study.run.links.stream import _Streamed
from sim.study.run.links.supervision import (
    POLL,
    RESULT_GRACE,
    LatestWatch,
    Look,
    Motion,
    Tolerances,
    Watchdogs,
    brakes_on_exit,
    stale,
    watched_to_rest,
)
from sim.study.safety.separation import SeparationMonitor, SeparationParameters, Verdict

TOLERANCES = Tolerances(stale_after=0.1, tracking=0.1, surface=0.005, floor=0.01)
SKEW = 0.002  # s: the joint states' offset at connect
NOW = 1000.0


def motion(start: float = NOW - 1.0) -> Motion:
    return Motion("the approach", JointLine(np.zeros(2), np.ones(2)), 1.0, 10.0, start, start + 2.0, start + 2.0)


def state(arrival: float = NOW - 0.01, offset: float = SKEW) -> FedState:
    return FedState(arrival - offset, arrival, np.zeros(2), np.zeros(2))


def look(**changes: Any) -> Look:
    """A look at a motion where nothing is wrong, but for `changes`."""
    calm = Look(
        now=NOW,
        latest=state(),
        faults=[],
        clock_step=0.0,
        least_offset=SKEW,
        tracking=0.01,
        surface_off=0.001,
        distance=0.2,
        hand_places=[],
        stop_lead=0.02,
        goal_failure="",
    )
    return dataclasses.replace(calm, **changes)


# each watchdog's fault, and the start of the reason it gives, in the order they are judged
FAULTS: list[tuple[str, dict[str, Any], str]] = [
    ("stale", {"latest": state(arrival=NOW - 0.2)}, "joint states stale: none for 0.200 s"),
    ("malformed", {"faults": [FeedFault(NOW - 0.5, "JointState with a non-finite velocity")]}, "a malformed joint"),
    ("clock step", {"clock_step": -2.0}, "the wall clock stepped -2.000 s"),
    ("clock ahead", {"latest": state(offset=SKEW - SKEW_LIMIT - 0.01)}, "the joint states arrive -0.058 s after"),
    ("tracking", {"tracking": 0.11}, "tracking error 0.1100 rad"),
    ("surface", {"surface_off": 0.006}, "the arm's distance to the hand 6.0 mm off"),
    ("floor", {"distance": 0.009}, "achieved distance to the hand 0.0090 m under the floor"),
    ("goal", {"goal_failure": "the controller ended the goal ABORTED (-4): path tolerance"}, "the controller ended"),
]


@pytest.mark.parametrize("name, fault, reason", FAULTS, ids=[name for name, _, _ in FAULTS])
def test_each_watchdog_fires_on_its_fault_and_not_without_it(name: str, fault: dict[str, Any], reason: str) -> None:
    watchdogs = Watchdogs(TOLERANCES, SKEW)
    assert watchdogs.reason(look(), motion()) == ""
    assert watchdogs.reason(look(**fault), motion()).startswith(reason)


def test_the_first_watchdog_in_the_order_is_the_reason() -> None:
    watchdogs = Watchdogs(TOLERANCES, SKEW)
    for k, (_, _, reason) in enumerate(FAULTS):
        faults: dict[str, Any] = {}
        for _, fault, _ in reversed(FAULTS[k:]):
            faults.update(fault)  # the earlier watchdog's fault wins a key two share (the latest state)
        assert watchdogs.reason(look(**faults), motion()).startswith(reason), reason


def test_no_state_at_all_is_a_stale_feed() -> None:
    assert stale(NOW, None, 0.1) == "joint states stale: none for inf s (limit 0.1 s)"
    assert stale(NOW, NOW - 0.099, 0.1) == "" and stale(NOW, NOW - 0.101, 0.1).startswith("joint states stale")
    assert Watchdogs(TOLERANCES, SKEW).reason(look(latest=None), motion()).startswith("joint states stale")


def test_a_feed_read_by_its_latest_state_is_stale_once_no_state_has_been_new_for_the_limit() -> None:
    first, second = object(), object()
    watch = LatestWatch(0.0)
    assert watch.took(first, 0.5, 1.0) == ""
    assert watch.took(first, 1.4, 1.0) == ""
    assert watch.took(first, 1.6, 1.0) == "joint states stale: none for 1.100 s (limit 1 s)"
    assert watch.took(second, 1.7, 1.0) == ""
    assert watch.took(second, 2.8, 1.0).startswith("joint states stale")
    watch.restart(10.0)  # a motion begins after a wait without steps: judged from now
    assert watch.took(second, 10.5, 1.0) == ""
    assert watch.took(second, 11.1, 1.0).startswith("joint states stale")


def test_a_step_of_the_wall_clock_within_its_limit_and_a_late_delivery_do_not_fire() -> None:
    watchdogs = Watchdogs(TOLERANCES, SKEW)
    assert watchdogs.reason(look(clock_step=STEP_LIMIT), motion()) == ""
    late = state(offset=SKEW + 0.1)  # delivered 100 ms late, while another of the last states came promptly
    assert watchdogs.reason(look(latest=late, least_offset=SKEW), motion()) == ""
    behind = watchdogs.reason(look(latest=late, least_offset=SKEW + SKEW_LIMIT + 0.01), motion())
    assert behind.startswith("the joint states arrive +0.062 s after their stamps, +0.002 s at connect")


def test_the_least_separation_is_kept_while_the_feed_is_fresh_whichever_watchdog_fires() -> None:
    watchdogs = Watchdogs(TOLERANCES, SKEW)
    moving = motion()
    watchdogs.reason(look(distance=0.15, tracking=1.0), moving)
    assert moving.least_separation == 0.15
    watchdogs.reason(look(distance=0.05, latest=state(arrival=NOW - 1.0)), moving)  # stale: not counted
    watchdogs.reason(look(distance=math.nan), moving)  # at rest: not judged
    assert moving.least_separation == 0.15


class Recorded(SeparationMonitor):
    """The monitor, its checks recorded and its verdict set by the test."""

    def __init__(self, brake: bool) -> None:
        super().__init__(SeparationParameters(floor=0.01, deceleration=1.0), tracked=True)
        self.brake = brake
        self.checks: list[tuple[float, float, float, float | None]] = []
        self.places: list[float] = []

    def hand_seen(self, stamp: float, position: np.ndarray) -> None:
        self.places.append(stamp)
        super().hand_seen(stamp, position)

    def check(
        self,
        now: float,
        separation: float,
        lead: float,
        plan_time: float | None = None,
        robot_speed: float = 0.0,
        path_speed: float = 0.0,
        path_acceleration: float = 0.0,
        remaining: float = math.inf,
        direction: np.ndarray | None = None,
    ) -> Verdict:
        self.checks.append((now, separation, lead, plan_time))
        verdict = super().check(now, separation, lead)
        return dataclasses.replace(verdict, brake=self.brake, reason="the hand closes" if self.brake else "")


def test_the_separation_monitor_sees_the_hand_and_brakes_with_a_reaction_of_the_stop_lead_and_the_next_check() -> None:
    watchdogs = Watchdogs(TOLERANCES, SKEW)
    moving = motion()
    moving.speed_scale = 0.5  # the rehearsal's half speed: the plan's seconds per wall second
    moving.monitor = monitor = Recorded(brake=False)
    places = [(NOW - 0.02, np.zeros(3)), (NOW - 0.01, np.zeros(3))]
    assert watchdogs.reason(look(hand_places=places), moving) == ""
    assert monitor.places == [NOW - 0.02, NOW - 0.01] and moving.hand_seen == NOW - 0.01
    assert monitor.checks == [(NOW, 0.2, pytest.approx((0.02 + POLL) * 0.5), pytest.approx(0.5))]
    monitor.brake = True
    later = NOW + 0.05  # a look 50 ms after the last: the next may be as late
    assert watchdogs.reason(look(now=later, latest=state(arrival=later)), moving) == "the hand closes"
    assert monitor.checks[-1][2] == pytest.approx((0.02 + 0.05) * 0.5)


def test_the_separation_monitor_is_not_asked_once_a_stop_is_in_force_or_an_earlier_watchdog_fired() -> None:
    watchdogs = Watchdogs(TOLERANCES, SKEW)
    moving = motion()
    moving.monitor = monitor = Recorded(brake=True)
    assert watchdogs.reason(look(tracking=1.0), moving).startswith("tracking error")
    moving.stopped = True
    assert watchdogs.reason(look(), moving) == ""
    assert monitor.checks == [] and math.isnan(moving.checked)


def test_a_motion_is_watched_until_it_rests_settle_s_past_its_end_or_the_result_grace() -> None:
    moving = motion()
    assert not watched_to_rest(moving.ends, moving, 0.5, done=True)
    assert watched_to_rest(moving.ends + 0.5, moving, 0.5, done=True)
    assert not watched_to_rest(moving.ends + 0.5, moving, 0.5, done=False)
    assert watched_to_rest(moving.ends + RESULT_GRACE, moving, 0.5, done=False)


class Stream:
    """What the stream's guard sees of its link: the last command and its hold."""

    name = "stream"

    def __init__(self, velocity: float) -> None:
        self._target = (np.ones(2), np.full(2, velocity))
        self.holds = 0

    def hold(self) -> None:
        self.holds += 1
        self._target = (self._target[0], np.zeros(2))


def test_the_streams_motion_holds_on_an_exit_while_commanded_to_move_and_not_once_ended_or_at_rest() -> None:
    link: Any = Stream(velocity=0.1)
    with pytest.raises(KeyboardInterrupt), brakes_on_exit(_Streamed(link, "the approach")):
        raise KeyboardInterrupt
    assert link.holds == 1 and not np.any(link._target[1])
    moving: Any = Stream(velocity=0.1)
    ended = _Streamed(moving, "the approach")
    with brakes_on_exit(ended):
        ended.ended = True
    resting: Any = Stream(velocity=0.0)
    with pytest.raises(RuntimeError), brakes_on_exit(_Streamed(resting, "the move to the path's start")):
        raise RuntimeError("no joint state")
    assert moving.holds == 0 and resting.holds == 0
