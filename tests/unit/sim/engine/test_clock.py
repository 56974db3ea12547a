"""sim.engine.clock: the engine's one clock, both policies (auto-simulate and /clock-driven), stamps and the
failsafe."""

from __future__ import annotations

import numpy as np
import pytest

from sim.engine.clock import MIN_ADVANCE_S, ClockError, StepClock

DT = 0.02


# --- clock-driven (lockstep) ----------------------------------------------------------------------------------


def driven(value: float, clock: StepClock) -> tuple:
    clock.observe_clock(value, wall_s=0.0)
    return clock.advance()


def test_nothing_happens_before_the_first_clock_value() -> None:
    clock = StepClock(DT)
    assert clock.pending() == 0 and clock.advance().steps == 0 and clock.newest_clock is None


def test_the_clock_steps_as_it_advances_on_a_fixed_grid() -> None:
    clock = StepClock(DT)
    clock.observe_clock(10.0, wall_s=0.0)
    assert clock.pending() == 1  # "call advance": the first value anchors the grid
    first = clock.advance()
    assert first.steps == 0 and first.anchored_at == 10.0 and not first.resynced
    clock.observe_clock(10.05, wall_s=0.0)
    assert clock.pending() == 2 and clock.steps == 0  # pending changes nothing
    advance = clock.advance()
    np.testing.assert_allclose(advance.step_ends, [10.02, 10.04])
    assert advance.anchored_at is None and advance.jump == pytest.approx(0.05)
    assert driven(10.059, clock).steps == 0
    advance = driven(10.0599999999, clock)  # a stamp truncated to whole nanoseconds still reaches the grid point
    assert advance.steps == 1 and advance.step_ends[0] == pytest.approx(10.06)
    assert clock.time == pytest.approx(3 * DT)
    assert sum(driven(10.06 + k * 0.001, clock).steps for k in range(1, 1001)) == 50  # no drift


def test_a_big_clock_jump_resyncs_instead_of_catching_up() -> None:
    clock = StepClock(DT, max_jump=1.0)
    driven(0.0, clock)
    driven(0.5, clock)
    clock.observe_clock(30.0, wall_s=0.0)
    assert clock.pending() == 1
    advance = clock.advance()
    assert advance.resynced and advance.steps == 0 and advance.anchored_at == 30.0
    assert advance.jump == pytest.approx(29.5) and clock.resyncs == 1
    advance = driven(30.04, clock)  # resumed on a grid from 30.0
    assert advance.steps == 2 and not advance.resynced
    np.testing.assert_allclose(advance.step_ends, [30.02, 30.04])
    backwards = driven(5.0, clock)  # e.g. a bag restarted
    assert backwards.resynced and backwards.steps == 0 and clock.resyncs == 2
    assert driven(5.02, clock).steps == 1
    assert driven(5.02 + 0.99, clock).steps == 49  # below max_jump: caught up in full


# --- auto-simulate --------------------------------------------------------------------------------------------


def test_auto_simulate_follows_the_wall_clock_times_the_time_scale_on_its_own_time() -> None:
    clock = StepClock(DT, auto_simulate=True, time_scale=2.0, max_jump=1.0)
    assert clock.poll(100.0).steps == 0 and clock.next_step_wall() == pytest.approx(100.01)
    advance = clock.poll(100.1)  # 0.2 s of sim time at time_scale 2
    np.testing.assert_allclose(advance.step_ends, np.arange(1, 11) * DT)  # the engine's own time: steps x dt
    assert clock.time == pytest.approx(0.2) and clock.next_step_wall() == pytest.approx(100.11)
    stalled = clock.poll(105.1)  # the machine stalled for 5 s: no burst of 500 steps
    assert stalled.resynced and stalled.steps == 0 and clock.resyncs == 1
    assert clock.poll(105.11).steps == 1


def test_auto_simulate_stamps_follow_the_controllers_clock_once_seen() -> None:
    clock = StepClock(DT, auto_simulate=True, time_scale=4.0)
    clock.poll(100.0)
    clock.observe_clock(10.0, wall_s=100.001)
    advance = clock.poll(100.0105)  # two steps were due (at 100.005 and 100.010 wall); they run now
    # the last ends at the controller's time now, 10 + (100.0105 - 100.001) x 4; the one before dt earlier
    np.testing.assert_allclose(advance.step_ends, [10.018, 10.038])
    assert clock.controller_time(100.251) == pytest.approx(11.0)
    clock.observe_clock(10.1, wall_s=100.0152)  # a /clock came just after the next step fell due (100.015)
    (late,) = clock.poll(100.0158).step_ends  # the engine woke late: the step runs at 100.0158
    assert late == pytest.approx(10.1024) and late > 10.1  # never behind the /clock already seen
    clock.observe_clock(0.0, wall_s=100.3)  # a restarted controller: its newest value is the base
    assert clock.controller_time(100.4) == pytest.approx(0.4)


def test_a_late_clock_does_not_stamp_a_step_before_the_one_before_it() -> None:
    clock = StepClock(0.01, auto_simulate=True, max_jump=1.0)
    clock.poll(100.0)
    clock.observe_clock(10.0, wall_s=100.0)
    assert clock.poll(100.02).step_ends == pytest.approx((10.01, 10.02))
    clock.observe_clock(10.01, wall_s=100.025)  # sent at 100.01, 15 ms late: the estimate falls back by 15 ms
    (held,) = clock.poll(100.03).step_ends  # "now" is 10.015, before the last end (10.02)
    assert held == pytest.approx(10.02 + MIN_ADVANCE_S, abs=1e-12)
    followed = clock.poll(100.05).step_ends  # the estimate is past the last end again: followed
    assert followed == pytest.approx((10.025, 10.035))
    clock.observe_clock(0.0, wall_s=100.06)  # a restarted controller, far back: followed
    assert clock.poll(100.06).step_ends == pytest.approx((0.0,))


# --- checks ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"dt": 0}, "dt"),
        ({"dt": float("nan")}, "dt"),
        ({"dt": DT, "time_scale": -1}, "time_scale"),
        ({"dt": DT, "max_jump": 0}, "max_jump"),
    ],
)
def test_bad_settings_are_named(kwargs: dict, fragment: str) -> None:
    with pytest.raises(ClockError, match=fragment):
        StepClock(**kwargs)


def test_each_policy_is_driven_its_own_way() -> None:
    with pytest.raises(ClockError, match="clock-driven"):
        StepClock(DT).poll(0.0)
    with pytest.raises(ClockError, match="auto-simulated"):
        StepClock(DT, auto_simulate=True).advance()
    with pytest.raises(ClockError, match="finite"):
        StepClock(DT).observe_clock(float("nan"), wall_s=0.0)
