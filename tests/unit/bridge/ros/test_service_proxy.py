"""bridge.ros.service_proxy: the calls of a service, every client's proxy's, share one lookupService in flight, its
answer or its refusal."""

from __future__ import annotations

import threading
import time

import pytest

from bridge.ros import service_proxy as ros_service_proxy
from bridge.ros.master import MasterRefused
from bridge.ros.service_proxy import RawServiceProxy, _Asking


class _Raw:
    _type = "std_srvs/Trigger"
    _md5sum = "*"


class Master:
    """lookupService answered when released, after counting the questions."""

    def __init__(self, answer: object) -> None:
        self.questions = 0
        self.release = threading.Event()
        self._answer = answer

    def __call__(self, method: str, *args: object, timeout_s: float) -> str:
        assert method == "lookupService"
        self.questions += 1
        self.release.wait(10)
        if isinstance(self._answer, Exception):
            raise self._answer
        return str(self._answer)


class _Waiters(threading.Event):
    """An Event that notes the threads that have waited on it."""

    threads: set[int] = set()

    def wait(self, timeout: float | None = None) -> bool:
        _Waiters.threads.add(threading.get_ident())
        return super().wait(timeout)


class _CountedAsking(_Asking):
    def __init__(self) -> None:
        super().__init__()
        self.answered = _Waiters()


@pytest.mark.parametrize("answer", ["rosrpc://127.0.0.1:1", MasterRefused("no provider")])
def test_a_burst_of_calls_from_two_clients_asks_the_master_once(monkeypatch, answer: object) -> None:
    master = Master(answer)
    monkeypatch.setattr(ros_service_proxy, "call_master", master)
    monkeypatch.setattr(ros_service_proxy, "_Asking", _CountedAsking)
    _Waiters.threads = set()
    proxies = [RawServiceProxy(_Raw, "/burst", 1 << 20) for _ in range(2)]  # two clients'
    deadline = time.monotonic() + 30
    outcomes: list[object] = []

    def ask(proxy: RawServiceProxy) -> None:
        try:
            outcomes.append(proxy._ask_master(deadline, threading.Event()))
        except MasterRefused as error:
            outcomes.append(error)

    callers = [threading.Thread(target=ask, args=(proxies[index % 2],)) for index in range(8)]
    for caller in callers:
        caller.start()
    for _ in range(1000):  # the seven that came while the first asks wait for its answer
        if len(_Waiters.threads) >= 7:
            break
        time.sleep(0.01)
    master.release.set()
    for caller in callers:
        caller.join(10)
    assert master.questions == 1 and [(type(o), str(o)) for o in outcomes] == [(type(answer), str(answer))] * 8
