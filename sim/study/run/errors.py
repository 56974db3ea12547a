"""The one error type of sim.study.run."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["RunError"]


class RunError(StudyError):
    """A session that cannot go on: a bad trial status or answer, a record that cannot be written."""
