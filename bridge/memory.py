"""How the endpoint's memory is handled by the C library's allocator (glibc; elsewhere nothing is changed).

Large messages (camera images, point clouds) pass through the endpoint many times a second, each in a few buffers
of its size. Two things are wanted of the allocator, and glibc's defaults give neither:
- speed: a large buffer freed should be reused by the next message. By default glibc maps buffers above its mmap
  threshold from the system and unmaps them when freed, so the next one is fresh memory that the kernel zero-fills
  page by page (measured: the endpoint at 0.4-0.5 of rospy's throughput for 1-3 MB messages, 4x the CPU);
- memory that comes back: what a burst (or a fuzzing client) made the endpoint allocate should be returned once
  the burst is over. Buffers cut from the heap stay with the process after they are freed.

So: buffers up to the largest threshold glibc allows come from the heap and are reused (keep_large_buffers), the
heap is not shrunk while traffic flows, and freed memory is handed back when traffic has gone quiet
(give_back_free_memory, when QuietTrim says).
"""

from __future__ import annotations

import ctypes
import ctypes.util

__all__ = [
    "MMAP_THRESHOLD_BYTES",
    "TRIM_THRESHOLD_BYTES",
    "ARENAS",
    "QUIET_BYTES",
    "QuietTrim",
    "keep_large_buffers",
    "give_back_free_memory",
]

# glibc's largest mmap threshold on 64-bit systems (DEFAULT_MMAP_THRESHOLD_MAX): every buffer below it comes from
# the heap. Setting it also stops glibc from moving the threshold (and the trim threshold) by itself.
MMAP_THRESHOLD_BYTES = 32 * 1024 * 1024
# The heap's top is given back only when this much of it is free, so it never shrinks and grows again around every
# large message; give_back_free_memory returns the rest when traffic is quiet.
TRIM_THRESHOLD_BYTES = 256 * 1024 * 1024
# Traffic counts as quiet over a housekeeping period that moved fewer bytes than this (in and out, all clients):
# a 1 kHz JointState stream moves ~0.3 MB/s, one 30 Hz camera ~80 MB/s.
QUIET_BYTES = 2 * 1024 * 1024
# One heap (arena) for every thread. Freed memory can only be given back from whole free pages and, in the other
# arenas glibc would make for threads, not from their top, which malloc_trim leaves alone. Nothing is lost by it in
# a Python process: its threads allocate while holding the GIL, so they would rarely contend for the heap anyway.
ARENAS = 1
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD, _M_ARENA_MAX = -1, -3, -8  # mallopt's parameter numbers (glibc's malloc.h)


def _glibc() -> ctypes.CDLL | None:
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    except OSError:
        return None
    return libc if hasattr(libc, "mallopt") and hasattr(libc, "malloc_trim") else None


_LIBC = _glibc()


def keep_large_buffers() -> None:
    """Large buffers come from the heap and are reused (see the module); nothing where the C library is not glibc."""
    if _LIBC is not None:
        _LIBC.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
        _LIBC.mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)
        _LIBC.mallopt(_M_ARENA_MAX, ARENAS)


def give_back_free_memory() -> bool:
    """Return the free memory of every heap (arena) to the system (malloc_trim); whether any was returned."""
    return bool(_LIBC.malloc_trim(0)) if _LIBC is not None else False


class QuietTrim:
    """When to give free memory back: in a quiet housekeeping period (fewer than `quiet_bytes` moved), once at least
    `quiet_bytes` have been moved since memory was last given back. Pure: fed the endpoint's running total of bytes
    moved, once per period."""

    def __init__(self, quiet_bytes: int = QUIET_BYTES) -> None:
        self.quiet_bytes = quiet_bytes
        self._last_total = 0
        self._trimmed_at_total = 0  # the total when memory was last given back

    def due(self, total_bytes: int) -> bool:
        """Whether to give memory back now, the total of bytes moved so far being `total_bytes`."""
        moved, self._last_total = total_bytes - self._last_total, total_bytes
        if moved >= self.quiet_bytes or total_bytes - self._trimmed_at_total < self.quiet_bytes:
            return False
        self._trimmed_at_total = total_bytes
        return True
