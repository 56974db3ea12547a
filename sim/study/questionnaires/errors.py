"""The one error type of sim.study.questionnaires."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["QuestionnaireError"]


class QuestionnaireError(StudyError):
    """An instrument that cannot be used (a malformed data file or item) or answers that cannot be scored: a
    missing, unknown or out-of-range answer. The message names the item and the value."""
