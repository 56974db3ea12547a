"""A log line for something that may recur very often (a flood of bad input, connections turned away): at most one
per interval, saying how many were not logged in between."""

from __future__ import annotations

import logging
import threading
import time

__all__ = ["LogThrottle"]


class LogThrottle:
    def __init__(self, logger: logging.Logger, interval_s: float = 1.0) -> None:
        self._logger = logger
        self._interval_s = interval_s
        self._lock = threading.Lock()
        self._last_at = -interval_s
        self._not_logged = 0

    def warning(self, message: str, *args: object) -> None:
        now = time.monotonic()
        with self._lock:
            if now - self._last_at < self._interval_s:
                self._not_logged += 1
                return
            not_logged, self._not_logged, self._last_at = self._not_logged, 0, now
        suffix = f" ({not_logged} more like it not logged)" if not_logged else ""
        self._logger.warning(message + suffix, *args)
