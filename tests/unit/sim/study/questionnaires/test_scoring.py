"""sim.study.questionnaires.scoring: worked examples scored by hand from the published keys (SSQ: Kennedy et al.
1993; IPQ: igroup.org), the scales' ends, and every answer that cannot be scored."""

from __future__ import annotations

import pytest

from sim.study.questionnaires.errors import QuestionnaireError
from sim.study.questionnaires.instruments import single_item, standard_instrument
from sim.study.questionnaires.scoring import checked_answers, item_score, raw_sums, scores

SSQ = standard_instrument("ssq")
IPQ = standard_instrument("ipq")


def ssq_answers(**given: int) -> dict[str, object]:
    return {item.id: given.get(item.id, 0) for item in SSQ.items}


def test_an_ssq_worked_example() -> None:
    answers = ssq_answers(
        general_discomfort=1,  # N, O
        fatigue=3,  # O
        eye_strain=1,  # O
        difficulty_focusing=1,  # O, D
        sweating=1,  # N
        nausea=2,  # N, D
        fullness_of_head=1,  # D
        dizzy_eyes_closed=1,  # D
        vertigo=2,  # D
        stomach_awareness=1,  # N
    )
    # N raw = general discomfort 1 + sweating 1 + nausea 2 + stomach awareness 1 = 5
    # O raw = general discomfort 1 + fatigue 3 + eye strain 1 + difficulty focusing 1 = 6
    # D raw = difficulty focusing 1 + nausea 2 + fullness of head 1 + dizzy (eyes closed) 1 + vertigo 2 = 7
    assert raw_sums(SSQ, answers) == {"nausea": 5, "oculomotor": 6, "disorientation": 7}
    # N = 5 x 9.54, O = 6 x 7.58, D = 7 x 13.92; total = (5 + 6 + 7) x 3.74
    assert scores(SSQ, answers) == pytest.approx(
        {"nausea": 47.70, "oculomotor": 45.48, "disorientation": 97.44, "total": 67.32}
    )
    assert list(scores(SSQ, answers)) == ["nausea", "oculomotor", "disorientation", "total"]


def test_the_ssqs_ends_none_at_all_and_every_symptom_severe() -> None:
    assert scores(SSQ, ssq_answers()) == {"nausea": 0.0, "oculomotor": 0.0, "disorientation": 0.0, "total": 0.0}
    # seven symptoms per cluster, each 3: raw 21 each, 63 in all
    worst = {item.id: 3 for item in SSQ.items}
    assert scores(SSQ, worst) == pytest.approx(
        {"nausea": 200.34, "oculomotor": 159.18, "disorientation": 292.32, "total": 235.62}
    )


def test_a_symptom_in_two_clusters_counts_in_both() -> None:
    # difficulty concentrating belongs to nausea and oculomotor: 2 there, and twice in the total's raw sum
    assert raw_sums(SSQ, ssq_answers(difficulty_concentrating=2)) == {"nausea": 2, "oculomotor": 2, "disorientation": 0}
    assert scores(SSQ, ssq_answers(difficulty_concentrating=2))["total"] == pytest.approx(4 * 3.74)


IPQ_EXAMPLE = {
    "G1": 5,
    "SP1": 4,
    "SP2": 1,  # reversed: 5
    "SP3": 6,
    "SP4": 3,
    "SP5": 2,
    "INV1": 2,
    "INV2": 3,
    "INV3": 5,  # reversed: 1
    "INV4": 6,
    "REAL1": 0,  # reversed: 6
    "REAL2": 3,
    "REAL3": 1,
    "REAL4": 4,
}


def test_an_ipq_worked_example_with_its_reversed_items() -> None:
    # general presence = G1 = 5
    # spatial presence = (4 + (6 - 1) + 6 + 3 + 2) / 5 = 20 / 5 = 4
    # involvement = (2 + 3 + (6 - 5) + 6) / 4 = 12 / 4 = 3
    # experienced realism = ((6 - 0) + 3 + 1 + 4) / 4 = 14 / 4 = 3.5
    assert scores(IPQ, IPQ_EXAMPLE) == {
        "general_presence": 5.0,
        "spatial_presence": 4.0,
        "involvement": 3.0,
        "experienced_realism": 3.5,
    }


def test_the_ipqs_ends_count_the_reversed_items_the_other_way() -> None:
    # all 0: only SP2, INV3 and REAL1 score 6 -> spatial 6/5, involvement 6/4, realism 6/4
    assert scores(IPQ, dict.fromkeys(IPQ.item_ids, 0)) == {
        "general_presence": 0.0,
        "spatial_presence": 1.2,
        "involvement": 1.5,
        "experienced_realism": 1.5,
    }
    # all 6: those three score 0 -> spatial 24/5, involvement 18/4, realism 18/4
    assert scores(IPQ, dict.fromkeys(IPQ.item_ids, 6)) == {
        "general_presence": 6.0,
        "spatial_presence": 4.8,
        "involvement": 4.5,
        "experienced_realism": 4.5,
    }
    assert item_score(IPQ.item("SP2"), 2) == 4 and item_score(IPQ.item("SP1"), 2) == 2


def test_a_single_item_scores_its_answer_on_its_own_scale() -> None:
    safety = single_item("perceived_safety", {"text": "Safe?", "scale": [1, 7], "labels": ["no", "yes"]})
    assert scores(safety, {"perceived_safety": 1}) == {"perceived_safety": 1.0}
    assert scores(safety, {"perceived_safety": 7}) == {"perceived_safety": 7.0}
    with pytest.raises(QuestionnaireError, match=r"item perceived_safety: the answer 0 is not a whole number of 1..7"):
        scores(safety, {"perceived_safety": 0})


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda a: a.pop("vertigo"), "ssq: item vertigo has no answer"),
        (lambda a: a.update(vertigo=4), "ssq: item vertigo: the answer 4 is not a whole number of 0..3"),
        (lambda a: a.update(fatigue=-1), "item fatigue: the answer -1 is not"),
        (lambda a: a.update(burping=1.0), "item burping: the answer 1.0 is not"),
        (lambda a: a.update(burping=True), "item burping: the answer True is not"),
        (lambda a: a.update(burping=None), "item burping: the answer None is not"),
        (lambda a: a.update(burping="2"), "item burping: the answer '2' is not"),
        (lambda a: a.update(G1=3), r"ssq: answers to no item \['G1'\]"),
    ],
)
def test_an_answer_that_cannot_be_scored_names_the_item_and_the_value(change, message) -> None:
    answers = ssq_answers()
    change(answers)
    for score in (checked_answers, raw_sums, scores):
        with pytest.raises(QuestionnaireError, match=message):
            score(SSQ, answers)


def test_answers_are_given_back_in_the_instruments_order() -> None:
    answers = dict(reversed(list(IPQ_EXAMPLE.items())))
    assert list(checked_answers(IPQ, answers)) == list(IPQ.item_ids)
