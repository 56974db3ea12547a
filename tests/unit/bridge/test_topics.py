"""bridge.topics.EchoFilter: which client a message that came back from ROS through our own publisher was from."""

from __future__ import annotations

from bridge.topics import ECHO_RECORD_MAX, EchoFilter


def filter_of(records: dict[object, list[bytes]]) -> EchoFilter:
    echoes = EchoFilter()
    echoes.keep_for(records)
    for client, payloads in records.items():
        for payload in payloads:
            echoes.record(client, payload)
    return echoes


def test_each_clients_messages_come_back_in_its_order_whatever_the_interleaving() -> None:
    a, b = object(), object()
    echoes = filter_of({a: [b"a1", b"a2"], b: [b"b1", b"b2"]})
    assert [echoes.take(payload) for payload in (b"b1", b"a1", b"b2", b"a2")] == [b, a, b, a]
    assert all(not record for record in echoes.records.values())


def test_a_message_that_never_came_back_is_forgotten_at_the_next_one() -> None:
    a = object()
    echoes = filter_of({a: [b"dropped", b"a2", b"a3"]})
    assert echoes.take(b"a2") is a
    assert list(echoes.records[a]) == [b"a3"]


def test_a_message_no_client_recorded_skips_nobody_and_forgets_nothing() -> None:
    a = object()
    echoes = filter_of({a: [b"a1"]})
    assert echoes.take(b"from another node of ours") is None
    assert list(echoes.records[a]) == [b"a1"]


def test_only_the_clients_kept_for_are_recorded_and_their_records_survive_a_change() -> None:
    a, b, c = object(), object(), object()
    echoes = filter_of({a: [b"a1"], b: [b"b1"]})
    echoes.record(c, b"c1")  # c publishes but does not subscribe: nothing to filter for it
    assert set(echoes.records) == {a, b}
    echoes.keep_for([a, c])  # b left the topic, c subscribed too
    assert list(echoes.records[a]) == [b"a1"] and list(echoes.records[c]) == [] and b not in echoes.records
    echoes.keep_for([])
    assert echoes.records == {} and echoes.take(b"a1") is None


def test_a_record_keeps_the_newest_messages_only() -> None:
    a = object()
    echoes = filter_of({a: [str(n).encode() for n in range(ECHO_RECORD_MAX + 10)]})
    assert len(echoes.records[a]) == ECHO_RECORD_MAX and echoes.records[a][0] == b"10"
