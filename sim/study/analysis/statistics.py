"""The study's statistics: paired comparisons (VR vs reality, perceived vs actual) with effect sizes and confidence
intervals. Pure logic on scipy.stats.

For pairs (a_i, b_i), d_i = a_i − b_i:
  mean difference with its Student-t confidence interval;
  paired t-test (two-sided) and Cohen's d_z = mean(d) / sd(d);
  Wilcoxon signed-rank test (two-sided; zero differences dropped, as Wilcox's method; exact up to 50 pairs
  without tied magnitudes, else the normal approximation) and its matched-pairs
  rank-biserial correlation r = (W+ − W−) / (W+ + W−).
A ratio summary (perceived / actual) gives a bias as a fraction with its t interval: 0.85 is a 15 % underestimate.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from sim.study.analysis.errors import AnalysisError

__all__ = ["PairedComparison", "Estimate", "paired_comparison", "mean_estimate", "one_value", "ratio_summary"]


@dataclass(frozen=True)
class PairedComparison:
    n: int
    mean_a: float
    mean_b: float
    mean_difference: float  # mean of a − b
    ci_low: float
    ci_high: float
    t: float
    t_p: float
    cohen_dz: float
    wilcoxon_w: float  # the smaller of the signed-rank sums, as scipy reports it
    wilcoxon_p: float
    rank_biserial: float


@dataclass(frozen=True)
class Estimate:
    """A mean with its Student-t confidence interval (NaN for one value: a pilot's single participant)."""

    n: int
    mean: float
    ci_low: float
    ci_high: float


def _pairs(a: Sequence[float], b: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    a_arr, b_arr = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a_arr.shape != b_arr.shape or a_arr.ndim != 1:
        raise AnalysisError(f"paired samples need two equally long lists, got {a_arr.shape} and {b_arr.shape}")
    if a_arr.size < 2:
        raise AnalysisError(f"a paired comparison needs at least 2 pairs, got {a_arr.size}")
    if not (np.all(np.isfinite(a_arr)) and np.all(np.isfinite(b_arr))):
        raise AnalysisError("paired samples must be finite numbers")
    return a_arr, b_arr


def _sem(values: np.ndarray) -> float:
    """Standard error of the mean; 0 for values equal to within rounding (scipy would warn of cancellation)."""
    sd = float(np.std(values, ddof=1))
    if sd <= 1e-12 * max(1.0, float(np.max(np.abs(values)))):
        return 0.0
    return sd / math.sqrt(values.size)


def _t_interval(values: np.ndarray, confidence: float) -> tuple[float, float, float]:
    mean = float(np.mean(values))
    sem = _sem(values)
    if sem == 0.0:
        return mean, mean, mean
    half = float(stats.t.ppf(0.5 + confidence / 2.0, values.size - 1)) * sem
    return mean, mean - half, mean + half


def paired_comparison(a: Sequence[float], b: Sequence[float], confidence: float = 0.95) -> PairedComparison:
    a_arr, b_arr = _pairs(a, b)
    d = a_arr - b_arr
    mean, low, high = _t_interval(d, confidence)
    sem = _sem(d)
    if sem == 0.0:
        t, t_p, dz = (
            (math.copysign(math.inf, mean), 0.0, math.copysign(math.inf, mean)) if mean else (math.nan, 1.0, 0.0)
        )
    else:  # the paired t-test (scipy's ttest_rel), computed here so that equal differences need no special case
        t = mean / sem
        t_p = float(2.0 * stats.t.sf(abs(t), d.size - 1))
        dz = mean / float(np.std(d, ddof=1))
    nonzero = d[d != 0.0]
    if nonzero.size == 0:
        w, w_p, r = math.nan, 1.0, 0.0
    else:
        # exact for small samples without tied magnitudes, else the normal approximation (scipy would fall back
        # on a slow permutation test for ties)
        tied = np.unique(np.abs(nonzero)).size < nonzero.size
        wilcoxon = stats.wilcoxon(nonzero, method="approx" if tied or nonzero.size > 50 else "exact")
        ranks = stats.rankdata(np.abs(nonzero))
        plus, minus = float(ranks[nonzero > 0].sum()), float(ranks[nonzero < 0].sum())
        w, w_p, r = float(wilcoxon.statistic), float(wilcoxon.pvalue), (plus - minus) / (plus + minus)
    return PairedComparison(
        a_arr.size, float(a_arr.mean()), float(b_arr.mean()), mean, low, high, t, t_p, dz, w, w_p, r
    )


def ratio_summary(numerator: Sequence[float], denominator: Sequence[float], confidence: float = 0.95) -> Estimate:
    top, bottom = _pairs(numerator, denominator)
    if np.any(bottom == 0.0):
        raise AnalysisError("a ratio needs non-zero denominators")
    mean, low, high = _t_interval(top / bottom, confidence)
    return Estimate(top.size, mean, low, high)


def mean_estimate(values: Sequence[float], confidence: float = 0.95) -> Estimate:
    """The mean of `values` (e.g. one per participant) with its t interval."""
    array = np.asarray(values, dtype=float)
    if array.ndim != 1 or array.size < 2 or not np.all(np.isfinite(array)):
        raise AnalysisError(f"an estimate needs at least 2 finite values, got {array.tolist()}")
    mean, low, high = _t_interval(array, confidence)
    return Estimate(array.size, mean, low, high)


def one_value(value: float) -> Estimate:
    """One participant's mean, as a pilot has: no spread across participants, so no interval (NaN)."""
    return Estimate(1, float(value), math.nan, math.nan)
