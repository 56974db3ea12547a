"""The one error type of sim.robots."""

from __future__ import annotations

from sim.errors import SimError

__all__ = ["RobotError"]


class RobotError(SimError, ValueError):
    """A robot that cannot be loaded: an unknown name, a missing or malformed URDF or YAML, an ambiguous or
    inconsistent description. The message names the file and the offending value."""
