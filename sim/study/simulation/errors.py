"""The one error type of sim.study.simulation: a run that failed, as against bad input (a StudyError)."""

from __future__ import annotations

from sim.errors import SimError

__all__ = ["SimulationError"]


class SimulationError(SimError, RuntimeError):
    """A process of the simulated study failed (its log is named)."""
