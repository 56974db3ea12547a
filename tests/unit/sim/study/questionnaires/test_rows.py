"""sim.study.questionnaires.rows: answers and scores as tidy rows, and the CSV they are written to."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from sim.study.questionnaires.errors import QuestionnaireError
from sim.study.questionnaires.instruments import single_item, standard_instrument
from sim.study.questionnaires.rows import (
    AnswerRow,
    ScoreRow,
    answer_rows,
    asked_rows,
    read_answers,
    read_scores,
    score_rows,
    write_rows,
)

SSQ = standard_instrument("ssq")
SAFETY = single_item("perceived_safety", {"text": "Safe?", "scale": [1, 7], "labels": ["no", "yes"]})


def ssq_answers() -> dict[str, object]:
    answers: dict[str, object] = dict.fromkeys(SSQ.item_ids, 0)
    answers.update(nausea=3)  # N and D: raw 3 each, 6 in the total
    return answers


def test_answers_become_one_row_per_item_and_scores_one_per_subscale() -> None:
    rows = answer_rows(4, SSQ, "ssq_after_vr", ssq_answers())
    assert len(rows) == 16 and [row.item for row in rows] == list(SSQ.item_ids)
    assert rows[7] == AnswerRow(4, "ssq", "ssq_after_vr", "nausea", 3)
    assert {(row.participant, row.questionnaire, row.administration) for row in rows} == {(4, "ssq", "ssq_after_vr")}
    scored = score_rows(4, SSQ, "ssq_after_vr", ssq_answers())
    assert [row.subscale for row in scored] == ["nausea", "oculomotor", "disorientation", "total"]
    assert [row.score for row in scored] == pytest.approx([3 * 9.54, 0.0, 3 * 13.92, 6 * 3.74])
    assert score_rows(2, SAFETY, "perceived_safety_after_reality", {"perceived_safety": 6}) == [
        ScoreRow(2, "perceived_safety", "perceived_safety_after_reality", "perceived_safety", 6.0)
    ]


@pytest.mark.parametrize(
    "participant, administration, message",
    [
        (0, "ssq_after_vr", "participant number must be an integer >= 1, got 0"),
        (1, "ipq_after_vr", "the administration 'ipq_after_vr' of ssq must be ssq_<when>"),
        (1, "ssq after vr", "the administration 'ssq after vr' of ssq"),
    ],
)
def test_rows_name_a_real_participant_and_an_administration_of_their_questionnaire(
    participant: int, administration: str, message: str
) -> None:
    for rows in (answer_rows, score_rows):
        with pytest.raises(QuestionnaireError, match=message):
            rows(participant, SSQ, administration, ssq_answers())


def test_no_row_is_made_of_a_questionnaire_with_a_bad_answer() -> None:
    answers = ssq_answers()
    answers["vertigo"] = 5
    with pytest.raises(QuestionnaireError, match="item vertigo: the answer 5"):
        answer_rows(1, SSQ, "ssq_before_vr", answers)


def read(path: Path) -> list[list[str]]:
    with open(path, newline="") as source:
        return list(csv.reader(source))


def test_rows_are_written_whole_with_a_header_and_scores_without_float_noise(tmp_path: Path) -> None:
    path = tmp_path / "questionnaires" / "ssq_scores.csv"
    write_rows(path, score_rows(3, SSQ, "ssq_before_vr", ssq_answers()))
    assert read(path) == [
        ["participant", "questionnaire", "administration", "subscale", "score"],
        ["3", "ssq", "ssq_before_vr", "nausea", "28.62"],
        ["3", "ssq", "ssq_before_vr", "oculomotor", "0.0"],
        ["3", "ssq", "ssq_before_vr", "disorientation", "41.76"],
        ["3", "ssq", "ssq_before_vr", "total", "22.44"],
    ]
    write_rows(path.with_name("ssq_answers.csv"), answer_rows(3, SSQ, "ssq_before_vr", ssq_answers()))
    written = read(path.with_name("ssq_answers.csv"))
    assert written[0] == ["participant", "questionnaire", "administration", "item", "answer"]
    assert written[8] == ["3", "ssq", "ssq_before_vr", "nausea", "3"] and len(written) == 17
    assert sorted(p.name for p in path.parent.iterdir()) == ["ssq_answers.csv", "ssq_scores.csv"]  # no .partial


def test_rows_of_two_kinds_or_none_are_not_written(tmp_path: Path) -> None:
    mixed = [
        *answer_rows(1, SAFETY, "perceived_safety_after_vr", {"perceived_safety": 3}),
        *score_rows(1, SAFETY, "perceived_safety_after_vr", {"perceived_safety": 3}),
    ]
    for rows in (mixed, []):
        with pytest.raises(QuestionnaireError, match="rows must be all answers or all scores"):
            write_rows(tmp_path / "rows.csv", rows)
    assert not (tmp_path / "rows.csv").exists()


def test_a_session_records_an_item_asked_and_not_answered_as_an_empty_cell(tmp_path: Path) -> None:
    answers = {**ssq_answers(), "vertigo": None}
    del answers["burping"]
    rows = asked_rows(6, SSQ, "ssq_after_vr", answers)  # type: ignore[arg-type]
    assert [row.item for row in rows] == list(SSQ.item_ids)
    assert {row.item for row in rows if row.answer is None} == {"vertigo", "burping"}
    assert rows[7].answer == 3
    path = tmp_path / "ssq_participant_06.csv"
    write_rows(path, rows)
    assert ["6", "ssq", "ssq_after_vr", "vertigo", ""] in read(path)
    assert read_answers(path) == rows
    scored = score_rows(6, SSQ, "ssq_after_vr", ssq_answers())
    write_rows(tmp_path / "scores.csv", scored)
    assert read_scores(tmp_path / "scores.csv") == [
        ScoreRow(6, "ssq", "ssq_after_vr", row.subscale, pytest.approx(row.score)) for row in scored
    ]
    with pytest.raises(QuestionnaireError, match="item vertigo: the answer 4"):
        asked_rows(6, SSQ, "ssq_after_vr", {"vertigo": 4})
    with pytest.raises(QuestionnaireError, match="answers to no item"):
        asked_rows(6, SSQ, "ssq_after_vr", {"wellbeing": 1})


def test_a_csv_that_is_not_rows_of_its_kind_is_one_error(tmp_path: Path) -> None:
    path = tmp_path / "rows.csv"
    write_rows(path, score_rows(3, SSQ, "ssq_before_vr", ssq_answers()))
    with pytest.raises(QuestionnaireError, match="the header must be participant,questionnaire,administration,item"):
        read_answers(path)
    path.write_text(path.read_text().replace("28.62", "lots"))
    with pytest.raises(QuestionnaireError, match="line 2: '3' / 'lots' are not numbers"):
        read_scores(path)
    with pytest.raises(QuestionnaireError, match="cannot read"):
        read_scores(tmp_path / "none.csv")
