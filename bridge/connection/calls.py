"""The threads of the clients' ROS calls. A service call starts when it is asked, on a thread of its own, so a burst
of calls from one client never waits behind its earlier ones: its deadline runs from its asking (bridge.services),
and a queue would spend it. Threads are bounded per client and in total (CallRoom):
- each client may always run --call-workers calls at once, its own share, which no other client can take;
- past its share, up to --max-pending-calls, it borrows from a room all clients share, --max-clients x --call-workers
  calls, so the endpoint never runs more than twice the threads of every client's share together;
- a call that finds no room waits, its deadline running, and starts when a call of its client, or a borrowed one,
  ends (the clients that wait take turns).
A thread ends when no call waits for it: a client that does not call costs none. Look-ups at the ROS master (topic
lists) run on a worker of the client's own, never behind its service calls."""

from __future__ import annotations

import logging
import threading
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TYPE_CHECKING, Callable, Tuple

from bridge.errors import RequestRefused

if TYPE_CHECKING:
    from bridge.config import EndpointConfig

__all__ = ["CallRoom", "ClientCalls"]

log = logging.getLogger(__name__)

_Call = Tuple[str, Callable[[], None]]  # what it is (for the log), and the call


class CallRoom:
    """The room every client's calls share: `spare` calls at once past the clients' own shares, all clients together.
    Its lock guards every client's counts too (ClientCalls), so a call's end can start another client's call."""

    def __init__(self, spare: int) -> None:
        self.spare = spare
        self.borrowed = 0  # calls running past their client's share
        self.lock = threading.Lock()
        self._waiting: deque[ClientCalls] = deque()  # clients with calls waiting, in turn

    def wait(self, client: ClientCalls) -> None:
        if client not in self._waiting:
            self._waiting.append(client)

    def forget(self, client: ClientCalls) -> None:
        if client in self._waiting:
            self._waiting.remove(client)

    def work(self, client: ClientCalls, call: _Call) -> None:
        """A call's thread: runs the call, then the next that may start (of any client), until none may."""
        while True:
            what, run = call
            try:
                run()
            except Exception:
                log.exception("client %s: %s failed", client.name, what)
            with self.lock:
                client.ended()
                taken = self._next_call()
            if taken is None:
                return
            client, call = taken

    def _next_call(self) -> tuple[ClientCalls, _Call] | None:
        """The next call that may start, from the clients in turn, counted as started; None when none may. Under the
        lock: one call's end makes room for at most one other, so the thread that ends it takes it."""
        for _ in range(len(self._waiting)):
            client = self._waiting[0]
            self._waiting.rotate(-1)  # the next one first next time
            if client.may_start():
                call = client.waiting.popleft()
                if not client.waiting:
                    self._waiting.remove(client)
                client.started()
                return client, call
        return None


class ClientCalls:
    """The ROS calls of the client `name`: --call-workers at once of its own, more from `room`, --max-pending-calls
    in progress or waiting (service calls and look-ups)."""

    def __init__(self, name: str, config: EndpointConfig, room: CallRoom) -> None:
        self.name = name
        self._share = config.client_call_workers
        self._max_pending = config.client_max_pending_calls
        self._room = room
        self._lock = room.lock
        self.running = 0
        self.waiting: deque[_Call] = deque()
        self._stopped = False
        self._lookups = ThreadPoolExecutor(1, thread_name_prefix=f"look-ups {name}")
        self._lookups_pending: set[Future] = set()

    def run_call(self, what: str, call: Callable[[], None], srv_id: int | None = None) -> None:
        """Start a ROS service call now if there is room, else when there is; RequestRefused when the client has
        too many in progress or waiting already, or no thread can be had."""
        with self._lock:
            if self._stopped:  # the session is closing
                return
            self._check_room(what, srv_id)
            if not self.may_start():
                self.waiting.append((what, call))
                self._room.wait(self)
                return
            self.started()
            try:
                threading.Thread(target=self._room.work, args=(self, (what, call)), name="ROS calls").start()
            except RuntimeError:  # no thread to be had
                self.ended()
                raise RequestRefused(
                    f"{what}: refused, the endpoint cannot start a thread for it now", srv_id
                ) from None

    def run_lookup(self, what: str, look_up: Callable[[], None]) -> None:
        """Run a look-up at the ROS master (a topic list) on the client's look-up worker."""
        with self._lock:
            self._check_room(what, None)
            try:
                future = self._lookups.submit(look_up)
            except RuntimeError:  # the session is closing and its worker is shut down
                return
            self._lookups_pending.add(future)
        future.add_done_callback(self._looked_up)

    def stop(self) -> None:
        """The client has gone: calls not started yet are dropped (running ones see the session's `gone` and end),
        and the look-up worker ends once idle. Cancelled outside the lock: cancel() runs the done callback."""
        with self._lock:
            self._stopped = True
            self.waiting.clear()
            self._room.forget(self)
            lookups = list(self._lookups_pending)
        for future in lookups:
            future.cancel()
        self._lookups.shutdown(wait=False)

    # --- under the room's lock --------------------------------------------------------------------------------
    def may_start(self) -> bool:
        return self.running < self._share or self._room.borrowed < self._room.spare

    def started(self) -> None:
        if self.running >= self._share:
            self._room.borrowed += 1
        self.running += 1

    def ended(self) -> None:
        self.running -= 1
        if self.running >= self._share:
            self._room.borrowed -= 1

    def _check_room(self, what: str, srv_id: int | None) -> None:
        pending = self.running + len(self.waiting) + len(self._lookups_pending)
        if pending >= self._max_pending:
            raise RequestRefused(
                f"{what}: refused, this client already has {pending} ROS calls in progress; this call will not "
                "complete",
                srv_id,
            )

    def _looked_up(self, future: Future) -> None:
        with self._lock:
            self._lookups_pending.discard(future)
        if not future.cancelled() and future.exception() is not None:
            log.error("client %s: a look-up at the ROS master failed", self.name, exc_info=future.exception())
