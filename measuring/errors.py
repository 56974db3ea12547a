"""The one error type of the measuring package."""

from __future__ import annotations


class MeasuringError(Exception):
    """A measurement that cannot be made: no values to take a percentile of, a process gone from /proc."""
