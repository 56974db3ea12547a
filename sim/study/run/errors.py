"""The one error type of sim.study.run."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["RunError", "SafetyStopped"]


class RunError(StudyError):
    """A session that cannot go on: a bad trial status or answer, a record that cannot be written."""


class SafetyStopped(RunError):
    """The runner stopped the arm on its own (sim.study.run.links): the session ends (after that trial's record,
    when the stop came in its approach)."""
