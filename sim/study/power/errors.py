"""The one error type of sim.study.power."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["PowerError"]


class PowerError(StudyError):
    """A sample-size question that cannot be answered as asked."""
