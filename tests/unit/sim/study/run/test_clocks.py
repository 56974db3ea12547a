"""The session's clocks: a page's announcements judged against the limit, recorded per trial and per session, and the
robot's clock over an approach (sim.study.run.clocks, sim.study.run.links.clock)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from sim.study.errors import StudyError
from sim.study.run.clocks import (
    PAGE_CLOCK_LIMIT,
    ClockError,
    PageClock,
    PageClocks,
    page_clock_from_json,
    page_clock_to_json,
    write_session_clocks,
)
from sim.study.run.links.clock import RobotClockSpan


def page(offset: float = 12.0, round_trip: float = 0.004, applied: float | None = None, source: str = "vr_trigger"):
    return PageClock(source, offset, round_trip, offset if applied is None else applied, 3)


def test_an_announcement_round_trips_and_its_uncertainty_is_half_its_round_trip_plus_its_lag() -> None:
    clock = page(12.0, 0.006, 12.003)
    assert page_clock_from_json(page_clock_to_json(clock)) == clock
    assert clock.uncertainty == pytest.approx(0.003 + 0.003)


@pytest.mark.parametrize(
    "text",
    [
        "not json",
        '{"source": "vr_trigger", "offset": 1.0}',
        '{"source": "vr_trigger", "offset": NaN, "round_trip": 0.01, "applied": 1.0, "samples": 2}',
        '{"source": "", "offset": 1.0, "round_trip": 0.01, "applied": 1.0, "samples": 2}',
        '{"source": "vr_trigger", "offset": 1.0, "round_trip": -0.01, "applied": 1.0, "samples": 2}',
        '{"source": "vr_trigger", "offset": 1.0, "round_trip": 0.01, "applied": 1.0, "samples": 0}',
    ],
)
def test_a_malformed_announcement_is_refused_and_logged_not_kept(text: str) -> None:
    with pytest.raises(StudyError):
        page_clock_from_json(text)
    clocks, said = PageClocks(), []
    clocks.heard_json(text, said.append)
    assert len(said) == 1 and said[0].startswith("a page's clock was refused: ")
    assert all(math.isnan(x) for x in clocks.trial("vr_trigger"))


def test_a_page_within_the_limit_goes_on_and_one_beyond_it_refuses_in_one_line_naming_its_skew() -> None:
    clocks = PageClocks()
    clocks.heard(page(round_trip=0.004))
    clocks.heard(page(round_trip=2 * PAGE_CLOCK_LIMIT - 0.001))  # 19.5 ms: within
    assert clocks.check() == ""
    clocks.heard(page(round_trip=0.05))  # half of it 25 ms: beyond
    reason = clocks.check()
    assert reason.startswith("the vr_trigger page's clock cannot be trusted: its stamps may be off by 25.0 ms")
    assert "limit 20.0 ms" in reason and "\n" not in reason
    with pytest.raises(ClockError, match="limit 20.0 ms"):
        clocks.heard(page(round_trip=0.05))
        clocks.refuse()
    assert clocks.check() == ""  # each announcement judged once: the runner refused already


def test_a_clock_unsettled_as_it_stands_is_named_without_being_judged_until_it_settles() -> None:
    # what the runner waits on at go (in real time): each page whose latest announcement is beyond the limit
    clocks = PageClocks()
    assert clocks.unsettled() == ""  # no page: nothing to wait for
    clocks.heard(page(round_trip=0.060))
    clocks.heard(page(round_trip=0.004, source="button"))
    assert clocks.unsettled() == (
        "the vr_trigger page's stamps may be off by 30.0 ms (half its best round trip 30.0 ms, its applied offset "
        "0.0 ms off its estimate; limit 20.0 ms)"
    )
    assert clocks.unsettled() == clocks.unsettled()  # judges nothing: the check still refuses it
    assert clocks.check().startswith("the vr_trigger page's clock cannot be trusted: its stamps may be off by 30.0 ms")
    clocks.heard(page(round_trip=0.060))
    clocks.heard(page(round_trip=0.010))  # a quicker answer: settled
    assert clocks.unsettled() == "" and clocks.check() == ""
    clocks.heard(page(12.0, 0.004, 12.0 - 0.030, source="button"))  # a lagging applied offset counts too
    assert clocks.unsettled().startswith("the button page's stamps may be off by 32.0 ms")


def test_a_transient_settled_by_the_check_goes_on_and_stays_in_the_trials_worst_uncertainty() -> None:
    # a slow round trip and a slewing offset's lag (21 ms), then the page's clock as it stands: within
    clocks = PageClocks()
    clocks.heard(page(12.0, 0.004, 12.0 - 0.019))
    clocks.heard(page(12.0, 0.004, 12.0 - 0.001))
    assert clocks.check() == ""
    _, worst = clocks.trial("vr_trigger")
    assert worst == pytest.approx(0.021)


def test_an_applied_offset_lagging_its_estimate_counts_to_the_skew() -> None:
    clocks = PageClocks()
    clocks.heard(page(12.0, 0.004, 12.0 - 0.019))  # 2 + 19 ms
    assert "may be off by 21.0 ms" in clocks.check()


def test_a_step_between_estimates_beyond_their_round_trips_refuses_and_a_drift_within_them_does_not() -> None:
    clocks = PageClocks()
    clocks.approach_begins()  # steps count from the session's first approach on (the test below)
    clocks.heard(page(12.0, 0.010))
    clocks.heard(page(12.008, 0.010))  # 8 ms apart, within their half round trips (10 ms)
    assert clocks.check() == ""
    clocks.heard(page(12.040, 0.010))  # 32 ms from the last: 22 ms beyond their round trips
    reason = clocks.check()
    assert reason.startswith("the vr_trigger page's clock stepped 22.0 ms beyond its round trips"), reason
    # ROS time that steps every 20 ms (the runner's /clock in real time): an estimate may move by a step more
    stepping = PageClocks(quantum=0.02)
    stepping.approach_begins()
    stepping.heard(page(12.0, 0.001))
    stepping.heard(page(12.0205, 0.001))  # 20.5 ms apart: the pings caught /clock early in a step, then late
    stepping.heard(page(12.0, 0.001))
    assert stepping.check() == ""
    stepping.heard(page(12.045, 0.001))  # 45 ms: 24 ms beyond a step and the round trips
    assert "stepped 24.0 ms" in stepping.check()


def test_a_step_before_the_first_approach_refuses_nothing_and_one_from_its_estimate_on_does() -> None:
    # The button page's first estimate rode on the runner's /clock as it started, 80 ms stale (a two-page session on a
    # slow machine): its next estimate was 85 ms higher, and the session was refused at its first go, before any press
    # could count. A step from the estimate in force at the first go on still refuses.
    clocks = PageClocks()
    clocks.heard(page(12.0, 0.0094, source="button"))
    clocks.heard(page(12.085, 0.0039, source="button"))
    assert clocks.check() == ""
    clocks.heard(page(12.085, 0.0035, source="button"))  # heard between the check and the approach: in force at go
    clocks.approach_begins()
    assert clocks.check() == ""
    clocks.heard(page(12.135, 0.0035, source="button"))  # 50 ms from the one in force at go
    assert clocks.check().startswith("the button page's clock stepped 46.5 ms beyond its round trips")


def test_each_trial_records_the_conditions_page_its_offset_as_it_ended_and_its_worst_uncertainty() -> None:
    clocks = PageClocks()
    assert all(math.isnan(x) for x in clocks.trial("vr_trigger"))  # no page: NaN, never 0
    clocks.heard(page(12.0, 0.012))
    clocks.heard(page(12.001, 0.004, source="button"))
    assert clocks.trial("vr_trigger") == (12.0, pytest.approx(0.006))
    # the next trial: none heard during it, the one in force as it began counts
    assert clocks.trial("vr_trigger") == (12.0, pytest.approx(0.006))
    clocks.heard(page(12.002, 0.002))
    assert clocks.trial("vr_trigger") == (12.002, pytest.approx(0.006))  # the one in force at its start was worse
    assert clocks.trial("vr_trigger") == (12.002, pytest.approx(0.001))
    assert clocks.trial("button") == (12.001, pytest.approx(0.002))
    # a clock that settled at go (the arm held at the start meanwhile): the trial counts from the one in force at go
    clocks.heard(page(12.002, 0.060))
    clocks.heard(page(12.002, 0.002))
    clocks.approach_begins()
    clocks.heard(page(12.003, 0.004))
    assert clocks.trial("vr_trigger") == (12.003, pytest.approx(0.002))


def test_a_page_whose_condition_comes_later_counts_from_its_own_trials_go_not_the_sessions_start() -> None:
    # The button page was slow as the session began (a 197 ms round trip), then settled; the VR trials came first.
    # The reality trial's record is of its approach: its page's estimate at its go and since (before, it counted from
    # the session's start: 98.5 ms, beside two CPU burners, for a trial whose page was off by 0.5 ms throughout).
    clocks = PageClocks()
    clocks.heard(page(12.0, 0.197, source="button"))
    clocks.heard(page(12.1, 0.001, source="button"))
    for _ in range(2):  # two VR trials
        clocks.approach_begins()
        clocks.heard(page(12.1, 0.002))
        clocks.trial("vr_trigger")
    clocks.approach_begins()
    clocks.heard(page(12.1, 0.001, source="button"))
    assert clocks.trial("button") == (12.1, pytest.approx(0.0005))


def test_the_session_record_has_the_robots_offset_at_connect_and_each_pages_summary(tmp_path: Path) -> None:
    clocks = PageClocks()
    clocks.heard(page(12.0, 0.010))
    clocks.heard(page(12.009, 0.004))
    path = tmp_path / "clocks" / "participant_03.json"
    write_session_clocks(path, 3, {"franka_ros (/ns)": 0.0012, "stream": math.nan}, clocks)
    record = json.loads(path.read_text())
    assert record["robot_clock_offset_at_connect_s"] == {"franka_ros (/ns)": 0.0012, "stream": None}
    summary = record["pages"]["vr_trigger"]
    assert summary["announcements"] == 2 and summary["round_trip_least_s"] == 0.004
    assert summary["uncertainty_largest_s"] == pytest.approx(0.005)
    assert summary["step_largest_s"] == pytest.approx(0.002)  # 9 ms apart, 7 of them explained
    assert record["page_clock_limit_s"] == PAGE_CLOCK_LIMIT


def test_the_robots_clock_over_an_approach_places_a_press_on_its_clock_and_keeps_the_range_it_moved() -> None:
    span = RobotClockSpan(0.030)  # the robot's clock 30 ms behind: a press at runner time t is its t - 0.03
    assert span.on_robot_clock(100.0) == pytest.approx(99.97)
    assert math.isnan(span.on_robot_clock(math.nan))
    for offset in (0.031, None, 0.0295, math.nan):
        span.looked(offset)
    assert span.drift == pytest.approx(0.0015) and span.offset == 0.030
