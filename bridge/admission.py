"""Who makes room when the endpoint is full (pure).

A full endpoint does not turn a newcomer away while a connection holds a slot without using it: the one that sends
the least, for the longest, goes first. What counts as not using a slot:
- a frame that has been arriving for more than FRAME_GRACE_S at less than SLOW_PACE bytes a second (a slow-loris
  client sends a byte now and then; a camera image over Wi-Fi comes at megabytes a second; holding all 64 slots at
  SLOW_PACE would take 32 Mbit/s);
- no __auth yet, more than FRAME_GRACE_S after connecting (a client sends it first thing);
- not one frame in SILENT_GRACE_S since connecting (Unity's connector sends a keepalive every second it is idle;
  a client that never speaks the protocol holds its slot for nothing).
Connections that only wait, between whole frames, are using their slot and are never cut.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

__all__ = ["FRAME_GRACE_S", "SILENT_GRACE_S", "SLOW_PACE", "SlotUse", "pace", "to_evict"]

FRAME_GRACE_S = 1.0
SILENT_GRACE_S = 10.0
SLOW_PACE = 64 * 1024  # bytes per second


@dataclass(frozen=True)
class SlotUse:
    """What one connection has done with its slot, as admission sees it."""

    connected_for_s: float
    frame_for_s: float | None  # how long the frame now partly received has been arriving; None: no such frame
    frame_bytes: int  # bytes of that frame received so far
    frames_completed: int
    authenticated: bool


def pace(use: SlotUse) -> float | None:
    """Bytes per second at which the connection uses its slot, when it is not using it (see the module); None when
    it is using it, or is too young to tell."""
    if not use.authenticated and use.connected_for_s > FRAME_GRACE_S:
        return 0.0
    if use.frames_completed == 0 and use.frame_for_s is None and use.connected_for_s > SILENT_GRACE_S:
        return 0.0
    if use.frame_for_s is not None and use.frame_for_s > FRAME_GRACE_S:
        rate = use.frame_bytes / use.frame_for_s
        return rate if rate < SLOW_PACE else None
    return None


def to_evict(uses: Sequence[SlotUse]) -> int | None:
    """The index of the connection to close to make room: the lowest pace, and of those the longest connected;
    None when every connection uses its slot."""
    candidates = [
        (rate, -use.connected_for_s, index)
        for index, use in enumerate(uses)
        for rate in (pace(use),)
        if rate is not None
    ]
    return min(candidates)[2] if candidates else None
