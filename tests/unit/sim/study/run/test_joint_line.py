"""A move to a path's start as the separation monitor's plan: its own samples, their travel along the joint line and
the move's braking in the line's units."""

from __future__ import annotations

import numpy as np
import pytest

from sim.study.run.links.joint_line import MOVE_DECELERATION, MOVE_JERK, JointLine
from sim.study.safety.separation import SeparationMonitor, SeparationParameters, braking_travel

DT = 0.01


def quintic_move(line: JointLine, duration: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Samples every DT of a rest-to-rest quintic along the line: positions and velocities."""
    u = np.arange(int(round(duration / DT)) + 1) * DT / duration
    s = line.length * (10 * u**3 - 15 * u**4 + 6 * u**5)
    ds = line.length * (30 * u**2 - 60 * u**3 + 30 * u**4) / duration
    return line.joints(s), ds[:, None] * line.direction


def test_a_moves_travel_is_its_line_parameter_and_speed_at_its_samples_times() -> None:
    line = JointLine(np.zeros(3), np.array([0.6, -0.8, 0.0]))
    q, qd = quintic_move(line)
    distances = 0.40 - 0.02 * np.linspace(0.0, 1.0, len(q))
    travel = line.travel(q, qd, DT, distances)
    np.testing.assert_allclose(travel.times, np.arange(len(q)) * DT)
    assert travel.arc[0] == 0.0 and travel.arc[-1] == pytest.approx(line.length)
    assert np.all(np.diff(travel.arc) >= 0.0)
    np.testing.assert_allclose(travel.speeds, np.linalg.norm(qd, axis=1), atol=1e-12)  # forward along the line
    np.testing.assert_allclose(travel.distances, distances)


def test_the_move_is_braked_for_a_hand_rising_towards_it_and_not_for_a_hand_at_rest() -> None:
    # The arm 0.4 m over the hand, moving at about 0.9 rad/s mid-move: its braking at MOVE_DECELERATION takes ~0.9 s,
    # over which a hand rising at 0.5 m/s comes 0.45 m: brake now. A tracked hand at rest lets the move run.
    line = JointLine(np.zeros(3), np.array([0.6, -0.8, 0.0]))
    q, qd = quintic_move(line)
    travel = line.travel(q, qd, DT, np.full(len(q), 0.40))
    parameters = SeparationParameters(floor=0.05, deceleration=MOVE_DECELERATION, jerk=MOVE_JERK)
    speed = float(np.interp(1.0, travel.times, travel.speeds))
    _, stop_time = braking_travel(speed, 0.0, MOVE_DECELERATION, MOVE_JERK)
    assert stop_time > 0.8  # the move's own braking, in rad/s² along the line, not an approach's m/s²
    for rising, brakes in ((0.5, True), (0.0, False)):
        monitor = SeparationMonitor(parameters, tracked=True, plan=travel)
        for k in range(7):  # 60 Hz places over 0.1 s
            stamp = 0.9 + k / 60
            monitor.hand_seen(stamp, np.array([0.0, 0.0, rising * stamp]))
        verdict = monitor.check(stamp, 0.40 - rising * stamp, 0.03, plan_time=stamp)
        assert verdict.brake is brakes, verdict.reason
        if brakes:
            assert verdict.terms.hand == pytest.approx(0.5 * (0.03 + verdict.terms.stop_time), rel=0.01)
            assert verdict.terms.stop_time == pytest.approx(stop_time, abs=0.05)
