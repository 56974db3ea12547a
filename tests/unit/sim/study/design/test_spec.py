"""sim.study.design.spec's questionnaires: the bundled design asks the SSQ before and after VR, the IPQ after VR and
the lab's perceived-safety item after each condition; a bad questionnaires section is one DesignError naming the
bad key or value. (The tests' sections are checked in test_plan.py.)"""

from __future__ import annotations

import copy

import pytest
import yaml

from sim.study.design.errors import DesignError
from sim.study.design.spec import CONDITIONS, DEFAULT_DESIGN, WHEN, load_design, parse_design
from sim.study.questionnaires.instruments import STANDARD, standard_instrument

DATA = yaml.safe_load(DEFAULT_DESIGN.read_text())


def test_the_bundled_design_declares_the_issues_questionnaires() -> None:
    declared = {q.instrument.name: q for q in load_design().questionnaires}
    assert list(declared) == ["ssq", "ipq", "perceived_safety"]  # the order asked where they share a point
    assert declared["ssq"].placements == (("vr", "before"), ("vr", "after"))
    assert declared["ipq"].placements == (("vr", "after"),)
    assert declared["perceived_safety"].when == ("after_each",)
    assert declared["perceived_safety"].placements == (("vr", "after"), ("reality", "after"))
    safety = declared["perceived_safety"].instrument.items[0]
    assert (safety.low, safety.high, safety.label(1), safety.label(7)) == (1, 7, "not at all safe", "completely safe")
    assert declared["ssq"].instrument == standard_instrument("ssq")


def test_when_words_stand_for_before_or_after_one_conditions_block_or_each() -> None:
    assert sorted(WHEN) == sorted(
        ["before_vr", "after_vr", "before_reality", "after_reality", "before_each", "after_each"]
    )
    assert WHEN["before_each"] == (("vr", "before"), ("reality", "before"))
    # every bundled instrument is for conditions the design has
    assert all(set(standard_instrument(name).conditions) <= set(CONDITIONS) for name in STANDARD)


def test_questionnaires_are_optional_and_may_be_empty() -> None:
    data = copy.deepcopy(DATA)
    del data["questionnaires"]
    assert parse_design(data).questionnaires == ()
    data["questionnaires"] = {"ipq": {"when": ["after_vr"]}}
    assert [q.instrument.name for q in parse_design(data).questionnaires] == ["ipq"]
    data["questionnaires"] = {}
    assert parse_design(data).questionnaires == ()


def with_change(change) -> dict:
    data = copy.deepcopy(DATA)
    change(data)
    return data


def safety(data: dict) -> dict:
    return data["questionnaires"]["items"]["perceived_safety"]


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d.update(test3={}), r"unknown \['test3'\]; it has test1, test2 and optionally planning"),
        (lambda d: d.update(questionaires={}), r"unknown \['questionaires'\]"),
        (lambda d: d.pop("test2"), "must have test1, test2 and optionally planning, questionnaires"),
        (lambda d: d.update(questionnaires=["ssq"]), "questionnaires must map ssq, ipq, items to when"),
        (lambda d: d["questionnaires"].update(nasa_tlx={"when": ["after_vr"]}), r"unknown \['nasa_tlx'\]"),
        (lambda d: d["questionnaires"]["ssq"].update(order="random"), "questionnaires.ssq must have exactly when"),
        (lambda d: d["questionnaires"].update(ssq={"when": ["during_vr"]}), r"ssq.when: unknown \['during_vr'\]"),
        (lambda d: d["questionnaires"].update(ssq={"when": []}), "ssq.when must be a non-empty list of before_vr"),
        (lambda d: d["questionnaires"].update(ssq={"when": "after_vr"}), "ssq.when must be a non-empty list"),
        (
            lambda d: d["questionnaires"].update(ipq={"when": ["after_each"]}),
            "ipq.when asks ipq in reality; it is for vr only",
        ),
        (
            lambda d: safety(d).update(when=["after_vr", "after_each"]),
            "perceived_safety.when asks perceived_safety twice at the same point",
        ),
        (lambda d: safety(d).pop("when"), "items.perceived_safety must have text, scale, labels and when"),
        (lambda d: safety(d).update(labels=["not at all safe"]), "perceived_safety.labels as a list must be"),
        (lambda d: safety(d).update(scale=[1, 70]), r"perceived_safety.scale must have 2..11 points"),
        (lambda d: safety(d).update(points=7), r"perceived_safety: unknown \['points'\]"),
        (lambda d: d["questionnaires"]["items"].update(ssq=safety(d)), "items: ssq: an item's name must be"),
        (lambda d: d["questionnaires"].update(items=["perceived_safety"]), "items must map item names"),
    ],
)
def test_a_bad_questionnaires_section_is_one_design_error_naming_it(change, message) -> None:
    with pytest.raises(DesignError, match=message):
        parse_design(with_change(change))
