"""The runner's inputs (sim.study.run.runner.Inputs): presses by their stamps, answers in order, waits bounded."""

from __future__ import annotations

import threading

from sim.study.run.runner import Inputs


def test_presses_are_taken_when_their_time_has_come_and_unstamped_ones_at_once() -> None:
    inputs = Inputs()
    inputs.press(12.40, "vr_trigger")  # sent ahead, stamped when it is to land
    assert inputs.take_press(until=12.38) is None
    taken = inputs.take_press(until=12.40)
    assert taken is not None and taken.source == "vr_trigger"
    inputs.press(0.0, "button")  # no stamp: when it arrives
    taken = inputs.take_press(until=3.0)
    assert taken is not None and taken.stamp == 0.0 and inputs.take_press(until=1e9) is None


def test_clear_forgets_what_came_before_the_phase() -> None:
    inputs, stop = Inputs(), threading.Event()
    inputs.go()
    inputs.press(1.0, "button")
    inputs.distance(0.2)
    inputs.preference("1")
    inputs.clear()
    assert inputs.take_press(until=1e9) is None
    for what in ("go", "distance", "preference"):
        assert inputs.wait(what, 0.01, stop) is None


def test_answers_come_in_order_and_impossible_distances_are_refused() -> None:
    inputs, stop = Inputs(), threading.Event()
    inputs.distance(-0.3)
    inputs.distance(0.14)
    inputs.preference("lateral_arc")
    assert inputs.wait("distance", 1.0, stop) == 0.14
    assert inputs.rejected and "perceived distance" in inputs.rejected[0]
    assert inputs.wait("preference", 1.0, stop) == "lateral_arc"


def test_a_wait_ends_when_the_answer_comes_from_another_thread_or_on_stop() -> None:
    inputs, stop = Inputs(), threading.Event()
    threading.Timer(0.05, inputs.go).start()
    assert inputs.wait("go", 10.0, stop) is True
    threading.Timer(0.05, stop.set).start()
    assert inputs.wait("distance", 10.0, stop) is None
