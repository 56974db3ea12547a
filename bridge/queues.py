"""Bounded frame queues: drop the oldest topic frame when full, never a service frame.

Used per client for frames going out to it, and per bridged topic for client payloads waiting for the ROS
publisher's pump thread (bridge.ros.RawPublisher).
"""
from __future__ import annotations

import threading
import time
from collections import deque
from typing import Dict, Optional, Tuple

__all__ = ["OutgoingQueue", "ByteBudget"]


class OutgoingQueue:
    """Frames waiting for one client's writer.

    Bounded by frame count and bytes. When full, the oldest *droppable* frame (a topic message) goes; service
    request/response pairs and errors are never dropped, so a slow reader loses stale samples, not answers.
    A frame may also carry a key (its topic) with a limit of its own: at most that many frames of the key wait, the
    oldest of them going first (a client's queue_size for a topic).
    """

    def __init__(self, max_frames: int, max_bytes: int) -> None:
        if max_frames < 1 or max_bytes < 1:
            raise ValueError(f"queue limits must be positive, got max_frames={max_frames}, max_bytes={max_bytes}")
        self.max_frames = max_frames
        self.max_bytes = max_bytes
        self._items: deque[Tuple[bytes, bool, Optional[str]]] = deque()  # (frame, droppable, key)
        self._key_counts: Dict[str, int] = {}  # frames queued per key
        self._bytes = 0
        self._kept_bytes = 0  # of frames that are never dropped (answers)
        self._filled_at = 0.0  # monotonic time the queue last went from empty to not empty
        self._closed = False
        self._dropped = 0
        lock = threading.Lock()
        self._not_empty = threading.Condition(lock)  # the consumer waits here
        self._not_full = threading.Condition(lock)  # producers that may wait for room (put's wait_s) wait here

    @property
    def dropped(self) -> int:
        """Frames dropped since the queue was made."""
        return self._dropped

    def __len__(self) -> int:
        return len(self._items)

    @property
    def queued_bytes(self) -> int:
        return self._bytes

    @property
    def kept_bytes(self) -> int:
        """Bytes of queued frames that are never dropped (answers): what a peer that reads nothing piles up; the
        producer must stop making them (the queue cannot drop them)."""
        return self._kept_bytes

    def oldest_age(self) -> Optional[float]:
        """How long the oldest queued frame has waited, at most (s); None when nothing is queued. Frames leave all
        at once (take_all), so the queue's oldest came when it was last empty."""
        return time.monotonic() - self._filled_at if self._items else None

    def put(self, data: bytes, droppable: bool = True, wait_s: float = 0.0, key: Optional[str] = None,
            key_limit: int = 0) -> int:
        """Queue `data`; returns how many older frames were dropped to make room for it (and, with a `key` and a
        positive `key_limit`, to keep at most that many frames of the key).

        With `wait_s`, a full queue is first given up to that long to make room (the consumer taking frames),
        so a producer that outpaces the consumer is slowed to its pace instead of losing frames.
        A queue is never emptied to make room, so one frame larger than `max_bytes` still goes through."""
        with self._not_full:
            if wait_s > 0.0:
                self._wait_for_room(len(data), wait_s)
            if self._closed:
                return 0
            dropped = self._append(data, droppable, key, key_limit)
            self._not_empty.notify()
            return dropped

    def put_many(self, items: list[bytes], wait_s: float = 0.0) -> int:
        """`put` (droppable) of each item in turn under one lock acquisition: what a client's reader hands over from
        one read. While the queue is full, each item waits up to `wait_s` for room, as with `put`; once one waited
        in vain, the rest drop oldest without waiting. Returns how many frames were dropped."""
        dropped = 0
        with self._not_full:
            for data in items:
                if wait_s > 0.0 and not self._has_room(len(data)):
                    self._not_empty.notify()  # the consumer takes what is queued while we wait
                    if not self._wait_for_room(len(data), wait_s):
                        wait_s = 0.0
                if self._closed:
                    break
                dropped += self._append(data, True)
            self._not_empty.notify()
        return dropped

    def _wait_for_room(self, size: int, wait_s: float) -> bool:
        """With the lock held: wait up to `wait_s` for room for `size` more bytes; whether there is room."""
        deadline = time.monotonic() + wait_s
        while not self._closed and not self._has_room(size):
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                return False
            self._not_full.wait(remaining)
        return True

    def _append(self, data: bytes, droppable: bool, key: Optional[str] = None, key_limit: int = 0) -> int:
        """With the lock held: queue `data`, dropping the oldest droppable frames while over a limit; how many."""
        dropped = 0
        if key is not None and key_limit > 0:  # only frames with a limit of their own are counted by key
            while self._key_counts.get(key, 0) >= key_limit and self._drop_oldest_of(key):
                dropped += 1
            self._key_counts[key] = self._key_counts.get(key, 0) + 1
        else:
            key = None
        if not self._items:
            self._filled_at = time.monotonic()
        self._items.append((data, droppable, key))
        self._bytes += len(data)
        if not droppable:
            self._kept_bytes += len(data)
        while (len(self._items) > self.max_frames or self._bytes > self.max_bytes) and len(self._items) > 1:
            if not self._drop_oldest_droppable():
                break
            dropped += 1
        return dropped

    def _has_room(self, size: int) -> bool:
        return len(self._items) < self.max_frames and (not self._items or self._bytes + size <= self.max_bytes)

    def _drop_oldest_droppable(self) -> bool:
        if self._items[0][1]:  # the usual case, and the cheap one
            self._forget(self._items.popleft())
            return True
        index = next((i for i, item in enumerate(self._items) if item[1]), None)
        if index is None:
            return False
        self._drop_at(index)
        return True

    def _drop_oldest_of(self, key: str) -> bool:
        index = next((i for i, item in enumerate(self._items) if item[2] == key), None)
        if index is None:
            return False
        self._drop_at(index)
        return True

    def _drop_at(self, index: int) -> None:
        item = self._items[index]
        del self._items[index]
        self._forget(item)

    def _forget(self, item: Tuple[bytes, bool, Optional[str]]) -> None:
        """Account for a dropped frame."""
        self._bytes -= len(item[0])
        self._dropped += 1
        if item[2] is not None:
            self._key_counts[item[2]] -= 1

    def take_all(self, timeout: float | None = None) -> list[bytes] | None:
        """Everything queued (waiting up to `timeout` for something); [] on timeout; None once closed and empty."""
        with self._not_empty:
            if not self._items and not self._closed:
                self._not_empty.wait(timeout)
            if not self._items:
                return None if self._closed else []
            items = [item[0] for item in self._items]
            self._items.clear()
            self._key_counts.clear()
            self._bytes = self._kept_bytes = 0
            self._not_full.notify_all()
            return items

    def wait(self, timeout: float | None = None) -> bool:
        """Until something is queued (True) or `timeout` passed (True, maybe empty); False once closed and empty."""
        with self._not_empty:
            if not self._items and not self._closed:
                self._not_empty.wait(timeout)
            return bool(self._items) or not self._closed

    def close(self, discard: bool = False) -> None:
        """No more puts; the writer drains what is queued (unless `discard`) and then gets None."""
        with self._not_empty:
            self._closed = True
            if discard:
                self._items.clear()
                self._key_counts.clear()
                self._bytes = self._kept_bytes = 0
            self._not_empty.notify_all()
            self._not_full.notify_all()


class ByteBudget:
    """Bytes that many holders share under one limit (e.g. partly received frames across all clients); thread-safe.
    Each holder says how much it holds now. A holder asking for more than is left is told no and, in the same step,
    holds nothing any more: it is done (its connection closes), and the others may have its bytes from that moment,
    not only once it has cleaned up. Otherwise two holders near the limit could each be refused while the other's
    bytes were still counted, where one of them alone fits."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self._lock = threading.Lock()
        self._used = 0

    @property
    def used(self) -> int:
        return self._used

    def resize(self, held: int, wanted: int) -> bool:
        """Go from holding `held` bytes to `wanted`; when that would pass the limit, False, and the holder now holds
        nothing (see the class)."""
        with self._lock:
            if wanted > held and self._used - held + wanted > self.limit:
                self._used -= held
                return False
            self._used += wanted - held
            return True
