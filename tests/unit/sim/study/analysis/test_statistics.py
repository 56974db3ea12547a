"""sim.study.analysis.statistics against known data and scipy's own tests."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from sim.study.analysis.statistics import paired_comparison, ratio_summary
from sim.study.errors import StudyError


def test_a_known_shift_is_found_with_its_interval_and_effect_sizes():
    rng = np.random.default_rng(1)
    b = rng.uniform(0.05, 0.25, size=40)
    a = b - 0.02 + rng.normal(0.0, 0.01, size=40)
    result = paired_comparison(a, b)
    assert result.ci_low < -0.02 < result.ci_high and result.ci_high < 0
    assert result.t_p < 1e-6 and result.wilcoxon_p < 1e-6
    assert result.cohen_dz == pytest.approx(np.mean(a - b) / np.std(a - b, ddof=1))
    assert result.rank_biserial < -0.8  # nearly every difference negative
    assert result.t == pytest.approx(stats.ttest_rel(a, b).statistic)
    assert result.wilcoxon_w == pytest.approx(stats.wilcoxon(a - b).statistic)


def test_no_difference_is_not_significant():
    rng = np.random.default_rng(2)
    b = rng.uniform(size=30)
    a = b + rng.normal(0.0, 0.05, size=30)
    result = paired_comparison(a, b)
    assert result.t_p > 0.05 and result.ci_low < 0 < result.ci_high


def test_a_15_percent_underestimate_is_recovered_as_a_ratio():
    rng = np.random.default_rng(3)
    actual = np.tile([0.05, 0.1, 0.15, 0.2, 0.25], 12)
    perceived = 0.85 * actual * rng.lognormal(0.0, 0.05, size=actual.size)
    summary = ratio_summary(perceived, actual)
    assert summary.ci_low < 0.85 < summary.ci_high and summary.ci_high - summary.ci_low < 0.05


def test_identical_samples_and_constant_differences_are_handled():
    same = paired_comparison([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])
    assert same.mean_difference == 0.0 and same.t_p == 1.0 and same.wilcoxon_p == 1.0
    shifted = paired_comparison([2.0, 3.0, 4.0], [1.0, 2.0, 3.0])
    assert shifted.ci_low == shifted.ci_high == 1.0 and shifted.t_p == 0.0


@pytest.mark.parametrize(
    "a, b, message",
    [
        ([1.0], [2.0], "at least 2 pairs"),
        ([1.0, 2.0], [1.0], "equally long"),
        ([1.0, float("nan")], [1.0, 2.0], "finite"),
    ],
)
def test_bad_samples_are_named(a, b, message):
    with pytest.raises(StudyError, match=message):
        paired_comparison(a, b)
    with pytest.raises(StudyError, match="non-zero"):
        ratio_summary([1.0, 2.0], [0.0, 1.0])
