"""The workers of one client's ROS calls: service calls on a few threads of its own, look-ups at the ROS master
(topic lists) on another, so a slow ROS side holds up only this client's calls, and never its look-ups. Threads are
started on demand: a client that never calls a service costs none."""

from __future__ import annotations

import logging
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Callable

from bridge.errors import RequestRefused

__all__ = ["ClientCalls"]

log = logging.getLogger(__name__)


class ClientCalls:
    """The ROS calls of the client `name`: at most `workers` at once, `max_pending` in progress or waiting."""

    def __init__(self, name: str, workers: int, max_pending: int) -> None:
        self._name = name
        self._calls = ThreadPoolExecutor(workers, thread_name_prefix=f"calls {name}")
        self._lookups = ThreadPoolExecutor(1, thread_name_prefix=f"look-ups {name}")
        self._max_pending = max_pending
        self._lock = threading.Lock()
        self._pending: set[Future] = set()

    def run_call(self, what: str, call: Callable[[], None], srv_id: int | None = None) -> None:
        """Run a ROS service call on the client's call workers; RequestRefused when too many are waiting already."""
        self._submit(self._calls, what, call, srv_id)

    def run_lookup(self, what: str, look_up: Callable[[], None]) -> None:
        """Run a look-up at the ROS master (a topic list) on the client's look-up worker."""
        self._submit(self._lookups, what, look_up, None)

    def stop(self) -> None:
        """The client has gone: calls not started yet are dropped (running ones see the session's `gone` and end),
        and the workers end once idle. Cancelled outside the lock: cancel() runs the done callback, which takes it."""
        with self._lock:
            pending = list(self._pending)
        for future in pending:
            future.cancel()
        self._calls.shutdown(wait=False)
        self._lookups.shutdown(wait=False)

    def _submit(self, workers: ThreadPoolExecutor, what: str, call: Callable[[], None], srv_id: int | None) -> None:
        with self._lock:
            if len(self._pending) >= self._max_pending:
                raise RequestRefused(
                    f"{what}: refused, this client already has {len(self._pending)} ROS calls in progress; "
                    "this call will not complete",
                    srv_id,
                )
            try:
                future = workers.submit(call)
            except RuntimeError:  # the session is closing and its workers are shut down
                return
            self._pending.add(future)
        future.add_done_callback(self._done)

    def _done(self, future: Future) -> None:
        with self._lock:
            self._pending.discard(future)
        if not future.cancelled() and future.exception() is not None:
            log.error("client %s: a ROS call failed", self._name, exc_info=future.exception())
