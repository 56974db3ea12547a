"""The one error type of sim.study.participants."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["ParticipantError"]


class ParticipantError(StudyError):
    """A participant model or a simulated participant that cannot be used."""
