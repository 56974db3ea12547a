"""Tracking metrics against hand-computed values."""

import numpy as np
import pytest

from sim.control.metrics import (
    MetricsError,
    lag_seconds,
    mape_percent,
    mean_and_std,
    nrmse_percent,
    resample,
    tracking_metrics,
    wape_percent,
)


def test_metrics_of_a_known_error():
    reference = np.array([1.0, 2.0, 4.0, -2.0])
    achieved = np.array([1.1, 2.0, 3.6, -2.0])
    mape, used = mape_percent(reference, achieved)
    assert used == 4
    assert mape == pytest.approx(100 * (0.1 / 1 + 0 + 0.4 / 4 + 0) / 4)
    assert wape_percent(reference, achieved) == pytest.approx(100 * 0.5 / 9)
    assert nrmse_percent(reference, achieved) == pytest.approx(100 * np.sqrt((0.01 + 0.16) / 4) / 6)


def test_mape_leaves_out_samples_near_zero_instead_of_exploding():
    reference = np.array([0.0, 1e-9, 1.0])
    achieved = np.array([0.01, 0.01, 1.01])
    mape, used = mape_percent(reference, achieved, floor=1e-3)
    assert used == 1
    assert mape == pytest.approx(1.0)
    assert mape_percent(np.zeros(3), np.ones(3))[0] != mape_percent(np.zeros(3), np.ones(3))[0]  # NaN


@pytest.mark.parametrize("held_at", [0.0, 1e-12, -3e-7])
def test_wape_of_a_joint_held_at_zero_is_undefined_not_huge(held_at):
    """Float noise around zero (a joint held still at 0 rad) once printed WAPE ~ 1e10 %."""
    reference = np.full(100, held_at)
    achieved = reference + 1e-6
    assert np.isnan(wape_percent(reference, achieved))
    assert np.isnan(tracking_metrics(reference, achieved, dt=0.02).wape_percent)


def test_wape_of_a_joint_held_away_from_zero_is_defined():
    reference = np.full(100, 0.5)
    assert wape_percent(reference, reference + 0.005) == pytest.approx(1.0)


def test_perfect_tracking_is_zero_error_and_zero_lag():
    t = np.arange(0, 10, 0.02)
    reference = np.sin(t)
    metrics = tracking_metrics(reference, reference.copy(), dt=0.02)
    assert metrics.mape_percent == 0 and metrics.wape_percent == 0 and metrics.max_abs_error == 0
    assert metrics.lag_s == pytest.approx(0.0, abs=0.02 / 100)


@pytest.mark.parametrize("delay_s", [0.02, 0.06, 0.2])
def test_lag_recovers_a_known_delay(delay_s):
    dt = 0.02
    t = np.arange(0, 20, dt)
    reference = np.sin(0.7 * t) + 0.3 * np.sin(2.3 * t)
    achieved = np.sin(0.7 * (t - delay_s)) + 0.3 * np.sin(2.3 * (t - delay_s))
    assert lag_seconds(reference, achieved, dt) == pytest.approx(delay_s, abs=dt / 10)
    assert lag_seconds(achieved, reference, dt) == pytest.approx(-delay_s, abs=dt / 10)


def test_constant_reference_has_no_lag():
    assert np.isnan(lag_seconds(np.ones(50), np.ones(50), 0.02))


def test_bad_shapes_are_named():
    with pytest.raises(MetricsError, match="equal 1-D shapes"):
        tracking_metrics(np.zeros(3), np.zeros(4), 0.02)


def test_resample_interpolates_columns_and_refuses_extrapolation():
    times = np.array([0.0, 1.0, 2.0])
    values = np.array([[0.0, 10.0], [1.0, 20.0], [4.0, 30.0]])
    np.testing.assert_allclose(resample(times, values, [0.5, 1.5]), [[0.5, 15.0], [2.5, 25.0]])
    with pytest.raises(MetricsError, match="outside"):
        resample(times, values, [2.5])


def test_mean_and_std_over_trials():
    assert mean_and_std([1.0, 3.0]) == pytest.approx((2.0, np.sqrt(2.0)))
    assert mean_and_std([5.0]) == (5.0, 0.0)


def test_a_reference_held_still_but_for_float_noise_has_no_nrmse_or_lag():
    reference = 0.5 + 1e-15 * np.sin(np.arange(200))  # a held joint, as float arithmetic delivers it
    achieved = reference + 1e-4 * np.cos(np.arange(200))
    metrics = tracking_metrics(reference, achieved, dt=0.02)
    assert np.isnan(metrics.nrmse_percent) and np.isnan(metrics.lag_s)
    assert metrics.max_abs_error == pytest.approx(1e-4, rel=1e-3)  # the other metrics stay defined
    assert metrics.wape_percent > 0
