"""The one percentile, held to numpy's default (linear interpolation between the closest ranks)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from measuring.errors import MeasuringError
from measuring.stats import percentile

finite = st.floats(min_value=-1e9, max_value=1e9, allow_nan=False)


@given(values=st.lists(finite, min_size=1, max_size=200), q=st.floats(min_value=0.0, max_value=100.0))
def test_it_is_numpys_percentile(values: list[float], q: float) -> None:
    assert percentile(values, q) == pytest.approx(float(np.percentile(values, q)), rel=1e-12, abs=1e-9)


@pytest.mark.parametrize("q", [0, 1, 25, 50, 90, 95, 99, 99.9, 100])
def test_the_quantiles_the_benches_print_match_numpy_exactly_on_timings(q: float) -> None:
    timings = [0.25 * ((index * 7919) % 1013) for index in range(1000)]  # unordered, with repeats
    assert percentile(timings, q) == float(np.percentile(timings, q))


def test_the_ends_and_the_middle() -> None:
    values = [5.0, 1.0, 4.0, 2.0, 3.0]
    assert (percentile(values, 0), percentile(values, 50), percentile(values, 100)) == (1.0, 3.0, 5.0)
    assert percentile([1.0, 2.0], 50) == 1.5  # between the two: the median of an even count
    assert percentile([1.0, 2.0, 3.0, 4.0], 99) == pytest.approx(3.97)
    assert percentile(iter([7.0]), 99) == 7.0  # any iterable, one value


@pytest.mark.parametrize("q", [-1.0, 100.5, math.nan])
def test_a_q_outside_0_to_100_is_refused(q: float) -> None:
    with pytest.raises(MeasuringError, match="0..100"):
        percentile([1.0, 2.0], q)


def test_no_values_is_refused() -> None:
    with pytest.raises(MeasuringError, match="no values"):
        percentile([], 50)
