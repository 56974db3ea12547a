"""The one error type of sim.study.design."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["DesignError"]


class DesignError(StudyError):
    """A scene, design, path or plan that cannot be used, or a combination that cannot be run."""
