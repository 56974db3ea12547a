"""bridge.connection.queues.OutgoingQueue: bounded by frames and bytes, drop-oldest-droppable, close/timeout
semantics."""

from __future__ import annotations

import threading
import time

import pytest

from bridge.connection.queues import ByteBudget, OutgoingQueue


def test_limits_must_be_positive() -> None:
    with pytest.raises(ValueError, match="max_frames=0"):
        OutgoingQueue(0, 10)
    with pytest.raises(ValueError, match="max_bytes=0"):
        OutgoingQueue(10, 0)


def test_bounded_by_frame_count_drops_oldest() -> None:
    queue = OutgoingQueue(max_frames=3, max_bytes=1 << 20)
    for index in range(5):
        queue.put(b"m%d" % index)
    assert len(queue) == 3 and queue.dropped == 2
    assert queue.take_all(timeout=0) == [b"m2", b"m3", b"m4"]
    assert len(queue) == 0 and queue.queued_bytes == 0


def test_bounded_by_bytes_drops_oldest() -> None:
    queue = OutgoingQueue(max_frames=100, max_bytes=10)
    for index in range(4):
        queue.put(b"%04d" % index)  # 4 bytes each: 16 > 10, so two go
    assert queue.dropped == 2 and queue.queued_bytes == 8
    assert queue.take_all(timeout=0) == [b"0002", b"0003"]


def test_drops_only_the_oldest_droppable_frame() -> None:
    queue = OutgoingQueue(max_frames=3, max_bytes=1 << 20)
    queue.put(b"response", droppable=False)
    queue.put(b"d1")
    queue.put(b"d2")
    queue.put(b"d3")
    assert queue.dropped == 1
    assert queue.take_all(timeout=0) == [b"response", b"d2", b"d3"]


def test_never_drops_non_droppable_frames_even_over_the_limit() -> None:
    queue = OutgoingQueue(max_frames=2, max_bytes=8)
    for index in range(5):
        queue.put(b"service-%d" % index, droppable=False)
    assert len(queue) == 5 and queue.dropped == 0
    queue.put(b"topic")  # the only droppable frame is the one that goes
    assert queue.dropped == 1
    assert queue.take_all(timeout=0) == [b"service-%d" % index for index in range(5)]


def test_drop_count_accumulates_across_batches() -> None:
    queue = OutgoingQueue(max_frames=1, max_bytes=1 << 20)
    for _ in range(3):
        queue.put(b"a")
        queue.put(b"b")
        assert queue.take_all(timeout=0) == [b"b"]
    assert queue.dropped == 3


def test_take_all_times_out_with_an_empty_list() -> None:
    queue = OutgoingQueue(10, 100)
    started = time.monotonic()
    assert queue.take_all(timeout=0.1) == []
    assert 0.08 <= time.monotonic() - started < 2.0


def test_take_all_returns_at_once_when_something_is_queued() -> None:
    queue = OutgoingQueue(10, 100)
    queue.put(b"x")
    started = time.monotonic()
    assert queue.take_all(timeout=5) == [b"x"]
    assert time.monotonic() - started < 1.0


def test_take_all_wakes_on_put_from_another_thread() -> None:
    queue = OutgoingQueue(10, 100)
    timer = threading.Timer(0.05, queue.put, args=(b"late",))
    timer.start()
    started = time.monotonic()
    try:
        assert queue.take_all(timeout=5) == [b"late"]
    finally:
        timer.cancel()
    assert time.monotonic() - started < 2.0


def test_close_drains_then_returns_none() -> None:
    queue = OutgoingQueue(10, 100)
    queue.put(b"last words", droppable=False)
    queue.close()
    queue.put(b"ignored after close")
    assert queue.take_all(timeout=5) == [b"last words"]
    assert queue.take_all(timeout=5) is None


def test_close_with_discard_drops_everything() -> None:
    queue = OutgoingQueue(10, 100)
    queue.put(b"a")
    queue.close(discard=True)
    assert queue.take_all(timeout=5) is None and queue.queued_bytes == 0


def test_close_wakes_a_waiting_writer() -> None:
    queue = OutgoingQueue(10, 100)
    result = []
    waiter = threading.Thread(target=lambda: result.append(queue.take_all(timeout=10)))
    waiter.start()
    time.sleep(0.05)  # let the writer block in take_all (the test also passes if it has not yet)
    queue.close()
    waiter.join(timeout=5)
    assert not waiter.is_alive() and result == [None]


def test_thread_safety_smoke() -> None:
    queue = OutgoingQueue(max_frames=50, max_bytes=1000)
    producers, per_producer = 4, 3000
    taken: list[bytes] = []
    done = threading.Event()

    def produce(index: int) -> None:
        for count in range(per_producer):
            queue.put(b"%d:%d" % (index, count), droppable=count % 10 != 0)

    def consume() -> None:
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            batch = queue.take_all(timeout=0.05)
            if batch is None:
                return
            taken.extend(batch)
            if done.is_set() and not batch:
                return

    consumer = threading.Thread(target=consume)
    consumer.start()
    threads = [threading.Thread(target=produce, args=(index,)) for index in range(producers)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=20)
    done.set()
    queue.close()
    consumer.join(timeout=20)
    assert not consumer.is_alive()
    assert len(taken) + queue.dropped == producers * per_producer
    assert len(set(taken)) == len(taken)
    non_droppable = {b"%d:%d" % (index, count) for index in range(producers) for count in range(0, per_producer, 10)}
    assert non_droppable <= set(taken), "a non-droppable frame was lost"
    for index in range(producers):  # per producer, order is kept
        mine = [int(item.split(b":")[1]) for item in taken if item.startswith(b"%d:" % index)]
        assert mine == sorted(mine)


def test_put_returns_how_many_frames_it_dropped() -> None:
    queue = OutgoingQueue(max_frames=2, max_bytes=1 << 20)
    assert [queue.put(b"x") for _ in range(4)] == [0, 0, 1, 1]


def test_a_frame_larger_than_the_byte_limit_still_goes_through() -> None:
    queue = OutgoingQueue(max_frames=10, max_bytes=8)
    queue.put(b"small")
    assert queue.put(b"a big camera image") == 1  # the older frame makes room; the big one stays
    assert queue.take_all(timeout=0) == [b"a big camera image"]


def test_wait_reports_items_timeout_and_closed() -> None:
    queue = OutgoingQueue(max_frames=10, max_bytes=100)
    assert queue.wait(timeout=0.01) is True and len(queue) == 0  # timed out, still open
    queue.put(b"a")
    assert queue.wait() is True and len(queue) == 1  # does not take
    queue.close(discard=True)
    assert queue.wait() is False


def test_put_with_wait_takes_the_room_the_consumer_makes_and_drops_nothing() -> None:
    queue = OutgoingQueue(max_frames=2, max_bytes=1 << 20)
    queue.put(b"a")
    queue.put(b"b")
    timer = threading.Timer(0.05, queue.take_all, kwargs={"timeout": 0})
    timer.start()
    started = time.monotonic()
    try:
        assert queue.put(b"c", wait_s=5.0) == 0
    finally:
        timer.cancel()
    assert time.monotonic() - started < 2.0
    assert queue.dropped == 0 and queue.take_all(timeout=0) == [b"c"]


def test_put_with_wait_drops_oldest_when_no_room_comes_in_time() -> None:
    queue = OutgoingQueue(max_frames=2, max_bytes=1 << 20)
    queue.put(b"a")
    queue.put(b"b")
    started = time.monotonic()
    assert queue.put(b"c", wait_s=0.05) == 1
    assert 0.04 <= time.monotonic() - started < 2.0
    assert queue.take_all(timeout=0) == [b"b", b"c"]


def test_put_with_wait_returns_at_once_when_there_is_room_or_the_queue_closes() -> None:
    queue = OutgoingQueue(max_frames=1, max_bytes=1 << 20)
    started = time.monotonic()
    assert queue.put(b"a", wait_s=5.0) == 0  # room: no wait
    closer = threading.Timer(0.05, queue.close)
    closer.start()
    assert queue.put(b"b", wait_s=5.0) == 0  # full: woken by close, and ignored like any put after close
    assert time.monotonic() - started < 2.0
    assert queue.take_all(timeout=0) == [b"a"]


def test_put_many_with_room_queues_everything_in_order() -> None:
    queue = OutgoingQueue(max_frames=10, max_bytes=1 << 20)
    assert queue.put_many([b"a", b"b", b"c"], wait_s=5.0) == 0
    assert queue.take_all(timeout=0) == [b"a", b"b", b"c"]


def test_put_many_hands_over_as_the_consumer_makes_room_and_drops_nothing() -> None:
    """More items than the queue holds: the consumer is woken while the producer waits, and nothing is lost."""
    queue = OutgoingQueue(max_frames=3, max_bytes=1 << 20)
    items = [bytes([index]) for index in range(50)]
    taken: list[bytes] = []

    def consume() -> None:
        while len(taken) < len(items):
            batch = queue.take_all(timeout=5.0)
            if not batch:
                return
            taken.extend(batch)

    consumer = threading.Thread(target=consume)
    consumer.start()
    assert queue.put_many(items, wait_s=5.0) == 0
    consumer.join(timeout=10)
    assert taken == items and queue.dropped == 0


def test_put_many_waits_once_then_drops_oldest_without_waiting_again() -> None:
    queue = OutgoingQueue(max_frames=2, max_bytes=1 << 20)
    started = time.monotonic()
    assert queue.put_many([b"a", b"b", b"c", b"d", b"e"], wait_s=1.0) == 3
    waited = time.monotonic() - started
    assert 0.9 <= waited < 2.5  # one wait of 1 s for "c", none for "d" and "e" (each waiting would take 3 s)
    assert queue.take_all(timeout=0) == [b"d", b"e"]


def test_put_many_stops_when_the_queue_closes() -> None:
    # Full before put_many begins, so that whether the close comes before it or while it waits for room, it must
    # stop at once, dropping and adding nothing (the timer may fire before put_many starts on a loaded machine)
    queue = OutgoingQueue(max_frames=1, max_bytes=1 << 20)
    queue.put(b"a")
    threading.Timer(0.05, queue.close).start()
    assert queue.put_many([b"b", b"c"], wait_s=5.0) == 0  # a wait that ran out would have dropped b"a"
    assert queue.take_all(timeout=0) == [b"a"]


def test_a_keyed_frame_keeps_at_most_its_limit_of_that_key_oldest_going_first() -> None:
    queue = OutgoingQueue(max_frames=100, max_bytes=10_000)
    for index in range(5):
        queue.put(f"latest{index}".encode(), key="/pose", key_limit=1)
        queue.put(f"all{index}".encode(), key="/joint_states", key_limit=0)  # 0: no limit of its own
    assert queue.put(b"service", droppable=False) == 0
    assert queue.take_all(timeout=0) == [b"all0", b"all1", b"all2", b"all3", b"latest4", b"all4", b"service"]
    assert queue.dropped == 4


def test_a_keys_count_follows_every_way_a_frame_leaves() -> None:
    queue = OutgoingQueue(max_frames=3, max_bytes=10_000)
    queue.put(b"a1", key="/a", key_limit=2)
    queue.put(b"b1")
    queue.put(b"b2")
    queue.put(b"b3")  # over max_frames: a1 goes, so /a has none queued
    queue.put(b"a2", key="/a", key_limit=2)
    queue.put(b"a3", key="/a", key_limit=2)
    assert queue.take_all(timeout=0) == [b"b3", b"a2", b"a3"]
    queue.put(b"a4", key="/a", key_limit=2)  # taken frames no longer count
    queue.put(b"a5", key="/a", key_limit=2)
    assert queue.take_all(timeout=0) == [b"a4", b"a5"]


def test_a_byte_budget_is_shared_and_refuses_growth_past_its_limit() -> None:
    budget = ByteBudget(100)
    assert budget.resize(0, 60) and budget.used == 60
    assert not budget.resize(0, 50) and budget.used == 60  # a second holder may not take what is not left
    assert budget.resize(0, 40) and budget.used == 100
    assert budget.resize(60, 10) and budget.used == 50  # shrinking always works
    assert budget.resize(10, 0) and budget.resize(40, 0) and budget.used == 0


def test_a_holder_refused_more_holds_nothing_from_that_moment() -> None:
    # Two holders near the limit: the one refused lets go at once, so the other's next step fits.
    budget = ByteBudget(100)
    assert budget.resize(0, 45) and budget.resize(0, 50)
    assert not budget.resize(45, 55) and budget.used == 50
    assert budget.resize(50, 100) and budget.used == 100


# --- the writer's batches: small frames before queued large ones ------------------------------------------------


def large_queue() -> OutgoingQueue:
    return OutgoingQueue(100, 1 << 20, large_bytes=10)


def test_small_frames_go_before_queued_large_ones_and_large_ones_one_per_batch() -> None:
    queue = large_queue()
    for frame, key in (
        (b"image-1...", "/image"),
        (b"j1", "/joints"),
        (b"cloud-1...", "/cloud"),
        (b"j2", "/joints"),
        (b"image-2...", "/image"),
    ):
        queue.put(frame, key=key)
    assert queue.take_batch() == [b"j1", b"j2", b"image-1..."]  # the oldest large frame last
    queue.put(b"j3", key="/joints")
    assert queue.take_batch() == [b"j3", b"cloud-1..."]  # what came meanwhile goes first
    assert queue.take_batch() == [b"image-2..."]
    assert queue.take_batch() == [] and queue.queued_bytes == 0


def test_a_frame_never_overtakes_an_earlier_one_of_its_key() -> None:
    queue = large_queue()
    queue.put(b"big-scan...", key="/scan")
    queue.put(b"small", key="/scan")  # the same topic, smaller this time: it waits for the large one
    queue.put(b"error-big...", droppable=False)  # frames without a key keep their order too
    queue.put(b"warn", droppable=False)
    assert queue.take_batch() == [b"big-scan..."]  # the others wait behind frames of their key
    assert queue.take_batch() == [b"small", b"error-big..."]
    assert queue.take_batch() == [b"warn"]


def test_the_rest_of_a_frame_begun_on_the_wire_goes_first() -> None:
    queue = large_queue()
    queue.put(b"j1", key="/joints")
    queue.put_continuation(b"...rest of a large frame")
    assert queue.take_batch() == [b"...rest of a large frame", b"j1"]
    queue.put_continuation(b"xy")
    queue.put(b"image-3...", key="/image")
    queue.put(b"j2", key="/joints")
    assert queue.take_batch() == [b"xy", b"j2", b"image-3..."]


def test_a_goodbye_drops_what_is_not_begun_and_follows_the_frame_on_the_wire() -> None:
    queue = large_queue()
    queue.put(b"j1", key="/joints")
    queue.put(b"answer", droppable=False)
    queue.put_continuation(b"...rest of an image")
    assert queue.finish_with(b"close")
    assert queue.take_batch() == [b"...rest of an image", b"close"]
    queue.put(b"j2")  # nothing after the goodbye
    assert not queue.finish_with(b"again") and queue.take_all(timeout=1) is None
    assert queue.dropped == 0  # frames thrown away for the close are not the client's slowness


def test_the_rest_of_a_frame_begun_goes_out_after_close_too() -> None:
    """A direct send that wrote a frame's first bytes as the queue closed: the rest must still follow them."""
    queue = OutgoingQueue(10, 100)
    assert queue.finish_with(b"close")
    queue.put_continuation(b"rest")
    assert queue.take_all(timeout=1) == [b"rest", b"close"]
    discarded = OutgoingQueue(10, 100)
    discarded.close(discard=True)  # the TCP session's close: nothing more goes out at all
    discarded.put_continuation(b"rest")
    assert discarded.take_all(timeout=1) is None


def test_a_topic_limited_to_one_keeps_its_newest_large_frame() -> None:
    queue = large_queue()
    for index in range(5):
        queue.put(f"image-{index}...".encode(), key="/image", key_limit=1)
        queue.put(f"j{index}".encode(), key="/joints")
    assert queue.dropped == 4
    assert queue.take_batch() == [b"j0", b"j1", b"j2", b"j3", b"j4", b"image-4..."]


def test_longest_waits_are_reported_per_key_and_reset() -> None:
    queue = large_queue()
    queue.put(b"j1", key="/joints")
    time.sleep(0.05)
    queue.put(b"j2", key="/joints")
    queue.put(b"no key")
    queue.take_batch()
    waits = queue.longest_waits()
    assert set(waits) == {"/joints"} and 0.04 <= waits["/joints"] < 5.0
    assert queue.longest_waits() == {}
    assert queue.oldest_age() is None
