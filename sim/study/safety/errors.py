"""The one error type of sim.study.safety."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["SafetyError"]


class SafetyError(StudyError):
    """A safety input that cannot be used: a margin outside (0, 1], a limit table that does not fit the robot, a
    braking asked of a path with no length."""
