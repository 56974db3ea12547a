"""What a trajectory controller executes, replayed from what it heard (sim.engine.executed): a smooth goal within
its limits at its own peak; a replacement bridged to late, and a cancel's hold, seen as what they are."""

from __future__ import annotations

import numpy as np
import pytest

from sim.engine.executed import Heard, executed_extremes
from sim.engine.trajectory_controller import Point, TrajectoryMessage

JOINTS = ("a", "b")
LIMITS = (10.0, 10.0)  # rad/s², rad/s³ alike, for reading ratios
REST = np.zeros(2)


def quintic(stamp: float, distance: float, duration: float, points: int = 50) -> TrajectoryMessage:
    """Joint a from 0 to `distance` rest to rest over `duration`, sampled with its velocities and accelerations."""
    t = np.linspace(duration / points, duration, points)
    s = t / duration
    q = distance * (10 * s**3 - 15 * s**4 + 6 * s**5)
    v = distance * (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    a = distance * (60 * s - 180 * s**2 + 120 * s**3) / duration**2
    return TrajectoryMessage(
        stamp,
        JOINTS,
        [Point(float(k), (float(p), 0.0), (float(w), 0.0), (float(c), 0.0)) for k, p, w, c in zip(t, q, v, a)],
    )


def test_a_smooth_goal_is_executed_at_its_own_peaks() -> None:
    heard = [Heard(100.0, "goal", "1", quintic(100.0, 1.0, 2.0))]
    executed = executed_extremes(heard, JOINTS, REST, 102.5, LIMITS, LIMITS)
    # a rest-to-rest quintic over T peaks at 5.7735·Δ/T² (1.443 rad/s²) and 60·Δ/T³ (7.5 rad/s³)
    assert executed.acceleration == pytest.approx(0.1443, rel=0.01) and executed.acceleration_joint == 1
    assert executed.jerk == pytest.approx(0.75, rel=0.02)


@pytest.mark.parametrize("at", [101.0, 101.5])  # the quintic's midpoint (no acceleration), and past it
def test_a_cancel_that_holds_at_once_is_a_step_the_replay_shows(at: float) -> None:
    heard = [Heard(100.0, "goal", "1", quintic(100.0, 1.0, 2.0)), Heard(at, "cancel", "1")]
    stopped = executed_extremes(heard, JOINTS, REST, at + 0.5, LIMITS, LIMITS)
    eased = executed_extremes(heard, JOINTS, REST, at + 1.0, LIMITS, LIMITS, stop_trajectory_duration=0.5)
    # the velocity's step at once (at the midpoint it is all there is: the desired acceleration is 0 on both sides)
    assert stopped.acceleration > 50 and stopped.acceleration_at == pytest.approx(at - 100.0, abs=0.002)
    assert eased.acceleration < 1 and eased.jerk < stopped.jerk / 100  # a controller that eases to rest over 0.5 s


def test_only_what_comes_from_since_is_counted_and_nothing_heard_is_an_error() -> None:
    heard = [Heard(100.0, "goal", "1", quintic(100.0, 1.0, 2.0))]
    late = executed_extremes(heard, JOINTS, REST, 102.5, LIMITS, LIMITS, since=101.99)
    assert late.acceleration < 0.02  # the quintic's last 10 ms, nearly at rest
    with pytest.raises(ValueError, match="no goal"):
        executed_extremes([], JOINTS, REST, 102.5, LIMITS, LIMITS)
