"""The root of every error the endpoint raises on purpose: `except BridgeError` catches them all.

Each module's error class sits under it and keeps the built-in base it always had (ValueError for bad input,
OSError for the master's link, RuntimeError for a ROS-side failure), so existing handlers still catch it.
"""

from __future__ import annotations

__all__ = ["BridgeError", "RequestRefused"]


class BridgeError(Exception):
    """A failure the endpoint names: bad input from a client or the settings, or a part of the world that failed."""


class RequestRefused(BridgeError):
    """A request of one client that the endpoint refuses. The text goes back to that client as __error, with the
    srv_id of the service call it concerns, if any."""

    def __init__(self, text: str, srv_id: int | None = None) -> None:
        super().__init__(text)
        self.srv_id = srv_id
