"""The endpoint's shared token: compared in constant time, with a back-off per address for wrong ones. No I/O.

Each wrong token from an address doubles how long the verdict on its next wrong token is held back (from
BACKOFF_FIRST_S up to BACKOFF_MAX_S); a right one is let in at once, and clears the record. A guesser thus learns
a handful of verdicts a minute per connection it may hold (the endpoint limits those per address) instead of
thousands a second, while a client with the right token on the same address is not held up at all.
"""

from __future__ import annotations

import hmac
import threading
import time
from dataclasses import dataclass
from typing import Callable

__all__ = ["BACKOFF_FIRST_S", "BACKOFF_MAX_S", "AuthGuard"]

BACKOFF_FIRST_S = 0.1
BACKOFF_MAX_S = 30.0
_MAX_RECORDS = 4096  # addresses remembered; the oldest expired ones are forgotten first


@dataclass
class _Failures:
    count: int
    last_at: float


class AuthGuard:
    def __init__(self, token: str, clock: Callable[[], float] = time.monotonic) -> None:
        self._token = token.encode("utf-8")
        self._clock = clock
        self._lock = threading.Lock()
        self._failures: dict[str, _Failures] = {}

    def check(self, host: str, token: str) -> float:
        """Whether `token` is the endpoint's (compared in constant time): 0.0 when it is, else the seconds to hold
        back the verdict (the address's back-off, doubled by this wrong token; always > 0)."""
        right = hmac.compare_digest(token.encode("utf-8"), self._token)
        with self._lock:
            if right:
                self._failures.pop(host, None)
                return 0.0
            now = self._clock()
            record = self._failures.get(host) or _Failures(0, now)
            record.count += 1
            delay = min(BACKOFF_MAX_S, BACKOFF_FIRST_S * 2 ** min(record.count - 1, 30))
            record.last_at = now
            self._failures[host] = record
            if len(self._failures) > _MAX_RECORDS:
                self._forget_oldest()
            return delay

    def failures(self, host: str) -> int:
        """Wrong tokens from `host` since its last right one."""
        with self._lock:
            record = self._failures.get(host)
            return record.count if record is not None else 0

    def _forget_oldest(self) -> None:
        """Forget the half of the records whose last wrong token is oldest."""
        by_age = sorted(self._failures, key=lambda host: self._failures[host].last_at)
        for host in by_age[: len(by_age) // 2]:
            del self._failures[host]
