"""What a client of the endpoint waits for (bridge.client): the answers to its service calls, topic-list queries and
pings, each handed to whoever asked, and a call failed at once when the endpoint says it will not complete. No
sockets: the client's reader thread hands the answers in, the asking threads wait on them."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

from bridge.protocol import Event, PingResponse, ServiceResponse, TopicList

__all__ = ["Answers", "PendingCall", "PingResult"]


@dataclass(frozen=True)
class PingResult:
    """One __ping: its round trip, and how far ROS time is ahead of this machine's clock (time.time()), taking the
    endpoint's answer as given half-way through the round trip (None from an endpoint that does not say)."""

    round_trip_s: float
    ros_clock_offset_s: float | None


@dataclass
class PendingCall:
    """A service call waiting for its response (or for the reason it will have none)."""

    service: str
    done: threading.Event = field(default_factory=threading.Event)
    response: bytes | None = None
    failure: str | None = None


class Answers:
    """The questions of one client still waiting for their answers, across its reconnects."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._calls: dict[int, PendingCall] = {}
        self._topic_lists: list[tuple[threading.Event, dict[str, str]]] = []
        self._pings: dict[str, tuple[threading.Event, list[PingResponse]]] = {}

    def call(self, srv_id: int, service: str) -> PendingCall:
        """A service call about to be sent, to wait on; forget_call(srv_id) once it is over."""
        call = PendingCall(service)
        with self._lock:
            self._calls[srv_id] = call
        return call

    def forget_call(self, srv_id: int) -> None:
        with self._lock:
            self._calls.pop(srv_id, None)

    def topic_list(self) -> tuple[threading.Event, dict[str, str]]:
        """A topic-list query about to be sent: set when the next __topic_list comes, the dict then filled."""
        waiter: tuple[threading.Event, dict[str, str]] = (threading.Event(), {})
        with self._lock:
            self._topic_lists.append(waiter)
        return waiter

    def ping(self, request_time: str) -> tuple[threading.Event, list[PingResponse]]:
        """A ping about to be sent: set when its answer comes, the list then holding it; forget_ping once over."""
        waiter: tuple[threading.Event, list[PingResponse]] = (threading.Event(), [])
        with self._lock:
            self._pings[request_time] = waiter
        return waiter

    def forget_ping(self, request_time: str) -> None:
        with self._lock:
            self._pings.pop(request_time, None)

    def take(self, event: Event) -> bool:
        """Hand an answer to whoever waits for it; False when `event` is not an answer."""
        if isinstance(event, ServiceResponse):
            with self._lock:
                call = self._calls.get(event.srv_id)
            if call is not None:
                call.response = event.payload
                call.done.set()
        elif isinstance(event, TopicList):
            with self._lock:
                waiters, self._topic_lists = self._topic_lists, []
            for done, result in waiters:
                result.update(zip(event.topics, event.types))
                done.set()
        elif isinstance(event, PingResponse):
            with self._lock:
                waiter = self._pings.get(event.request_time)
            if waiter is not None:
                waiter[1].append(event)
                waiter[0].set()
        else:
            return False
        return True

    def fail_call(self, srv_id: int, reason: str) -> None:
        """The endpoint says this call will not complete: its caller hears at once."""
        with self._lock:
            call = self._calls.get(srv_id)
        if call is not None:
            call.failure = reason
            call.done.set()

    def fail_calls(self, reason: str) -> None:
        """Every call waiting fails (the connection is lost, the client closed)."""
        with self._lock:
            calls = list(self._calls.values())
        for call in calls:
            call.failure = reason
            call.done.set()
