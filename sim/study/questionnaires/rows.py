"""Answers and scores as tidy rows, one value per row, ready for a CSV per questionnaire: the answers as given
(participant, questionnaire, administration, item, answer) and the scores made of them (participant, questionnaire,
administration, subscale, score). An administration names one asking of a questionnaire in a session, e.g.
ssq_before_vr. Pure logic, but for `write_rows`."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from dataclasses import astuple, dataclass, fields
from pathlib import Path
from typing import Union

from sim.study.questionnaires.errors import QuestionnaireError
from sim.study.questionnaires.instruments import Instrument, is_name
from sim.study.questionnaires.scoring import checked_answers, scores

__all__ = ["AnswerRow", "ScoreRow", "answer_rows", "score_rows", "write_rows"]


@dataclass(frozen=True)
class AnswerRow:
    participant: int
    questionnaire: str
    administration: str
    item: str
    answer: int  # as given, before any reversal


@dataclass(frozen=True)
class ScoreRow:
    participant: int
    questionnaire: str
    administration: str
    subscale: str  # a subscale's id, or the total's
    score: float


def _check(participant: int, instrument: Instrument, administration: str) -> None:
    if not (isinstance(participant, int) and not isinstance(participant, bool) and participant >= 1):
        raise QuestionnaireError(f"the participant number must be an integer >= 1, got {participant!r}")
    # the administration is a column value and part of file names: it must name the questionnaire it is of
    if not (is_name(administration) and administration.startswith(f"{instrument.name}_")):
        raise QuestionnaireError(
            f"the administration {administration!r} of {instrument.name} must be {instrument.name}_<when> "
            "in lower case letters, digits and _"
        )


def answer_rows(
    participant: int, instrument: Instrument, administration: str, answers: Mapping[str, object]
) -> list[AnswerRow]:
    """One row per item, in the instrument's order; every answer checked as scoring checks it."""
    _check(participant, instrument, administration)
    checked = checked_answers(instrument, answers)
    return [AnswerRow(participant, instrument.name, administration, item, answer) for item, answer in checked.items()]


def score_rows(
    participant: int, instrument: Instrument, administration: str, answers: Mapping[str, object]
) -> list[ScoreRow]:
    """One row per score, in `instrument.score_ids` order."""
    _check(participant, instrument, administration)
    return [
        ScoreRow(participant, instrument.name, administration, subscale, score)
        for subscale, score in scores(instrument, answers).items()
    ]


Row = Union[AnswerRow, ScoreRow]


def _text(value: object) -> str:
    # a score to six decimals: the weights have two and answers are whole, so nothing real is lost, and
    # 3 x 9.54 reads 28.62, not 28.619999999999997
    return repr(round(value, 6)) if isinstance(value, float) else str(value)


def write_rows(path: Path, rows: Sequence[Row]) -> None:
    """Write rows of one kind as a CSV with a header, at once (a temporary file, then renamed): a reader never
    sees half of it."""
    kinds = {type(row) for row in rows}
    if len(kinds) != 1:
        raise QuestionnaireError(f"{path}: rows must be all answers or all scores, and some, got {len(rows)} rows")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    with open(partial, "w", newline="") as out:
        writer = csv.writer(out)
        writer.writerow([field.name for field in fields(kinds.pop())])
        for row in rows:
            writer.writerow([_text(value) for value in astuple(row)])
    partial.replace(path)
