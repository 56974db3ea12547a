"""The plan's questionnaires in a session: which are asked where, the status that asks each item, and the records
they leave. Pure logic, but for `write_questionnaire`.

The runner asks each planned questionnaire at its place (after the trial it follows; 0: before the first), one
item at a time, in the instrument's order. Per questionnaire and participant, two tidy CSVs in the session's output
folder, rewritten whole as soon as an administration of it ends (so a crash loses at most the one being asked):
  questionnaires/answers/<name>_participant_XX.csv  every item asked, one row each; an empty answer: not answered
  questionnaires/scores/<name>_participant_XX.csv   the scores by the published key, of each administration with
                                                    every item answered (no score is made of part of one)
Folders of their own, because a lab's own item may have any name: no name can make one kind's file look like the
other's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Optional

from sim.study.design.plan import PlannedQuestionnaire, SessionPlan
from sim.study.questionnaires.instruments import Instrument
from sim.study.questionnaires.rows import AnswerRow, ScoreRow, asked_rows, score_rows, write_rows
from sim.study.run.errors import RunError
from sim.study.run.protocol import TrialStatus

__all__ = [
    "FOLDER",
    "Given",
    "asked_after",
    "item_status",
    "answers_path",
    "scores_path",
    "questionnaire_rows",
    "write_questionnaire",
]

FOLDER = "questionnaires"  # in the session's output folder
# per administration of one questionnaire, each item's answer as given (None: asked and not answered); typing's
# Mapping, as collections.abc's cannot be subscripted at run time on Python 3.8
Given = Mapping[str, Mapping[str, Optional[int]]]


def asked_after(plan: SessionPlan, after_trial: int) -> tuple[PlannedQuestionnaire, ...]:
    """The questionnaires asked once trial `after_trial` has ended (0: before the first trial), in the plan's
    order."""
    return tuple(q for q in plan.questionnaires if q.after_trial == after_trial)


def item_status(plan: SessionPlan, planned: PlannedQuestionnaire, number: int) -> TrialStatus:
    """The status that asks item `number` (1-based) of `planned`: the item's text, scale and labels, k of n. Its
    index is the trial the questionnaire follows (0 before the first), its condition the block it is asked
    around."""
    instrument = plan.instrument(planned.name)
    if not 1 <= number <= len(instrument.items):
        raise RunError(f"{planned.administration} has items 1..{len(instrument.items)}, not {number}")
    item = instrument.items[number - 1]
    return TrialStatus(
        plan.participant,
        planned.after_trial,
        len(plan.trials),
        "questionnaire",
        planned.condition,
        administration=planned.administration,
        questionnaire=planned.name,
        item=item.id,
        item_text=item.text,
        item_number=number,
        item_count=len(instrument.items),
        scale_low=item.low,
        scale_high=item.high,
        scale_labels=tuple(item.label(answer) for answer in range(item.low, item.high + 1)),
    )


def answers_path(out: Path, name: str, participant: int) -> Path:
    return Path(out) / FOLDER / "answers" / f"{name}_participant_{participant:02d}.csv"


def scores_path(out: Path, name: str, participant: int) -> Path:
    return Path(out) / FOLDER / "scores" / f"{name}_participant_{participant:02d}.csv"


def questionnaire_rows(
    participant: int, instrument: Instrument, given: Given
) -> tuple[list[AnswerRow], list[ScoreRow], list[str]]:
    """The answer rows of every administration given, the score rows of those with every item answered, and a note
    for each that is not scored (which items are missing)."""
    answers: list[AnswerRow] = []
    scored: list[ScoreRow] = []
    notes: list[str] = []
    for administration, items in given.items():
        answers += asked_rows(participant, instrument, administration, items)
        complete: dict[str, int] = {item: answer for item, answer in items.items() if answer is not None}
        missing = [item for item in instrument.item_ids if item not in complete]
        if missing:
            notes.append(f"{administration} not scored: no answer to {', '.join(missing)}")
        else:
            scored += score_rows(participant, instrument, administration, complete)
    return answers, scored, notes


def write_questionnaire(out: Path, participant: int, instrument: Instrument, given: Given) -> list[str]:
    """Write the questionnaire's answers and scores CSVs (every administration given so far); the notes of
    `questionnaire_rows`. Nothing is written of a questionnaire with no administration given."""
    answers, scored, notes = questionnaire_rows(participant, instrument, given)
    if answers:
        write_rows(answers_path(out, instrument.name, participant), answers)
    if scored:
        write_rows(scores_path(out, instrument.name, participant), scored)
    return notes
