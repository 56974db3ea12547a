"""The one percentile of the tests and benchmarks.

`percentile(values, q)` is numpy's default (`numpy.percentile(values, q)`, method "linear"): the values sorted, the
q-th percentile sits at rank h = (n - 1) * q / 100, and between the two closest ranks it is interpolated linearly.
So p0 is the minimum, p100 the maximum and p50 the median; a p99 of 100 samples lies between the 99th and the
100th smallest. Pure Python, so the ROS nodes of the benchmarks need no numpy.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from measuring.errors import MeasuringError

__all__ = ["percentile"]


def percentile(values: Iterable[float], q: float) -> float:
    """The q-th percentile (q in 0..100) of `values`, as numpy.percentile(values, q) computes it."""
    ordered = sorted(values)
    if not ordered:
        raise MeasuringError(f"no values to take the {q:g}th percentile of")
    if not 0.0 <= q <= 100.0:  # also refuses NaN
        raise MeasuringError(f"a percentile is 0..100, not {q!r}")
    rank = (len(ordered) - 1) * (q / 100.0)  # numpy's order of operations, for the same last bit
    below = math.floor(rank)
    above = min(below + 1, len(ordered) - 1)
    fraction = rank - below
    low, high = ordered[below], ordered[above]
    # numpy's lerp: from the nearer end, so that p100 is exactly the maximum
    return low + (high - low) * fraction if fraction < 0.5 else high - (high - low) * (1.0 - fraction)
