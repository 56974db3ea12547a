"""The slow link's token bucket, on a clock given to it."""

from __future__ import annotations

import pytest

from measuring.link import TokenBucket


def test_a_burst_passes_at_once_and_the_rest_waits_for_the_rate() -> None:
    bucket = TokenBucket(rate=1000.0, burst=100, now=0.0)
    assert bucket.wait_for(100, 0.0) == 0.0
    bucket.take(100, 0.0)
    assert bucket.wait_for(50, 0.0) == pytest.approx(0.05)
    assert bucket.wait_for(50, 0.05) == pytest.approx(0.0)


def test_tokens_never_pile_up_past_the_burst() -> None:
    bucket = TokenBucket(rate=1000.0, burst=100, now=0.0)
    bucket.take(100, 0.0)
    assert bucket.wait_for(200, 60.0) == pytest.approx(0.1)  # an idle minute refilled 100, not 60,000
