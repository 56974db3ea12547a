"""sim.control.scenarios.motion: the sample grid."""

from __future__ import annotations

from sim.control.scenarios import (
    sample_times,
)


def test_sample_times_are_exact_multiples():
    times = sample_times(40.0, 0.02)
    assert len(times) == 2001 and times[-1] == 2000 * 0.02
    assert len(sample_times(0.05, 0.02)) == 4  # rounded up to whole steps
