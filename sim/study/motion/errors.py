"""The one error type of sim.study.motion."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["MotionError"]


class MotionError(StudyError):
    """Motion that cannot be measured as given: a window that ends before it starts, a pose that is not a point."""
