"""sim.study.analysis.equivalence: the verdict's three outcomes (and the fourth case, surely non-zero yet inside the
SESOI), statsmodels' paired TOST against two one-sided t-tests done by hand, and Bland–Altman's bias and limits."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from sim.study.analysis.equivalence import agreement, paired_tost, verdict
from sim.study.errors import StudyError


@pytest.mark.parametrize(
    "estimate, se, label, different, equivalent",
    [
        (0.001, 0.004, "equivalent", False, True),  # 90 % CI ± 0.0072 inside ±0.02
        (0.03, 0.004, "different", True, False),
        (0.005, 0.01, "inconclusive", False, False),  # wide: reaches past +0.02 and over 0
        (0.012, 0.002, "equivalent", True, True),  # non-zero, and smaller than what matters
        (-0.03, 0.004, "different", True, False),
    ],
)
def test_the_verdict_on_a_contrast(estimate, se, label, different, equivalent):
    v = verdict(estimate, se, 10, 0.02)
    assert (v.label, v.different, v.equivalent) == (label, different, equivalent)
    t95, t90 = stats.t.ppf(0.975, 10), stats.t.ppf(0.95, 10)
    assert v.ci95 == pytest.approx((estimate - t95 * se, estimate + t95 * se))
    assert v.ci90 == pytest.approx((estimate - t90 * se, estimate + t90 * se))
    assert ("smaller than the SESOI" in v.explanation) == (different and equivalent)


def test_the_verdicts_edges_follow_the_intervals():
    t90 = stats.t.ppf(0.95, 10)
    assert verdict(0.02 - t90 * 0.004 - 1e-9, 0.004, 10, 0.02).equivalent
    assert not verdict(0.02 - t90 * 0.004 + 1e-9, 0.004, 10, 0.02).equivalent


def test_the_paired_tost_is_two_one_sided_t_tests():
    rng = np.random.default_rng(2)
    reality = rng.normal(0.12, 0.03, 12)
    vr = reality + rng.normal(0.004, 0.01, 12)
    d = vr - reality
    se = d.std(ddof=1) / np.sqrt(12)
    by_hand = max(stats.t.sf((d.mean() + 0.02) / se, 11), stats.t.cdf((d.mean() - 0.02) / se, 11))
    tost = paired_tost(vr, reality, 0.02)
    assert tost.p == pytest.approx(by_hand, rel=1e-9) and tost.equivalent == (by_hand < 0.05)
    assert tost.n == 12 and tost.mean_difference == pytest.approx(d.mean())
    same = paired_tost(reality + 0.01, reality, 0.02)  # constant differences: t is undefined, the answer is not
    assert same.p == 0.0 and same.equivalent
    assert not paired_tost(reality + 0.03, reality, 0.02).equivalent


def test_bland_altman_gives_the_bias_and_the_limits_of_agreement():
    reality = np.array([0.10, 0.12, 0.14, 0.11, 0.13])
    vr = reality + np.array([0.01, -0.01, 0.02, 0.0, 0.005])
    a = agreement(vr, reality)
    d = vr - reality
    assert a.n == 5 and a.bias == pytest.approx(d.mean()) and a.sd == pytest.approx(d.std(ddof=1))
    assert (a.low, a.high) == pytest.approx((d.mean() - 1.96 * d.std(ddof=1), d.mean() + 1.96 * d.std(ddof=1)))


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: verdict(0.0, 0.01, 10, 0.0), "a SESOI must be a positive number"),
        (lambda: verdict(float("nan"), 0.01, 10, 0.02), "a verdict needs a finite estimate"),
        (lambda: paired_tost([0.1, 0.2], [0.1, 0.2], 0.02), "at least 3 finite pairs"),
        (lambda: agreement([0.1, 0.2, 0.3], [0.1, 0.2]), "at least 3 finite pairs"),
    ],
)
def test_bad_input_is_named(call, message):
    with pytest.raises(StudyError, match=message):
        call()
