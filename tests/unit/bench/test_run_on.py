"""A stop's run-on bound (bench.run_on): the travel from the press to the stop's stamp, the tracking error twice
and the interpolation at the press, each as its figures give it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.run_on import RunOn, distribution, run_on_bound

TIMES = np.linspace(0.0, 2.0, 201)
SPEEDS = np.where(TIMES < 1.0, 0.2 * TIMES, 0.2)  # m/s: up to 0.2 by 1 s, then steady


def bound(**changes: float) -> float:
    figures = dict(press_time=1.5, latency=0.015, lead=0.025, tracking_error=0.0, joint_rate=2.0, acceleration=0.0)
    figures.update(changes)
    return run_on_bound(TIMES, SPEEDS, dof=7, state_interval=1 / 30, **figures)


def test_the_travel_until_the_stamp_is_the_fastest_speed_over_the_latency_and_the_lead() -> None:
    assert bound() == pytest.approx(0.2 * 0.040)
    assert bound(press_time=0.5) == pytest.approx(0.2 * 0.54 * 0.040, rel=1e-6)  # still speeding up: its end's
    assert bound(lead=0.225) == pytest.approx(0.2 * 0.240)  # a later stamp, a longer run-on allowed


def test_the_tracking_error_counts_at_the_press_and_at_rest_and_the_interpolation_once() -> None:
    tracked = bound(tracking_error=1e-3) - bound()
    assert tracked == pytest.approx(2 * math.sqrt(7) * 1e-3 / 2.0)
    assert bound(acceleration=1.0) - bound() == pytest.approx(1.0 / 30**2 / 8)


def test_figures_that_cannot_bound_are_refused() -> None:
    for bad in (dict(lead=math.nan), dict(latency=-0.01), dict(joint_rate=0.0)):
        with pytest.raises(ValueError, match="run-on's bound"):
            bound(**bad)


def test_the_distribution_names_the_least_margin() -> None:
    line = distribution([RunOn(0.004, 0.009), RunOn(0.006, 0.007), RunOn(0.002, 0.009)])
    assert "3 stops" in line and "median 4.0" in line and "max 6.0" in line
    assert "least margin 1.0 (6.0 of 7.0)" in line
    assert not RunOn(0.008, 0.007).within and distribution([]) == "run-on: no stop measured"
