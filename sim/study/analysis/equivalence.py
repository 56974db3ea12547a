"""Is VR the same as reality? The verdict on a VR − reality contrast against the smallest effect size of interest
(SESOI) declared in the design, the paired TOST beside it, and the agreement (Bland–Altman). Pure logic, on scipy
and statsmodels.

  equivalent    the 90 % confidence interval lies inside ±SESOI (two one-sided tests at 5 % each);
  different     the 95 % confidence interval excludes 0;
  inconclusive  neither.
A contrast can be both, when it is surely non-zero yet surely smaller than the SESOI: it is then called equivalent,
as the SESOI says such a difference does not matter, and the verdict says it is non-zero.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from sim.study.analysis.errors import AnalysisError

__all__ = ["Verdict", "PairedTost", "Agreement", "verdict", "paired_tost", "agreement"]


@dataclass(frozen=True)
class Verdict:
    estimate: float
    ci95: tuple[float, float]
    ci90: tuple[float, float]
    sesoi: float
    different: bool  # the 95 % CI excludes 0
    equivalent: bool  # the 90 % CI lies inside ±SESOI

    @property
    def label(self) -> str:
        if self.equivalent:
            return "equivalent"
        return "different" if self.different else "inconclusive"

    @property
    def explanation(self) -> str:
        inside = f"the 90 % CI [{self.ci90[0]:+.4g}, {self.ci90[1]:+.4g}]"
        if self.equivalent:
            also = "; non-zero (the 95 % CI excludes 0), but smaller than the SESOI" if self.different else ""
            return f"{inside} lies inside ±{self.sesoi:g}{also}"
        if self.different:
            return f"the 95 % CI [{self.ci95[0]:+.4g}, {self.ci95[1]:+.4g}] excludes 0"
        return f"{inside} reaches beyond ±{self.sesoi:g} and the 95 % CI includes 0"


def _check_sesoi(sesoi: float) -> None:
    if not (math.isfinite(sesoi) and sesoi > 0):
        raise AnalysisError(f"a SESOI must be a positive number, got {sesoi!r}")


def verdict(estimate: float, se: float, df: float, sesoi: float) -> Verdict:
    """The verdict on a contrast with standard error `se` and `df` degrees of freedom (Student's t)."""
    _check_sesoi(sesoi)
    if not (math.isfinite(estimate) and math.isfinite(se) and se >= 0 and df > 0):
        raise AnalysisError(f"a verdict needs a finite estimate, se >= 0 and df > 0, got {estimate}, {se}, {df}")
    half95, half90 = (float(stats.t.ppf(q, df)) * se for q in (0.975, 0.95))
    ci95, ci90 = (estimate - half95, estimate + half95), (estimate - half90, estimate + half90)
    return Verdict(
        estimate=estimate,
        ci95=ci95,
        ci90=ci90,
        sesoi=sesoi,
        different=ci95[0] > 0 or ci95[1] < 0,
        equivalent=-sesoi < ci90[0] and ci90[1] < sesoi,
    )


@dataclass(frozen=True)
class PairedTost:
    """statsmodels' paired TOST on per-participant means: equivalent when p < 0.05."""

    n: int
    mean_difference: float
    p: float  # the larger of the two one-sided tests' p
    sesoi: float

    @property
    def equivalent(self) -> bool:
        return self.p < 0.05


def _pairs(vr: Sequence[float], reality: Sequence[float], what: str) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.asarray(vr, dtype=float), np.asarray(reality, dtype=float)
    if a.shape != b.shape or a.ndim != 1 or a.size < 3 or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise AnalysisError(f"{what} needs at least 3 finite pairs, got {a.tolist()} and {b.tolist()}")
    return a, b


def paired_tost(vr: Sequence[float], reality: Sequence[float], sesoi: float) -> PairedTost:
    from statsmodels.stats.weightstats import ttost_paired

    _check_sesoi(sesoi)
    a, b = _pairs(vr, reality, "a paired TOST")
    d = a - b
    if float(np.std(d)) <= 1e-12 * max(1.0, float(np.max(np.abs(d)))):  # equal differences: t is undefined
        p = 0.0 if abs(float(d[0])) < sesoi else 1.0
    else:
        p = float(ttost_paired(a, b, -sesoi, sesoi)[0])
    return PairedTost(int(a.size), float(d.mean()), p, sesoi)


@dataclass(frozen=True)
class Agreement:
    """Bland–Altman: the bias (mean VR − reality) and the 95 % limits of agreement (bias ± 1.96 SD)."""

    n: int
    bias: float
    sd: float
    low: float
    high: float


def agreement(vr: Sequence[float], reality: Sequence[float]) -> Agreement:
    a, b = _pairs(vr, reality, "Bland–Altman")
    d = a - b
    bias, sd = float(d.mean()), float(d.std(ddof=1))
    return Agreement(int(a.size), bias, sd, bias - 1.96 * sd, bias + 1.96 * sd)
