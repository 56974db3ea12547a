"""sim.study.run.questionnaires: where the plan's questionnaires are asked, the status asking each item, and the
records an administration leaves (answers as given, missing ones empty; scores only of a whole one)."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from sim.study.design.plan import make_plan
from sim.study.design.spec import load_design
from sim.study.questionnaires.rows import read_answers, read_scores
from sim.study.questionnaires.scoring import scores
from sim.study.run.errors import RunError
from sim.study.run.protocol import status_from_json, status_to_json
from sim.study.run.questionnaires import (
    answers_path,
    asked_after,
    item_status,
    questionnaire_rows,
    scores_path,
    write_questionnaire,
)

PLAN = make_plan(load_design(), 3, 1)  # the bundled design; participant 3 starts with VR
SSQ = PLAN.instrument("ssq")


def test_each_questionnaire_is_asked_once_at_its_place() -> None:
    last_vr = max(t.index for t in PLAN.trials if t.condition == "vr")
    assert [q.administration for q in asked_after(PLAN, 0)] == ["ssq_before_vr"]
    assert [q.administration for q in asked_after(PLAN, last_vr)] == [
        "ssq_after_vr",
        "ipq_after_vr",
        "perceived_safety_after_vr",
    ]
    assert [q.administration for q in asked_after(PLAN, len(PLAN.trials))] == ["perceived_safety_after_reality"]
    assert asked_after(PLAN, 1) == ()
    everywhere = [q for k in range(len(PLAN.trials) + 1) for q in asked_after(PLAN, k)]
    assert everywhere == list(PLAN.questionnaires)


def test_an_items_status_says_the_item_its_scale_and_its_place() -> None:
    ipq = next(q for q in PLAN.questionnaires if q.name == "ipq")
    instrument = PLAN.instrument("ipq")
    status = item_status(PLAN, ipq, 3)
    item = instrument.items[2]
    assert (status.participant, status.index, status.total, status.phase) == (3, ipq.after_trial, 38, "questionnaire")
    assert (status.condition, status.administration, status.questionnaire) == ("vr", "ipq_after_vr", "ipq")
    assert (status.item, status.item_text, status.item_number, status.item_count) == (item.id, item.text, 3, 14)
    assert (status.scale_low, status.scale_high) == (0, 6) and len(status.scale_labels) == 7
    assert (status.scale_labels[0], status.scale_labels[-1]) == (item.label(0), item.label(6)) != ("", "")
    assert status_from_json(status_to_json(status)) == status
    safety = item_status(PLAN, PLAN.questionnaires[-1], 1)
    assert (safety.scale_low, safety.scale_high, safety.item_count) == (1, 7, 1)
    assert safety.scale_labels == ("not at all safe", "", "", "", "", "", "completely safe")
    for number in (0, 2):
        with pytest.raises(RunError, match=f"perceived_safety_after_reality has items 1..1, not {number}"):
            item_status(PLAN, PLAN.questionnaires[-1], number)


def test_a_whole_administration_is_scored_and_one_with_a_missing_item_only_recorded() -> None:
    before = {item: 1 for item in SSQ.item_ids}
    after = {**{item: 2 for item in SSQ.item_ids}, "vertigo": None}
    answers, scored, notes = questionnaire_rows(3, SSQ, {"ssq_before_vr": before, "ssq_after_vr": after})
    assert len(answers) == 32 and [row.answer for row in answers].count(None) == 1
    assert {row.administration for row in scored} == {"ssq_before_vr"}
    assert {row.subscale: row.score for row in scored} == pytest.approx(scores(SSQ, before))
    assert notes == ["ssq_after_vr not scored: no answer to vertigo"]


def test_the_records_are_written_per_questionnaire_in_folders_of_their_own(tmp_path: Path) -> None:
    before = {item: 0 for item in SSQ.item_ids}
    assert write_questionnaire(tmp_path, 3, SSQ, {"ssq_before_vr": before}) == []
    answers, scored = answers_path(tmp_path, "ssq", 3), scores_path(tmp_path, "ssq", 3)
    assert answers == tmp_path / "questionnaires" / "answers" / "ssq_participant_03.csv"
    assert scored == tmp_path / "questionnaires" / "scores" / "ssq_participant_03.csv"
    assert len(read_answers(answers)) == 16 and len(read_scores(scored)) == 4
    after = {item: 3 for item in SSQ.item_ids}
    assert write_questionnaire(tmp_path, 3, SSQ, {"ssq_before_vr": before, "ssq_after_vr": after}) == []
    rows = read_scores(scored)
    assert [(row.administration, row.subscale) for row in rows][-1] == ("ssq_after_vr", "total")
    assert rows[-1].score == pytest.approx(235.62)
    with open(answers, newline="") as source:
        assert len(list(csv.reader(source))) == 33  # a header and both administrations' items
    nothing = {item: None for item in SSQ.item_ids}
    notes = write_questionnaire(tmp_path / "other", 4, SSQ, {"ssq_before_vr": nothing})
    assert notes and not scores_path(tmp_path / "other", "ssq", 4).exists()
    assert all(row.answer is None for row in read_answers(answers_path(tmp_path / "other", "ssq", 4)))
