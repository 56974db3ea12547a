"""Bounded frame queues: drop the oldest topic frame when full, never a service frame.

Used per client for frames going out to it, and per bridged topic for client payloads waiting for the ROS
publisher's pump thread (bridge.ros.publisher.RawPublisher).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from typing import Optional, Sequence, Tuple

__all__ = ["OutgoingQueue", "ByteBudget"]


# One queued frame: (bytes, droppable, key, monotonic time it was queued, counted in _key_counts)
_Item = Tuple[bytes, bool, Optional[str], float, bool]


class OutgoingQueue:
    """Frames waiting for one client's writer.

    Bounded by frame count and bytes. When full, the oldest *droppable* frame (a topic message) goes; service
    request/response pairs and errors are never dropped, so a slow reader loses stale samples, not answers.
    A frame may also carry a key (its topic) with a limit of its own: at most that many frames of the key wait, the
    oldest of them going first (a client's queue_size for a topic).

    With `large_bytes`, the writer's next batch (take_batch) puts small frames before queued large ones, so control
    messages do not wait behind camera images on a slow link; frames of one key (and frames without a key) keep
    their order.
    """

    def __init__(self, max_frames: int, max_bytes: int, large_bytes: int | None = None) -> None:
        if max_frames < 1 or max_bytes < 1:
            raise ValueError(f"queue limits must be positive, got max_frames={max_frames}, max_bytes={max_bytes}")
        self.max_frames = max_frames
        self.max_bytes = max_bytes
        self.large_bytes = large_bytes
        self._items: deque[_Item] = deque()
        self._key_counts: dict[str, int] = {}  # frames queued per key
        self._large = 0  # frames of large_bytes or more queued
        self._bytes = 0
        self._kept_bytes = 0  # of frames that are never dropped (answers)
        self._longest_waits: dict[str, float] = {}  # per key, the longest a taken frame waited (take_batch)
        self._continuation = False  # the first frame is the rest of one begun on the wire (put_continuation)
        self._closed = False  # no more frames are taken (the writer drains what is queued)
        self._discarded = False  # closed with what was queued thrown away: nothing more is sent
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
    def large_queued(self) -> bool:
        """A frame of `large_bytes` or more is queued."""
        return self._large > 0

    @property
    def queued_bytes(self) -> int:
        return self._bytes

    @property
    def kept_bytes(self) -> int:
        """Bytes of queued frames that are never dropped (answers): what a peer that reads nothing piles up; the
        producer must stop making them (the queue cannot drop them)."""
        return self._kept_bytes

    def oldest_age(self) -> float | None:
        """How long the oldest queued frame has waited (s); None when nothing is queued."""
        with self._not_empty:
            if not self._items:
                return None
            return time.monotonic() - min(item[3] for item in self._items)

    def longest_waits(self) -> dict[str, float]:
        """Per key, the longest a frame of it waited before take_batch took it, since this was last asked."""
        with self._not_empty:
            waits, self._longest_waits = self._longest_waits, {}
            return waits

    def put(
        self, data: bytes, droppable: bool = True, wait_s: float = 0.0, key: str | None = None, key_limit: int = 0
    ) -> int:
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
            dropped = self._append(data, droppable, key, key_limit, time.monotonic())
            self._not_empty.notify()
            return dropped

    def put_continuation(self, data: bytes) -> None:
        """Queue the rest of a frame whose first bytes were written directly, ahead of everything: it must follow
        them on the wire. Never dropped; taken after close() too (unless discarded), as its frame is on the wire."""
        with self._not_full:
            if self._discarded:
                return
            self._items.appendleft((data, False, None, time.monotonic(), False))
            self._bytes += len(data)
            self._kept_bytes += len(data)
            if self.large_bytes is not None and len(data) >= self.large_bytes:
                self._large += 1
            self._continuation = True
            self._not_empty.notify()

    def put_many(self, items: list[bytes], wait_s: float = 0.0) -> int:
        """`put` (droppable) of each item in turn under one lock acquisition: what a client's reader hands over from
        one read. While the queue is full, each item waits up to `wait_s` for room, as with `put`; once one waited
        in vain, the rest drop oldest without waiting. Returns how many frames were dropped."""
        dropped = 0
        now = time.monotonic()  # one time for what one read brought
        with self._not_full:
            for data in items:
                if wait_s > 0.0 and not self._has_room(len(data)):
                    self._not_empty.notify()  # the consumer takes what is queued while we wait
                    if not self._wait_for_room(len(data), wait_s):
                        wait_s = 0.0
                if self._closed:
                    break
                dropped += self._append(data, True, None, 0, now)
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

    def _append(self, data: bytes, droppable: bool, key: str | None, key_limit: int, now: float) -> int:
        """With the lock held: queue `data` (queued at `now`), dropping the oldest droppable frames while over a
        limit; how many. The hot path of every queued frame: counts are kept inline."""
        dropped = 0
        counted = False
        if key is not None and key_limit > 0:  # only frames with a limit of their own are counted by key
            counted = True
            while self._key_counts.get(key, 0) >= key_limit and self._drop_oldest_of(key):
                dropped += 1
            self._key_counts[key] = self._key_counts.get(key, 0) + 1
        self._items.append((data, droppable, key, now, counted))
        size = len(data)
        self._bytes += size
        if not droppable:
            self._kept_bytes += size
        if self.large_bytes is not None and size >= self.large_bytes:
            self._large += 1
        while (len(self._items) > self.max_frames or self._bytes > self.max_bytes) and len(self._items) > 1:
            if not self._drop_oldest_droppable():
                break
            dropped += 1
        return dropped

    def _has_room(self, size: int) -> bool:
        return len(self._items) < self.max_frames and (not self._items or self._bytes + size <= self.max_bytes)

    def _drop_oldest_droppable(self) -> bool:
        if self._items[0][1]:  # the usual case, and the cheap one
            self._forget(self._items.popleft(), dropped=True)
            return True
        index = next((i for i, item in enumerate(self._items) if item[1]), None)
        if index is None:
            return False
        self._drop_at(index)
        return True

    def _drop_oldest_of(self, key: str) -> bool:
        index = next((i for i, item in enumerate(self._items) if item[2] == key and item[4]), None)
        if index is None:
            return False
        self._drop_at(index)
        return True

    def _drop_at(self, index: int) -> None:
        item = self._items[index]
        del self._items[index]
        self._forget(item, dropped=True)

    def _forget(self, item: _Item, dropped: bool) -> None:
        """Account for a frame leaving the queue (dropped, or taken by take_batch)."""
        data, droppable, key, counted = item[0], item[1], item[2], item[4]
        self._bytes -= len(data)
        if not droppable:
            self._kept_bytes -= len(data)
        if self.large_bytes is not None and len(data) >= self.large_bytes:
            self._large -= 1
        if dropped:
            self._dropped += 1
        if counted:
            self._key_counts[key] -= 1  # type: ignore[index]

    def take_all(self, timeout: float | None = None) -> list[bytes] | None:
        """Everything queued, in order (waiting up to `timeout` for something); [] on timeout; None once closed and
        empty."""
        with self._not_empty:
            if not self._items and not self._closed:
                self._not_empty.wait(timeout)
            if not self._items:
                return None if self._closed else []
            items = [item[0] for item in self._items]
            self._clear()
            self._not_full.notify_all()
            return items

    def take_batch(self) -> list[bytes]:
        """What the writer sends next, without waiting: a continuation first, then every small frame in order, then
        the oldest large frame (the rest of the large ones wait for the next batch, so small frames queued
        meanwhile go before them). A frame never overtakes an earlier one of its key (frames without a key count
        as one key). Without `large_bytes`, or with no large frame queued: everything, in order."""
        with self._not_empty:
            if not self._items:
                return []
            now = time.monotonic()
            taken = self._take_small_first() if self._large else self._items
            # The batch's first frame waited longest of its small ones, its last may be an older large one: their
            # waits are recorded (the others' would cost a dictionary update per frame, the hot path of a flood).
            for _, _, key, queued_at, _ in (taken[0], taken[-1]):
                if key is not None and now - queued_at > self._longest_waits.get(key, -1.0):
                    self._longest_waits[key] = now - queued_at
            frames = [item[0] for item in taken]
            if taken is self._items:
                self._clear()
            self._not_full.notify_all()
            return frames

    def _take_small_first(self) -> Sequence[_Item]:
        """With the lock held: take_batch's choice when large frames are queued (see there)."""
        large_bytes = self.large_bytes or 0
        taken: list[_Item] = []
        large: _Item | None = None
        kept: deque[_Item] = deque()
        held_keys: set[str | None] = set()  # keys with an earlier frame staying queued (or taken last)
        for index, item in enumerate(self._items):
            data, key = item[0], item[2]
            if key in held_keys:
                kept.append(item)
            elif len(data) < large_bytes or (index == 0 and self._continuation):  # a continuation goes first
                taken.append(item)
            elif large is None:
                large = item
                held_keys.add(key)
            else:
                kept.append(item)
                held_keys.add(key)
        if large is not None:
            taken.append(large)
        for item in taken:
            self._forget(item, dropped=False)
        self._items = kept
        self._continuation = False
        return taken

    def _clear(self) -> None:
        self._continuation = False
        self._items.clear()
        self._key_counts.clear()
        self._bytes = self._kept_bytes = self._large = 0

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
                self._discarded = True
                self._clear()
            self._not_empty.notify_all()
            self._not_full.notify_all()

    def finish_with(self, data: bytes) -> bool:
        """Close with `data` as the last thing sent: every frame not yet begun is thrown away (the rest of one begun
        on the wire stays first), then `data` is queued and no more puts are taken. False, and nothing queued, when
        the queue was closed already. (A connection's goodbye: it must not wait behind a backlog, nor cut a frame.)"""
        with self._not_empty:
            if self._closed:
                return False
            begun = self._items[0] if self._continuation and self._items else None
            self._clear()
            if begun is not None:
                self._items.append(begun)
                self._bytes = self._kept_bytes = len(begun[0])
                self._large = int(self.large_bytes is not None and len(begun[0]) >= self.large_bytes)
                self._continuation = True
            self._append(data, False, None, 0, time.monotonic())
            self._closed = True
            self._not_empty.notify_all()
            self._not_full.notify_all()
            return True


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
