"""sim.control.horizon: the commander's schedule as windows for a trajectory controller, and the achieved joints read
back between joint states. The windows are checked against the stand-in's controller semantics
(sim.engine.trajectory_controller): replacing each other on time, they make the one trajectory of the schedule."""

from __future__ import annotations

import numpy as np
import pytest

from sim.control.horizon import HorizonError, Window, achieved_at, hermite_at, windows
from sim.engine.trajectory_controller import GoalTolerances, JointState, Point, TrajectoryController, TrajectoryMessage

DT = 0.02


def test_the_windows_hold_every_sample_due_after_they_go_out_and_overlap() -> None:
    plan = windows(100, DT, horizon=50, period=12, lead=5)
    assert plan[0] == Window(1, 50, -5 * DT) and plan[-1].last == 100
    for before, after in zip(plan, plan[1:]):
        assert after.send_at == pytest.approx(before.send_at + 12 * DT)
        assert after.first == max(1, round(after.send_at / DT) + 1)  # the first sample due after it goes out
        assert before.last * DT > after.send_at  # the one before has not run out when it goes out
        assert len(after.indices) == 50 or after.last == 100
    assert windows(10, DT, horizon=50, period=12, lead=5) == [Window(1, 10, -5 * DT)]  # shorter than a horizon


@pytest.mark.parametrize("horizon, period, lead", [(10, 9, 1), (10, 0, 1), (10, 5, 0)])
def test_a_horizon_that_cannot_keep_the_controller_fed_is_refused(horizon: int, period: int, lead: int) -> None:
    with pytest.raises(HorizonError):
        windows(100, DT, horizon, period, lead)


def test_windows_sent_on_time_make_the_schedules_one_trajectory_without_a_seam() -> None:
    t = np.arange(0, 121) * DT
    positions = np.column_stack([np.sin(t), 0.5 * t**2])
    velocities = np.column_stack([np.cos(t), t])
    zero = 100.0  # the wall time of sample 0

    def message(indices: range) -> TrajectoryMessage:
        points = [Point(i * DT, positions[i], velocities[i]) for i in indices]
        return TrajectoryMessage(zero, ("a", "b"), points)

    whole = TrajectoryController(("a", "b"), positions[0])
    whole.on_command(message(range(1, 121)), zero - 0.1, JointState.at_rest(positions[0]))
    windowed = TrajectoryController(("a", "b"), positions[0])
    checks = np.arange(0.0, 120 * DT, DT / 7)
    plan = windows(120, DT, horizon=25, period=6, lead=5)
    for k, window in enumerate(plan):
        sent = zero + window.send_at
        verdict = windowed.on_goal(f"g{k}", message(window.indices), GoalTolerances(), sent, windowed.desired_at(sent))
        assert verdict.accepted, verdict.text
        # up to the next window, the trajectory is the schedule's
        until = zero + plan[k + 1].send_at if k + 1 < len(plan) else zero + 120 * DT
        for c in checks[(zero + checks >= sent) & (zero + checks < until)]:
            np.testing.assert_allclose(windowed.desired_at(zero + c).positions, whole.desired_at(zero + c).positions)
            np.testing.assert_allclose(
                windowed.desired_at(zero + c).velocities, whole.desired_at(zero + c).velocities, atol=1e-9
            )
    np.testing.assert_allclose(windowed.desired_at(zero + 3.0).positions, positions[-1])


def test_hermite_reads_a_cubic_exactly_between_states_and_nothing_outside() -> None:
    stamps = np.array([0.0, 0.03, 0.05, 0.09])
    cubic = np.column_stack([stamps**3 - stamps, 2 * stamps**2])
    slope = np.column_stack([3 * stamps**2 - 1, 4 * stamps])
    at = np.array([-0.01, 0.0, 0.01, 0.04, 0.09, 0.1])
    got = hermite_at(stamps, cubic, slope, at)
    assert np.all(np.isnan(got[[0, 5]]))
    inside = at[1:5]
    np.testing.assert_allclose(got[1:5], np.column_stack([inside**3 - inside, 2 * inside**2]), atol=1e-15)
    with pytest.raises(HorizonError, match="increase strictly"):
        hermite_at(stamps[::-1], cubic, slope, at)


def test_achieved_leaves_out_stamps_that_go_back_and_is_linear_without_velocities() -> None:
    stamps = np.array([0.0, 0.02, 0.02, 0.01, 0.04])  # a repeated and a late stamp: left out
    positions = np.array([[0.0], [0.2], [9.0], [9.0], [0.4]])
    with_velocities = achieved_at(stamps, positions, np.full((5, 1), 10.0), np.array([0.01, 0.03, 0.05]))
    np.testing.assert_allclose(with_velocities[:2, 0], [0.1, 0.3])  # a line: its cubic is the line
    assert np.isnan(with_velocities[2, 0])
    without = achieved_at(stamps, positions, np.full((5, 1), np.nan), np.array([0.01, 0.03, -0.01]))
    np.testing.assert_allclose(without[:2, 0], [0.1, 0.3])
    assert np.isnan(without[2, 0])
    assert np.all(np.isnan(achieved_at(np.array([0.0]), positions[:1], positions[:1], np.array([0.0]))))
