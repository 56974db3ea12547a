"""Answers and scores as tidy rows, one value per row, ready for a CSV per questionnaire: the answers as given
(participant, questionnaire, administration, item, answer) and the scores made of them (participant, questionnaire,
administration, subscale, score). An administration names one asking of a questionnaire in a session, e.g.
ssq_before_vr. Pure logic, but for `write_rows` and the readers."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from dataclasses import astuple, dataclass, fields
from pathlib import Path
from typing import Union

from sim.study.questionnaires.errors import QuestionnaireError
from sim.study.questionnaires.instruments import Instrument, is_name
from sim.study.questionnaires.scoring import checked_answer, checked_answers, scores

__all__ = [
    "AnswerRow",
    "ScoreRow",
    "answer_rows",
    "asked_rows",
    "score_rows",
    "write_rows",
    "read_answers",
    "read_scores",
]


@dataclass(frozen=True)
class AnswerRow:
    participant: int
    questionnaire: str
    administration: str
    item: str
    answer: int | None  # as given, before any reversal; None (an empty cell): asked and not answered


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


def asked_rows(
    participant: int, instrument: Instrument, administration: str, answers: Mapping[str, int | None]
) -> list[AnswerRow]:
    """One row per item, in the instrument's order, as a session asked them: an item without an answer (absent or
    None) is a row without one, so that the record shows what was asked and missed, and nothing is made up for it.
    Every answer given is checked as scoring checks it."""
    _check(participant, instrument, administration)
    unknown = [key for key in answers if key not in instrument.item_ids]
    if unknown:
        raise QuestionnaireError(
            f"{instrument.name}: answers to no item {unknown}; its items: {', '.join(instrument.item_ids)}"
        )
    rows = []
    for item in instrument.items:
        given = answers.get(item.id)
        answer = None if given is None else checked_answer(instrument, item, given)
        rows.append(AnswerRow(participant, instrument.name, administration, item.id, answer))
    return rows


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
    # 3 x 9.54 reads 28.62, not 28.619999999999997; a missing answer is an empty cell
    if value is None:
        return ""
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


def _read(path: Path, kind: type) -> list[list[str]]:
    """The rows of a CSV that `write_rows` wrote of `kind`, as texts; QuestionnaireError when it is not one."""
    names = [field.name for field in fields(kind)]
    try:
        with open(path, newline="") as source:
            lines = list(csv.reader(source))
    except OSError as error:
        raise QuestionnaireError(f"cannot read {path}: {error.strerror}") from None
    if not lines or lines[0] != names:
        raise QuestionnaireError(f"{path}: the header must be {','.join(names)}, got {lines[0] if lines else []}")
    for number, line in enumerate(lines[1:], start=2):
        if len(line) != len(names):
            raise QuestionnaireError(f"{path}: line {number} has {len(line)} cells, not {len(names)}")
    return lines[1:]


def read_answers(path: Path) -> list[AnswerRow]:
    """An answers CSV as written; an empty answer is None (asked and not answered)."""
    rows = []
    for number, (participant, questionnaire, administration, item, answer) in enumerate(_read(path, AnswerRow), 2):
        try:
            rows.append(
                AnswerRow(int(participant), questionnaire, administration, item, int(answer) if answer else None)
            )
        except ValueError:
            raise QuestionnaireError(f"{path}: line {number}: {participant!r} / {answer!r} are not numbers") from None
    return rows


def read_scores(path: Path) -> list[ScoreRow]:
    """A scores CSV as written."""
    rows = []
    for number, (participant, questionnaire, administration, subscale, score) in enumerate(_read(path, ScoreRow), 2):
        try:
            rows.append(ScoreRow(int(participant), questionnaire, administration, subscale, float(score)))
        except ValueError:
            raise QuestionnaireError(f"{path}: line {number}: {participant!r} / {score!r} are not numbers") from None
    return rows
