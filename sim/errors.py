"""The root of every error the simulator raises on purpose: `except SimError` catches them all.

Each part of sim/ has its own error class under it, which also keeps the built-in base it always had (ValueError for
bad input, RuntimeError for a failure of the world outside), so existing handlers still catch it.
"""

from __future__ import annotations

__all__ = ["SimError"]


class SimError(Exception):
    """A failure the simulator names: bad input, an impossible request, or a part of the system that failed."""
