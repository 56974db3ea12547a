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

Bytes the kernel holds that the endpoint's reader has not taken yet count as sent: on a starved machine a client's
__auth or frame can wait there past the grace, and the client is not to blame for that.

A connection too young to judge is safe, unless its address is a suspect: one of its connections was closed within
SUSPECT_S for not using its slot (to make room, or past a deadline). Without that, slow senders that reconnect at
once, evicting each other, keep every slot too young to judge, and a well-behaved newcomer finds none to free.
Proven non-users still go first; then young connections from suspect addresses, the longest connected first. A
newcomer from a suspect address makes no room at all (bridge.admission.gate): it is served where there is room, so
the slow senders stop churning each other and grow old enough to judge.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

__all__ = [
    "FRAME_GRACE_S",
    "MAX_SUSPECTS",
    "SILENT_GRACE_S",
    "SLOW_PACE",
    "SUSPECT_S",
    "SlotUse",
    "Suspects",
    "pace",
    "to_evict",
]

FRAME_GRACE_S = 1.0
SILENT_GRACE_S = 10.0
SLOW_PACE = 64 * 1024  # bytes per second
SUSPECT_S = 60.0
MAX_SUSPECTS = 4096  # addresses remembered at most (the oldest forgotten first)


@dataclass(frozen=True)
class SlotUse:
    """What one connection has done with its slot, as admission sees it."""

    connected_for_s: float
    frame_for_s: float | None  # how long the frame now partly received has been arriving; None: no such frame
    frame_bytes: int  # bytes of that frame received so far
    frames_completed: int
    authenticated: bool
    unread_bytes: int = 0  # bytes the kernel has received that the reader has not taken yet
    suspect: bool = False  # its address is a suspect (Suspects)


def pace(use: SlotUse) -> float | None:
    """Bytes per second at which the connection uses its slot, when it is not using it (see the module); None when
    it is using it, or is too young to tell."""
    if use.unread_bytes and use.frame_for_s is None:
        return None  # it has sent something the reader has not looked at yet: nothing to judge it by
    if not use.authenticated and use.connected_for_s > FRAME_GRACE_S:
        return 0.0
    if use.frames_completed == 0 and use.frame_for_s is None and use.connected_for_s > SILENT_GRACE_S:
        return 0.0
    if use.frame_for_s is not None and use.frame_for_s > FRAME_GRACE_S:
        rate = (use.frame_bytes + use.unread_bytes) / use.frame_for_s
        return rate if rate < SLOW_PACE else None
    return None


def to_evict(uses: Sequence[SlotUse]) -> int | None:
    """The index of the connection to close to make room: the lowest pace, and of those the longest connected; when
    none is proven not to use its slot, a young one from a suspect address, the longest connected; None otherwise."""
    candidates = []
    for index, use in enumerate(uses):
        rate = pace(use)
        if rate is not None:
            candidates.append((0, rate, -use.connected_for_s, index))
        elif use.suspect and _young(use):
            candidates.append((1, 0.0, -use.connected_for_s, index))
    return min(candidates)[3] if candidates else None


def _young(use: SlotUse) -> bool:
    """Too young to judge by what it has done: within the grace of its connection or of its frame."""
    if use.frame_for_s is not None:
        return use.frame_for_s <= FRAME_GRACE_S
    return use.frames_completed == 0 and use.connected_for_s <= SILENT_GRACE_S


class Suspects:
    """Addresses one of whose connections was closed for not using its slot, each remembered for SUSPECT_S
    (at most MAX_SUSPECTS of them). Times are monotonic seconds, given by the caller."""

    def __init__(self) -> None:
        self._since: dict[str, float] = {}  # insertion order: oldest first

    def note(self, host: str, now: float) -> None:
        self._since.pop(host, None)
        self._since[host] = now
        for old in [h for h, at in self._since.items() if now - at > SUSPECT_S]:
            del self._since[old]
        while len(self._since) > MAX_SUSPECTS:
            del self._since[next(iter(self._since))]

    def __len__(self) -> int:
        return len(self._since)

    def is_suspect(self, host: str, now: float) -> bool:
        at = self._since.get(host)
        return at is not None and now - at <= SUSPECT_S
