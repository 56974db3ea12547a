"""bridge.server._take_echo: which client a message that came back from ROS through our own publisher was from."""
from __future__ import annotations

from collections import deque
from typing import Any

from bridge.server import _take_echo


def test_each_clients_messages_come_back_in_its_order_whatever_the_interleaving() -> None:
    a, b = object(), object()
    echoes: Any = {a: deque([b"a1", b"a2"]), b: deque([b"b1", b"b2"])}
    assert [_take_echo(echoes, payload) for payload in (b"b1", b"a1", b"b2", b"a2")] == [b, a, b, a]
    assert all(not record for record in echoes.values())


def test_a_message_that_never_came_back_is_forgotten_at_the_next_one() -> None:
    a = object()
    echoes: Any = {a: deque([b"dropped", b"a2", b"a3"])}
    assert _take_echo(echoes, b"a2") is a
    assert list(echoes[a]) == [b"a3"]


def test_a_message_no_client_recorded_skips_nobody_and_forgets_nothing() -> None:
    a = object()
    echoes: Any = {a: deque([b"a1"])}
    assert _take_echo(echoes, b"from another node of ours") is None
    assert list(echoes[a]) == [b"a1"]
