"""The one error type of sim.study."""

from __future__ import annotations

from sim.errors import SimError

__all__ = ["StudyError"]


class StudyError(SimError, ValueError):
    """Bad study input: a scene, a path, a plan or a response that cannot be used. The message names the value."""
