"""The one error type of sim.study.views."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["ViewError"]


class ViewError(StudyError):
    """A view that cannot be served: a port, a certificate, missing page libraries."""
