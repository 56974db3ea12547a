"""The runner's inputs (sim.study.run.inputs.Inputs): only what the phase accepts (the protocol's table) is kept,
presses by their stamps, answers in order, waits bounded; a questionnaire item's answer checked, and the item said
again on a refused one (answer_item)."""

from __future__ import annotations

import math
import threading

import pytest

from sim.study.design.plan import make_plan
from sim.study.design.spec import load_design
from sim.study.run.inputs import Inputs, answer_item
from sim.study.run.links.base import Press
from sim.study.run.protocol import PHASES, PROTOCOL, Answer, answer_to_json
from sim.study.run.questionnaires import item_status


def entered(phase: str) -> Inputs:
    inputs = Inputs()
    inputs.enter(phase)
    return inputs


def test_presses_are_taken_when_their_time_has_come_and_unstamped_ones_at_once() -> None:
    inputs = entered("moving")
    inputs.press(12.40, "vr_trigger")  # sent ahead, stamped when it is to land
    assert inputs.take_press(until=12.38) is None
    taken = inputs.take_press(until=12.40)
    assert taken is not None and taken.source == "vr_trigger"
    inputs.press(0.0, "button")  # no stamp: when it arrives
    taken = inputs.take_press(until=3.0)
    assert taken is not None and taken.stamp == 0.0 and inputs.take_press(until=1e9) is None


def give_everything(inputs: Inputs) -> None:
    inputs.go()
    inputs.press(1.0, "button")
    inputs.distance(0.2)
    inputs.preference("1")
    inputs.answer_json(answer_to_json(Answer("ssq_before_vr", "nausea", 1)))


def kept(inputs: Inputs) -> set[str]:
    stop = threading.Event()
    found = {what for what in ("go", "distance", "preference", "answer") if inputs.wait(what, 0.0, stop) is not None}
    return found | ({"stop"} if inputs.take_press(until=1e9) is not None else set())


@pytest.mark.parametrize("phase", PHASES)
def test_a_phase_keeps_only_the_input_it_accepts(phase: str) -> None:
    inputs = entered(phase)
    give_everything(inputs)
    accepted = PROTOCOL.accepts(phase)
    assert kept(inputs) == (set() if accepted is None else {accepted})


def test_entering_a_phase_forgets_what_came_before_it() -> None:
    inputs = entered("moving")
    inputs.press(1.0, "button")
    inputs.enter("moving")  # the next trial's approach
    assert inputs.take_press(until=1e9) is None


def test_answers_come_in_order_and_impossible_distances_are_refused() -> None:
    inputs, stop = entered("distance"), threading.Event()
    inputs.distance(-0.3)
    inputs.distance(0.14)
    assert inputs.wait("distance", 1.0, stop) == 0.14
    assert inputs.rejected and "perceived distance" in inputs.rejected[0]
    inputs.enter("preference")
    inputs.preference("lateral_arc")
    assert inputs.wait("preference", 1.0, stop) == "lateral_arc"


def test_a_wait_ends_when_the_answer_comes_from_another_thread_or_on_stop() -> None:
    inputs, stop = entered("ready"), threading.Event()
    threading.Timer(0.05, inputs.go).start()
    assert inputs.wait("go", 10.0, stop) is True
    threading.Timer(0.05, stop.set).start()
    assert inputs.wait("distance", 10.0, stop) is None


def test_answers_are_kept_as_given_and_what_is_no_answer_is_refused() -> None:
    inputs, stop = entered("questionnaire"), threading.Event()
    inputs.answer_json('{"administration": "ssq_before_vr", "item": "nausea"}')
    inputs.answer_json(answer_to_json(Answer("ssq_before_vr", "nausea", 7)))  # off the scale: the runner's to refuse
    inputs.answer(Answer("ssq_before_vr", "nausea", 2))
    assert inputs.wait("answer", 1.0, stop) == Answer("ssq_before_vr", "nausea", 7)
    assert inputs.wait("answer", 1.0, stop) == Answer("ssq_before_vr", "nausea", 2)
    assert len(inputs.rejected) == 1 and "an answer must have exactly" in inputs.rejected[0]
    inputs.enter("ready")
    inputs.answer_json("nonsense")  # not asked for now: not kept, not even refused
    assert len(inputs.rejected) == 1


def test_a_refused_answer_has_the_item_said_again_and_the_next_answer_is_taken() -> None:
    plan = make_plan(load_design(), 3, 1)
    status = item_status(plan, plan.questionnaires[0], 8)  # ssq_before_vr's nausea, 0..3
    inputs, stop = entered("questionnaire"), threading.Event()
    said: list[str] = []  # the item said again, by the answer refused just before
    logged: list[str] = []

    def say_again() -> None:
        said.append(logged[-1])

    inputs.answer(Answer("ssq_before_vr", "fatigue", 1))  # late, to the item before
    inputs.answer(Answer("ssq_before_vr", "nausea", 4))  # off the scale
    inputs.answer_json("{}")  # no answer at all: refused as it came
    inputs.answer(Answer("ssq_before_vr", "nausea", 2))
    taken = answer_item(status, inputs, lambda: inputs.wait("answer", 0.0, stop), say_again, logged.append, 9.0)
    assert taken == 2
    # said again after each answer it refused; what was no answer at all was refused as it came, without one
    assert said == [
        "ssq_before_vr item nausea: an answer was refused: an answer to ssq_before_vr item 'fatigue' while "
        "ssq_before_vr item 'nausea' is asked; asking again",
        "ssq_before_vr item nausea: an answer was refused: ssq_before_vr item nausea: the answer 4 is not one of 0..3"
        "; asking again",
    ]
    assert len(logged) == 3 and "an answer must have exactly" in logged[0] and not inputs.rejected

    logged.clear()
    assert answer_item(status, inputs, lambda: inputs.wait("answer", 0.0, stop), say_again, logged.append, 9.0) is None
    assert logged == ["ssq_before_vr item nausea: no answer within 9 s; left missing"] and len(said) == 2


def test_a_press_keeps_its_latency_the_arrival_delay_only_when_it_is_stamped() -> None:
    inputs = entered("moving")
    inputs.press(12.40, "button", 0.0083, 12.4321)
    inputs.press(0.0, "keyboard")  # the observer's: nothing measured
    stamped, unstamped = inputs.take_press(until=1e9), inputs.take_press(until=1e9)
    assert stamped is not None and unstamped is not None
    assert stamped.input_delay == 0.0083 and stamped.arrival_delay == pytest.approx(0.0321)
    assert math.isnan(unstamped.input_delay) and math.isnan(unstamped.arrival_delay)
    assert math.isnan(Press(0.0, "vr_trigger", 0.01, 12.0).arrival_delay)  # its time is its arrival, by definition


def test_waiting_for_a_press_returns_when_one_comes_and_leaves_it_to_be_taken() -> None:
    inputs, stop = entered("moving"), threading.Event()
    assert inputs.wait_for_press(0.05, stop) is False  # none came within the grace
    later = threading.Timer(0.05, lambda: inputs.press(3.0, "button"))
    later.start()
    assert inputs.wait_for_press(10.0, stop) is True
    later.join()
    assert inputs.take_press(until=2.0) is None  # not taken by the wait: applied at its stamp, 3.0
    press = inputs.take_press(until=3.0)
    assert press is not None and press.stamp == 3.0 and press.source == "button"
    stop.set()
    assert inputs.wait_for_press(10.0, stop) is False  # a stopped runner does not wait
