"""bridge.connection.calls: a call starts when it is asked while there is room (a client's own share, then the room all
share), waits otherwise and starts as a call ends, clients waiting take turns, and a departed client's waiting calls
go."""

from __future__ import annotations

import threading
import time

import pytest

from bridge.config import EndpointConfig
from bridge.connection.calls import CallRoom, ClientCalls
from bridge.errors import RequestRefused


class Held:
    """Calls that run until released, each alone (`end`) or all (`release`); `started` names them in the order
    they started."""

    def __init__(self) -> None:
        self.started: list[str] = []
        self.release = threading.Event()
        self._ends: dict[str, threading.Event] = {}
        self._changed = threading.Condition()

    def call(self, name: str):
        self._ends[name] = threading.Event()

        def run() -> None:
            with self._changed:
                self.started.append(name)
                self._changed.notify_all()
            while not (self.release.is_set() or self._ends[name].wait(0.01)):
                pass

        return run

    def end(self, name: str) -> None:
        self._ends[name].set()

    def wait_started(self, count: int) -> list[str]:
        with self._changed:
            assert self._changed.wait_for(lambda: len(self.started) >= count, 10), self.started
            return list(self.started)


def client(name: str, room: CallRoom, share: int = 2, max_pending: int = 8) -> ClientCalls:
    config = EndpointConfig(client_call_workers=share, client_max_pending_calls=max_pending)
    return ClientCalls(name, config, room)


def running(room: CallRoom, *clients: ClientCalls) -> list[int]:
    with room.lock:
        return [calls.running for calls in clients]


def test_a_burst_starts_at_once_within_the_share_and_the_room() -> None:
    room, held = CallRoom(spare=3), Held()
    burst = client("a", room)
    for index in range(8):
        burst.run_call(f"a{index}", held.call(f"a{index}"))
    # its share (2) and the room (3) started when asked, in order; the other 3 wait
    assert held.wait_started(5) == ["a0", "a1", "a2", "a3", "a4"]
    assert running(room, burst) == [5] and room.borrowed == 3 and len(burst.waiting) == 3
    held.release.set()
    assert held.wait_started(8)[5:] == ["a5", "a6", "a7"]
    burst.stop()


def test_another_client_keeps_its_share_when_the_room_is_taken() -> None:
    room, held = CallRoom(spare=1), Held()
    greedy, other = client("greedy", room), client("other", room)
    for index in range(5):
        greedy.run_call(f"g{index}", held.call(f"g{index}"))
    held.wait_started(3)
    for index in range(3):
        other.run_call(f"o{index}", held.call(f"o{index}"))
    assert held.wait_started(5)[3:] == ["o0", "o1"]  # its share; the third waits for room
    assert running(room, greedy, other) == [3, 2] and len(other.waiting) == 1
    held.release.set()
    held.wait_started(8)
    greedy.stop()
    other.stop()


def test_clients_waiting_for_the_room_take_turns() -> None:
    room, held = CallRoom(spare=1), Held()
    first, second = client("first", room, share=1), client("second", room, share=1)
    first.run_call("f0", held.call("f0"))  # its share, held throughout
    second.run_call("s0", held.call("s0"))
    for index in range(1, 4):  # the room's one call, then two waiting
        first.run_call(f"f{index}", held.call(f"f{index}"))
    for index in range(1, 3):
        second.run_call(f"s{index}", held.call(f"s{index}"))
    assert held.wait_started(3) == ["f0", "s0", "f1"]
    # each end of a call in the room starts the next client's waiting call: neither waits behind all the other's
    for ending, count in (("f1", 4), ("f2", 5), ("s1", 6), ("f3", 7)):
        held.end(ending)
        held.wait_started(count)
    assert held.started[3:] == ["f2", "s1", "f3", "s2"]
    held.release.set()
    first.stop()
    second.stop()


def test_past_max_pending_a_call_is_refused_naming_its_srv_id() -> None:
    room, held = CallRoom(spare=0), Held()
    calls = client("a", room, share=1, max_pending=3)
    for index in range(3):
        calls.run_call(f"a{index}", held.call(f"a{index}"), srv_id=index)
    with pytest.raises(RequestRefused, match="3 ROS calls in progress") as refused:
        calls.run_call("a3", held.call("a3"), srv_id=101)
    assert refused.value.srv_id == 101
    held.release.set()
    calls.stop()


def test_a_departed_clients_waiting_calls_never_start_and_its_running_ones_make_room() -> None:
    room, held = CallRoom(spare=0), Held()
    gone, other = client("gone", room, share=1), client("other", room, share=1)
    gone.run_call("g0", held.call("g0"))
    gone.run_call("g1", held.call("g1"))  # waits for its share
    held.wait_started(1)
    gone.stop()
    gone.run_call("g2", held.call("g2"))  # asked while closing: dropped
    other.run_call("o0", held.call("o0"))
    held.end("g0")
    held.end("o0")
    for _ in range(1000):  # the threads count their calls' ends
        if running(room, gone, other) == [0, 0]:
            break
        time.sleep(0.01)
    assert held.started == ["g0", "o0"] and running(room, gone, other) == [0, 0] and not gone.waiting
    other.stop()
