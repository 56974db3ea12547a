"""Scoring by the instruments' published keys. Pure logic.

- SSQ (rule weighted_sum): each cluster's raw score is the sum of its symptoms' answers, a symptom counting in each
  cluster it belongs to; the cluster's score is its weight x that sum (Nausea 9.54, Oculomotor 7.58,
  Disorientation 13.92), the total 3.74 x the sum of the three raw sums (Kennedy et al. 1993).
- IPQ (rule mean): each subscale's score is the mean of its items' scores, a reversed item scoring 6 - answer;
  General presence is its one item, G1 (Schubert, Friedmann & Regenbrecht 2001).
- a single item of the lab's own (rule mean): its answer.

Every answer is checked first: an item without an answer, an answer to no item, or an answer off the item's scale
is a QuestionnaireError naming the item and the value, so that no score is ever made of part of a questionnaire.
"""

from __future__ import annotations

from collections.abc import Mapping

from sim.study.questionnaires.errors import QuestionnaireError
from sim.study.questionnaires.instruments import Instrument, Item

__all__ = ["checked_answers", "checked_answer", "item_score", "raw_sums", "scores"]


def checked_answers(instrument: Instrument, answers: Mapping[str, object]) -> dict[str, int]:
    """Every item's answer, in the instrument's order; QuestionnaireError for a missing, unknown or out-of-range
    one (a bool or a float is no answer: a scale's points are whole numbers)."""
    unknown = [key for key in answers if key not in instrument.item_ids]
    if unknown:
        raise QuestionnaireError(
            f"{instrument.name}: answers to no item {unknown}; its items: {', '.join(instrument.item_ids)}"
        )
    checked = {}
    for item in instrument.items:
        if item.id not in answers:
            raise QuestionnaireError(f"{instrument.name}: item {item.id} has no answer")
        checked[item.id] = checked_answer(instrument, item, answers[item.id])
    return checked


def checked_answer(instrument: Instrument, item: Item, answer: object) -> int:
    """One item's answer; QuestionnaireError when it is not a whole number on the item's scale."""
    if not (isinstance(answer, int) and not isinstance(answer, bool) and item.low <= answer <= item.high):
        raise QuestionnaireError(
            f"{instrument.name}: item {item.id}: the answer {answer!r} is not a whole number of {item.low}..{item.high}"
        )
    return answer


def item_score(item: Item, answer: int) -> int:
    """The answer as it counts: a reversed item's is mirrored on its scale (on the IPQ's 0..6, 6 - answer)."""
    return item.low + item.high - answer if item.reversed else answer


def raw_sums(instrument: Instrument, answers: Mapping[str, object]) -> dict[str, int]:
    """Each subscale's sum of its items' scores (the SSQ's raw cluster scores)."""
    checked = checked_answers(instrument, answers)
    sums = {subscale.id: 0 for subscale in instrument.subscales}
    for item in instrument.items:
        for subscale in item.subscales:
            sums[subscale] += item_score(item, checked[item.id])
    return sums


def scores(instrument: Instrument, answers: Mapping[str, object]) -> dict[str, float]:
    """The instrument's scores by its rule, in `instrument.score_ids` order."""
    sums = raw_sums(instrument, answers)
    if instrument.rule == "mean":
        counts = {s.id: sum(s.id in item.subscales for item in instrument.items) for s in instrument.subscales}
        return {name: total / counts[name] for name, total in sums.items()}
    # weighted_sum: the weights put the clusters on comparable scales; the total weighs the raw sums, not the
    # weighted scores, which is how the published key defines it
    result = {s.id: s.weight * sums[s.id] for s in instrument.subscales}
    if instrument.total is not None:
        result[instrument.total.id] = instrument.total.weight * sum(sums.values())
    return result
