"""Tracking metrics of an achieved signal against its reference. Pure numpy, no I/O.

MAPE (the thesis's metric) explodes where the reference crosses zero, so it is computed only over samples where
|reference| exceeds a floor, and always reported beside WAPE, NRMSE and the max |error|, which have no such flaw.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.errors import SimError

__all__ = [
    "DEFAULT_MAPE_FLOOR",
    "HELD_STILL_SPREAD",
    "MetricsError",
    "TrackingMetrics",
    "mape_percent",
    "wape_percent",
    "nrmse_percent",
    "lag_seconds",
    "tracking_metrics",
    "per_joint_metrics",
    "resample",
    "mean_and_std",
]

DEFAULT_MAPE_FLOOR = 1e-3  # rad or m: samples with |reference| below this are left out of MAPE
# rad or m: a reference whose spread is below this is held still (float noise, not motion); its NRMSE (relative
# to the spread) and its lag are undefined, NaN rather than huge.
HELD_STILL_SPREAD = 1e-9


class MetricsError(SimError, ValueError):
    """Signals that cannot be compared (shapes, too few samples, no overlap in time)."""


@dataclass(frozen=True)
class TrackingMetrics:
    mape_percent: float  # mean |e| / |ref| over samples with |ref| > floor, in %
    wape_percent: float  # sum |e| / sum |ref|, in %
    nrmse_percent: float  # RMSE / (max(ref) - min(ref)), in %
    max_abs_error: float  # in the signal's unit
    lag_s: float  # how far achieved trails reference (cross-correlation), in s
    samples: int
    mape_samples: int  # samples that entered MAPE


def _pair(reference: np.ndarray, achieved: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    reference = np.asarray(reference, dtype=float)
    achieved = np.asarray(achieved, dtype=float)
    if reference.shape != achieved.shape or reference.ndim != 1:
        raise MetricsError(f"reference {reference.shape} and achieved {achieved.shape} must be equal 1-D shapes")
    if reference.size < 2:
        raise MetricsError(f"need at least 2 samples, got {reference.size}")
    return reference, achieved


def mape_percent(reference: np.ndarray, achieved: np.ndarray, floor: float = DEFAULT_MAPE_FLOOR) -> tuple[float, int]:
    reference, achieved = _pair(reference, achieved)
    used = np.abs(reference) > floor
    if not used.any():
        return float("nan"), 0
    return float(100.0 * np.mean(np.abs(achieved[used] - reference[used]) / np.abs(reference[used]))), int(used.sum())


def wape_percent(reference: np.ndarray, achieved: np.ndarray, floor: float = DEFAULT_MAPE_FLOOR) -> float:
    """sum |e| / sum |ref| in %; NaN for a reference whose mean magnitude is below `floor` (a joint held at zero,
    where float noise such as 1e-12 rad would otherwise make the ratio 1e10 %)."""
    reference, achieved = _pair(reference, achieved)
    magnitude = np.abs(reference)
    if np.mean(magnitude) < floor:
        return float("nan")
    return float(100.0 * np.sum(np.abs(achieved - reference)) / np.sum(magnitude))


def nrmse_percent(reference: np.ndarray, achieved: np.ndarray) -> float:
    reference, achieved = _pair(reference, achieved)
    spread = np.ptp(reference)
    rmse = np.sqrt(np.mean((achieved - reference) ** 2))
    return float("nan") if spread < HELD_STILL_SPREAD else float(100.0 * rmse / spread)


def lag_seconds(reference: np.ndarray, achieved: np.ndarray, dt: float, max_lag_s: float = 1.0) -> float:
    """Delay of `achieved` behind `reference` (positive = trails), from the cross-correlation of their increments.

    Increments rather than values: the peak is sharp even for slow signals. Parabolic interpolation around the
    peak gives sub-sample resolution. A reference held still (spread < HELD_STILL_SPREAD) has no defined lag: NaN.
    """
    reference, achieved = _pair(reference, achieved)
    d_ref = np.diff(reference)
    d_ach = np.diff(achieved)
    if np.ptp(reference) < HELD_STILL_SPREAD or not np.any(d_ach):
        return float("nan")
    max_lag = max(1, min(int(round(max_lag_s / dt)), (d_ref.size - 1) // 3))
    lags = np.arange(-max_lag, max_lag + 1)
    # The same window of the reference for every lag, so the scores are comparable and the peak unbiased.
    window = d_ref[max_lag : d_ref.size - max_lag]
    segments = [d_ach[max_lag + lag : d_ach.size - max_lag + lag] for lag in lags]
    # Normalised correlation: by Cauchy-Schwarz it peaks where the shapes coincide, whatever the amplitudes.
    scores = np.array([np.dot(window, seg) / (np.linalg.norm(seg) or 1.0) for seg in segments])
    best = int(np.argmax(scores))
    refined = float(lags[best])
    if 0 < best < len(lags) - 1:
        left, centre, right = scores[best - 1 : best + 2]
        curvature = left - 2 * centre + right
        if curvature < 0:
            refined += 0.5 * (left - right) / curvature
    return refined * dt


def tracking_metrics(
    reference: np.ndarray, achieved: np.ndarray, dt: float, mape_floor: float = DEFAULT_MAPE_FLOOR
) -> TrackingMetrics:
    """All metrics of one joint (or coordinate), for samples taken at a fixed interval `dt`."""
    reference, achieved = _pair(reference, achieved)
    mape, mape_samples = mape_percent(reference, achieved, mape_floor)
    return TrackingMetrics(
        mape_percent=mape,
        wape_percent=wape_percent(reference, achieved, mape_floor),
        nrmse_percent=nrmse_percent(reference, achieved),
        max_abs_error=float(np.max(np.abs(achieved - reference))),
        lag_s=lag_seconds(reference, achieved, dt),
        samples=int(reference.size),
        mape_samples=mape_samples,
    )


def per_joint_metrics(
    joint_names: Sequence[str], desired: np.ndarray, achieved: np.ndarray, dt: float, min_range: float = 0.0
) -> dict[str, TrackingMetrics]:
    """The metrics of each joint whose desired range exceeds `min_range` (0: every joint). `desired` and `achieved`
    are (samples, joints), taken at the same instants, `dt` apart."""
    return {
        name: tracking_metrics(desired[:, j], achieved[:, j], dt)
        for j, name in enumerate(joint_names)
        if min_range <= 0 or np.ptp(desired[:, j]) > min_range
    }


def resample(times: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Linear interpolation of (times, values[, columns]) at `at`, which must lie within `times`."""
    times = np.asarray(times, dtype=float)
    values = np.asarray(values, dtype=float)
    at = np.asarray(at, dtype=float)
    if times.size < 2 or np.any(np.diff(times) <= 0):
        raise MetricsError("sample times must be strictly increasing with at least 2 samples")
    if at.size and (at[0] < times[0] - 1e-9 or at[-1] > times[-1] + 1e-9):
        raise MetricsError(f"cannot resample at [{at[0]:g}, {at[-1]:g}] s outside [{times[0]:g}, {times[-1]:g}] s")
    if values.ndim == 1:
        return np.interp(at, times, values)
    return np.column_stack([np.interp(at, times, values[:, j]) for j in range(values.shape[1])])


def mean_and_std(values: list[float] | np.ndarray) -> tuple[float, float]:
    """Mean and sample standard deviation over trials (std 0 for a single trial), NaNs ignored."""
    array = np.asarray(values, dtype=float)
    array = array[np.isfinite(array)]
    if array.size == 0:
        return float("nan"), float("nan")
    return float(array.mean()), float(array.std(ddof=1)) if array.size > 1 else 0.0
