"""The one error type of sim.study.analysis."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["AnalysisError"]


class AnalysisError(StudyError):
    """Records that cannot be analysed: missing columns, too few participants, a model that fails."""
