"""What the runner asks the participant, through its dialogue (sim.study.run.dialogue): test 1's perceived distance
after a trial, the preferred path after each group of test 2, and the plan's questionnaires.

The plan's questionnaires are asked at their places, before the first trial or after the trial they follow, one
item at a time (phase questionnaire, answers on `/study/answer`); an item without an answer within the response
timeout is recorded as missing, and an answer refused (off the item's scale, or to another item) has the item's
status published again, so that a client which took its answer as given asks again. Their answers and scores are
written as soon as each administration ends (sim.study.run.questionnaires).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Callable

from sim.study.design.plan import SessionPlan
from sim.study.errors import StudyError
from sim.study.run.dialogue import Dialogue
from sim.study.run.inputs import answer_item
from sim.study.run.protocol import TrialStatus, chosen_path
from sim.study.run.questionnaires import asked_after, item_status, write_questionnaire

__all__ = ["Asking"]


class Asking:
    """The plan's questions, asked through `dialogue`, each waited for at most `response_timeout` s; the
    questionnaires' answers so far."""

    def __init__(self, plan: SessionPlan, dialogue: Dialogue, response_timeout: float) -> None:
        self.plan, self.dialogue, self.response_timeout = plan, dialogue, response_timeout
        # per questionnaire, its administrations so far: each item's answer (None: not answered)
        self.given: dict[str, dict[str, dict[str, int | None]]] = {}

    def ask_distance(self, status: TrialStatus, log: Callable[[str], None]) -> float:
        """Test 1's perceived distance, asked by `status`; NaN when none came within the response timeout."""
        perceived = math.nan
        self.dialogue.publish_status(status)
        answer = self.dialogue.wait_for_input("distance")
        if answer is None:
            log(f"trial {status.index}: no perceived distance within {self.response_timeout:g} s; left empty")
        else:
            perceived = float(answer)
        for problem in self.dialogue.inputs.rejected:
            log(f"trial {status.index}: an answer was refused: {problem}")
        self.dialogue.inputs.rejected.clear()
        return perceived

    def ask_preference(self, status: TrialStatus, log: Callable[[str], None]) -> str:
        """The path preferred of the group's (`status.group_paths`, a group of test 2's), asked by `status`; "" when
        none came within the response timeout. An answer that names none of them is logged and waited on."""
        self.dialogue.publish_status(status)
        while True:
            answer = self.dialogue.wait_for_input("preference")
            if answer is None:
                log(f"trial {status.index}: no preference within {self.response_timeout:g} s; left empty")
                return ""
            try:
                return chosen_path(answer, status.group_paths)
            except StudyError as error:
                log(f"trial {status.index}: {error}; asking again")

    def administer(self, after_trial: int, out: Path, log: Callable[[str], None]) -> None:
        """Ask the questionnaires placed after trial `after_trial` (0: before the first), item by item; write each
        one's records as soon as it has been asked."""
        for planned in asked_after(self.plan, after_trial):
            instrument = self.plan.instrument(planned.name)
            answers: dict[str, int | None] = {}
            for number in range(1, len(instrument.items) + 1):
                status = item_status(self.plan, planned, number)
                answers[status.item] = self.ask_item(status, log)
            given = self.given.setdefault(planned.name, {})
            given[planned.administration] = answers
            for note in write_questionnaire(out, self.plan.participant, instrument, given):
                if note.startswith(f"{planned.administration} "):  # an earlier administration's was logged then
                    log(note)
            answered = sum(answer is not None for answer in answers.values())
            log(f"{planned.administration}: {answered} of {len(answers)} items answered")

    def ask_item(self, status: TrialStatus, log: Callable[[str], None]) -> int | None:
        """The item's answer, or None when none on its scale came within the response timeout (`answer_item`)."""
        self.dialogue.publish_status(status)
        return answer_item(
            status,
            self.dialogue.inputs,
            lambda: self.dialogue.wait_for_input("answer"),
            lambda: self.dialogue.say(status),
            log,
            self.response_timeout,
        )
