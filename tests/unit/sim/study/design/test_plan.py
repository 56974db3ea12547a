"""sim.study.design.spec and sim.study.design.plan: the session plan has the proposal's 38 trials, balanced and
randomised as it says, reproducible from the seed, with the design's questionnaires before and after the blocks,
round-trips through YAML; bad designs and malformed plans are one DesignError."""

from __future__ import annotations

import copy
from collections import Counter
from dataclasses import replace

import pytest
import yaml

from sim.study.design.paths import ON_TOP
from sim.study.design.plan import (
    PlannedQuestionnaire,
    condition_order,
    make_plan,
    plan_from_data,
    plan_to_data,
    printable,
)
from sim.study.design.spec import DEFAULT_DESIGN, load_design, parse_design
from sim.study.errors import StudyError
from sim.study.questionnaires.instruments import standard_instrument

DESIGN = load_design()


def test_the_bundled_design_gives_the_proposals_38_trials():
    assert DESIGN.trials_per_participant == 38
    assert len(make_plan(DESIGN, 1, 0).trials) == 38


@pytest.mark.parametrize("participant", [1, 2, 7])
def test_each_condition_has_every_combination_once_and_groups_of_three_per_speed_set(participant):
    plan = make_plan(DESIGN, participant, seed=11)
    assert [trial.index for trial in plan.trials] == list(range(1, 39))
    combinations = {(path, standoff) for path in DESIGN.test1_paths for standoff in DESIGN.test1_standoffs}
    for condition in plan.conditions:
        mine = [trial for trial in plan.trials if trial.condition == condition]
        assert [trial.test for trial in mine] == [1] * 10 + [2] * 9  # test 1 first, then test 2
        assert Counter((t.path, t.standoff) for t in mine if t.test == 1) == Counter(combinations)
        groups = plan.groups(condition)
        assert sorted(group[0].speed_set for group in groups) == sorted(name for name, _ in DESIGN.test2_speed_sets)
        for group in groups:
            assert sorted(t.path for t in group) == sorted(DESIGN.test2_paths)
            assert len({(t.speed_set, t.peak_speed) for t in group}) == 1 and all(t.standoff == ON_TOP for t in group)
    # the conditions run one after the other, not interleaved
    assert [t.condition for t in plan.trials] == [plan.conditions[0]] * 19 + [plan.conditions[1]] * 19


def test_half_the_participants_start_with_vr():
    starts = Counter(make_plan(DESIGN, participant, 3).conditions[0] for participant in range(1, 13))
    assert starts == {"vr": 6, "reality": 6}
    assert condition_order(1) == ("vr", "reality") and condition_order(2) == ("reality", "vr")


def test_orders_are_random_per_condition_and_participant_and_reproducible_from_the_seed():
    def test1_order(plan, condition):
        return [(t.path, t.standoff) for t in plan.trials if t.condition == condition and t.test == 1]

    plans = [make_plan(DESIGN, participant, 5) for participant in range(1, 13)]
    assert sum(test1_order(plan, "vr") != test1_order(plan, "reality") for plan in plans) >= 10
    assert len({tuple(test1_order(plan, "vr")) for plan in plans}) >= 10
    assert make_plan(DESIGN, 4, 5) == make_plan(DESIGN, 4, 5)
    assert make_plan(DESIGN, 4, 5) != make_plan(DESIGN, 4, 6)


def test_questionnaires_add_no_draws_so_trial_orders_stay_those_of_earlier_plans():
    # participant 2, seed 7, as plans made before there were questionnaires had it
    plan = make_plan(DESIGN, 2, 7)
    assert [(t.path, t.standoff) for t in plan.trials if t.test == 1][:10] == [
        ("straight", 0.1),
        ("vertical", 0.05),
        ("straight", 0.2),
        ("straight", 0.25),
        ("vertical", 0.1),
        ("vertical", 0.25),
        ("straight", 0.05),
        ("vertical", 0.2),
        ("straight", 0.15),
        ("vertical", 0.15),
    ]
    assert [(t.path, t.speed_set) for t in plan.trials if t.test == 2][:3] == [
        ("straight", "medium"),
        ("over_the_top", "medium"),
        ("lateral_arc", "medium"),
    ]
    assert plan.trials == make_plan(replace(DESIGN, questionnaires=()), 2, 7).trials


def test_the_questionnaires_are_placed_before_and_after_the_blocks_in_the_order_run():
    def placed(participant):
        return [(q.administration, q.after_trial) for q in make_plan(DESIGN, participant, 1).questionnaires]

    # VR first: its block is trials 1..19, reality's 20..38
    assert placed(1) == [
        ("ssq_before_vr", 0),
        ("ssq_after_vr", 19),
        ("ipq_after_vr", 19),
        ("perceived_safety_after_vr", 19),
        ("perceived_safety_after_reality", 38),
    ]
    # reality first: what follows its block comes before what precedes VR's
    assert placed(2) == [
        ("perceived_safety_after_reality", 19),
        ("ssq_before_vr", 19),
        ("ssq_after_vr", 38),
        ("ipq_after_vr", 38),
        ("perceived_safety_after_vr", 38),
    ]
    plan = make_plan(DESIGN, 2, 1)
    assert plan.questionnaires[1] == PlannedQuestionnaire(2, "ssq", "ssq_before_vr", "vr", "before", 19)
    assert [q.index for q in plan.questionnaires] == [1, 2, 3, 4, 5]
    # the plan carries the lab's own items, so it alone says what to ask
    assert [item.name for item in plan.items] == ["perceived_safety"]
    assert plan.instrument("perceived_safety").items[0].label(7) == "completely safe"
    assert plan.instrument("ipq") == standard_instrument("ipq")
    with pytest.raises(StudyError, match="the plan asks no questionnaire 'sus'; known: ssq, ipq, perceived_safety"):
        plan.instrument("sus")


def test_the_ssq_is_asked_first_where_several_share_a_point_whatever_the_declared_order():
    """Simulator sickness fades within minutes of leaving the headset: the SSQ after VR comes before the IPQ and the
    lab's items even where a design declares it last; the others keep the declared order."""
    data = copy.deepcopy(yaml.safe_load(DEFAULT_DESIGN.read_text()))
    bundled = data["questionnaires"]
    data["questionnaires"] = {"items": bundled["items"], "ipq": bundled["ipq"], "ssq": bundled["ssq"]}
    design = parse_design(data)
    assert [q.instrument.name for q in design.questionnaires] == ["perceived_safety", "ipq", "ssq"]
    plan = make_plan(design, 1, 1)
    assert [(q.administration, q.after_trial) for q in plan.questionnaires] == [
        ("ssq_before_vr", 0),
        ("ssq_after_vr", 19),
        ("perceived_safety_after_vr", 19),
        ("ipq_after_vr", 19),
        ("perceived_safety_after_reality", 38),
    ]
    assert [q.index for q in plan.questionnaires] == [1, 2, 3, 4, 5]
    assert plan.trials == make_plan(DESIGN, 1, 1).trials  # placing draws nothing
    assert plan_from_data(plan_to_data(plan)) == plan


def test_before_each_asks_at_the_start_of_both_blocks_and_no_questionnaires_is_none():
    data = copy.deepcopy(yaml.safe_load(DEFAULT_DESIGN.read_text()))
    data["questionnaires"] = {"ssq": {"when": ["before_each", "after_each"]}}
    plan = make_plan(parse_design(data), 1, 1)
    assert [(q.administration, q.after_trial) for q in plan.questionnaires] == [
        ("ssq_before_vr", 0),
        ("ssq_after_vr", 19),
        ("ssq_before_reality", 19),
        ("ssq_after_reality", 38),
    ]
    assert "2. ssq_after_vr: Simulator Sickness Questionnaire, 16 items, after trial 19" in printable(plan)
    assert "3. ssq_before_reality: Simulator Sickness Questionnaire, 16 items, before trial 20" in printable(plan)
    assert plan.items == ()
    bare = make_plan(replace(DESIGN, questionnaires=()), 1, 1)
    assert bare.questionnaires == () and bare.items == () and "Questionnaires" not in printable(bare)
    assert plan_from_data(plan_to_data(bare)) == bare


def test_the_plan_round_trips_through_yaml_and_prints_every_trial_and_questionnaire():
    plan = make_plan(DESIGN, 5, 9)
    assert plan_from_data(yaml.safe_load(yaml.safe_dump(plan_to_data(plan)))) == plan
    assert len(plan.questionnaires) == 5 and len(plan.items) == 1
    text = printable(plan)
    assert "participant 5 (seed 9)" in text and text.count("\n| ") == 38 + 1  # header + one row per trial
    assert "on the hand" in text and "5 cm" in text
    assert text.index("| 38 |") < text.index(
        "1. ssq_before_vr: Simulator Sickness Questionnaire, 16 items, before trial 1"
    )
    assert "4. perceived_safety_after_vr: How safe did you feel near the robot?, 1 item, after trial 19" in text


def malformed(change):
    data = plan_to_data(make_plan(DESIGN, 2, 1))
    change(data)
    return data


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d.pop("seed"), "must have exactly participant, seed, conditions, trials, questionnaires, items"),
        (lambda d: [d.pop("questionnaires"), d.pop("items")], "has no questionnaires: it was written before they"),
        (lambda d: d.update(questionnaires=None), "questionnaires must be a list"),
        (lambda d: d["questionnaires"][0].pop("after_trial"), "questionnaire 1 must have exactly index, name"),
        (lambda d: d["questionnaires"][1].update(index=5), "questionnaire 2: index 5 where 2 comes"),
        (lambda d: d["questionnaires"][1].update(name="sus"), "questionnaire 2: name 'sus' is none of ssq, ipq"),
        (lambda d: d["questionnaires"][1].update(condition="VR"), "questionnaire 2: condition 'VR' is not one of"),
        (lambda d: d["questionnaires"][1].update(position="during"), "position 'during' is not one of before, after"),
        (
            lambda d: d["questionnaires"][1].update(administration="ssq_pre"),
            "questionnaire 2: administration 'ssq_pre' is not ssq_before_vr",
        ),
        (
            lambda d: d["questionnaires"][1].update(after_trial=0),
            "questionnaire 2: after_trial 0 is not where the vr block's before is",
        ),
        (
            lambda d: d["questionnaires"][3].update(
                condition="reality", administration="ipq_after_reality", after_trial=19
            ),
            "questionnaire 4: ipq is for vr only, not reality",
        ),
        (
            lambda d: d.update(questionnaires=[dict(q, index=n) for n, q in enumerate(d["questionnaires"][::-1], 1)]),
            "the questionnaires are not in the order the session reaches them",
        ),
        (
            lambda d: (
                d["questionnaires"].insert(3, dict(d["questionnaires"][3], index=4))
                or [q.update(index=n) for n, q in enumerate(d["questionnaires"], 1)]
            ),
            "ipq_after_vr asked more than once",
        ),
        (lambda d: d.update(items=[]), "items must map the lab's own item names"),
        (lambda d: d["items"]["perceived_safety"].update(scale=[1, 70]), "perceived_safety.scale must have 2..11"),
        (lambda d: d["trials"][3].update(path="zigzag"), "trial 4: path 'zigzag' is not one of"),
        (lambda d: d["trials"][0].update(index=7), "trial 1: index 7 where 1 comes"),
        (lambda d: d["trials"][5].update(condition="VR"), "trial 6: condition 'VR' is not one of vr, reality"),
        (lambda d: d["trials"][2].update(standoff=0.9), "trial 3: stand-off 0.9 is not"),
        (lambda d: d["trials"][2].pop("peak_speed"), "trial 3 must have exactly"),
        (lambda d: d.update(participant=0), "participant must be an integer >= 1"),
        (lambda d: d.update(trials=[]), "trials must be a non-empty list"),
    ],
)
def test_a_malformed_plan_is_one_clear_error(change, message):
    with pytest.raises(StudyError, match=message):
        plan_from_data(malformed(change))


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d["test1"].update(paths=["straight", "spiral"]), r"unknown path\(s\) \['spiral'\]"),
        (lambda d: d["test1"].update(standoffs=[0.1, 0.1]), "distinct stand-offs"),
        (lambda d: d["test2"]["speed_sets"].update(slow=0.0), "speed_sets.slow must be a speed in"),
        (lambda d: d.update(test3={}), r"unknown \['test3'\]; it has test1, test2 and optionally planning"),
        (lambda d: d["test2"].pop("paths"), "test2 must have exactly paths, speed_sets, sesoi"),
        (lambda d: d["test2"].pop("sesoi"), "test2 must have exactly paths, speed_sets, sesoi"),
        (lambda d: d["test1"].update(sesoi=0), r"test1.sesoi \(perceived / actual\) must be a number in \(0, 1\]"),
        (lambda d: d["test2"].update(sesoi="2 cm"), r"test2.sesoi \(m\) must be a number"),
        (lambda d: d["planning"].pop("seed"), "planning must have exactly sd_between"),
        (lambda d: d["planning"].update(participants=[12, 8]), "planning.participants must be increasing"),
        (lambda d: d["planning"]["sd_between"].pop("test2"), "planning.sd_between must give test1 and test2"),
        (lambda d: d["planning"].update(power=1.5), r"planning.power must be a number in \(0.5, 0.99\]"),
    ],
)
def test_a_bad_design_is_one_clear_error(change, message):
    """Each test's SESOI is required: the verdicts judge against it. The planning section is optional (analysis
    needs none), but checked whole when given."""
    data = copy.deepcopy(yaml.safe_load(DEFAULT_DESIGN.read_text()))
    change(data)
    with pytest.raises(StudyError, match=message):
        parse_design(data)


@pytest.mark.parametrize("participant, seed", [(0, 1), (-3, 1), (1, -1)])
def test_bad_participant_numbers_and_seeds_are_named(participant, seed):
    with pytest.raises(StudyError, match="participant number|seed"):
        make_plan(DESIGN, participant, seed)
