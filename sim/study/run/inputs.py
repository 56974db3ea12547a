"""What comes in from the participant and the observer during a session (go, presses, distances, preferences,
questionnaire answers), kept by phase until the runner takes it, and how a questionnaire item's answer is taken.
Thread-safe; no ROS."""

from __future__ import annotations

import math
import threading
import time
from typing import Any, Callable

from sim.study.errors import StudyError
from sim.study.run.links.base import Press
from sim.study.run.protocol import PROTOCOL, Answer, TrialStatus, answer_from_json, checked_answer, checked_distance

__all__ = ["Inputs", "answer_item"]


class Inputs:
    """What comes in from the participant and the observer, kept until the runner takes it; thread-safe. Only the
    input that the current phase accepts (the protocol's table) is kept: a go, a press, a distance, a
    preference or a questionnaire's answer that comes in another phase is not."""

    def __init__(self) -> None:
        self._changed = threading.Condition()
        self._accepting: str | None = None
        self._go = False
        self._presses: list[Press] = []
        self._distances: list[float] = []
        self._preferences: list[str] = []
        self._answers: list[Answer] = []
        self.rejected: list[str] = []

    def enter(self, phase: str) -> None:
        """A new phase: forget what came before it; from now on keep what `phase` accepts."""
        with self._changed:
            self._accepting = PROTOCOL.accepts(phase)
            self._go = False
            self._presses.clear()
            self._distances.clear()
            self._preferences.clear()
            self._answers.clear()

    def go(self) -> None:
        with self._changed:
            if self._accepting == "go":
                self._go = True
                self._changed.notify_all()

    def press(self, stamp: float, source: str, input_delay: float = math.nan, arrival: float = math.nan) -> None:
        with self._changed:
            if self._accepting == "stop":
                self._presses.append(Press(stamp, source, input_delay, arrival))
                self._changed.notify_all()

    def distance(self, value: float) -> None:
        with self._changed:
            if self._accepting != "distance":
                return
            try:
                self._distances.append(checked_distance(value))
            except StudyError as error:
                self.rejected.append(str(error))
            self._changed.notify_all()

    def preference(self, text: str) -> None:
        with self._changed:
            if self._accepting == "preference":
                self._preferences.append(text)
                self._changed.notify_all()

    def answer(self, answer: Answer) -> None:
        """A questionnaire item's answer, kept as given: which item it answers, and whether on its scale, is the
        runner's to check against the item it asks."""
        with self._changed:
            if self._accepting == "answer":
                self._answers.append(answer)
                self._changed.notify_all()

    def answer_json(self, text: str) -> None:
        """An answer as it comes on the answer topic; one that is no answer at all is refused here."""
        try:
            answer = answer_from_json(text)
        except StudyError as error:
            with self._changed:
                if self._accepting == "answer":
                    self.rejected.append(str(error))
            return
        self.answer(answer)

    def take_press(self, until: float) -> Press | None:
        """The first press stamped at or before `until` (or unstamped), if one came."""
        with self._changed:
            for k, press in enumerate(self._presses):
                if press.stamp <= until:
                    return self._presses.pop(k)
        return None

    def wait_for_press(self, timeout: float, stop: threading.Event) -> bool:
        """Wait (up to `timeout` s, or until stopped) until a press has come, without taking it; whether one has."""
        return self._wait_for(lambda: True if self._presses else None, timeout, stop) is not None

    def wait(self, what: str, timeout: float, stop: threading.Event) -> Any:
        """Wait for go (True), a distance (float), a preference (str) or an answer (Answer); None after `timeout` s
        or when stopped."""
        taken: dict[str, Callable[[], Any]] = {
            "go": lambda: True if self._go else None,
            "distance": lambda: self._distances.pop(0) if self._distances else None,
            "preference": lambda: self._preferences.pop(0) if self._preferences else None,
            "answer": lambda: self._answers.pop(0) if self._answers else None,
        }
        return self._wait_for(taken[what], timeout, stop)

    def _wait_for(self, found: Callable[[], Any], timeout: float, stop: threading.Event) -> Any:
        """What `found()` gives (under the lock) once it is not None; None after `timeout` s or when stopped."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while not stop.is_set():
                value = found()
                if value is not None:
                    return value
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._changed.wait(min(remaining, 0.1))
        return None


def answer_item(
    status: TrialStatus,
    inputs: Inputs,
    wait: Callable[[], Any],
    say_again: Callable[[], None],
    log: Callable[[str], None],
    timeout: float,
) -> int | None:
    """The answer to the item `status` asks, taken from `inputs` by `wait()` (an Answer, or None after `timeout` s),
    or None when none on its scale came in time. An answer off the scale, or to another item, is refused and logged,
    and the item is said again (`say_again()`): the client that sent it has shown its participant that the answer
    was taken, and without a new status would wait on with them until the timeout."""
    where = f"{status.administration} item {status.item}"
    while True:
        answer = wait()
        for problem in inputs.rejected:
            log(f"{where}: an answer was refused: {problem}")
        inputs.rejected.clear()
        if answer is None:
            log(f"{where}: no answer within {timeout:g} s; left missing")
            return None
        try:
            return checked_answer(answer, status)
        except StudyError as error:
            log(f"{where}: an answer was refused: {error}; asking again")
            say_again()
