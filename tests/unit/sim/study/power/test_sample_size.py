"""sim.study.power.sample_size on few studies: the layout is the plans', the question is checked, the figures do not
depend on the number of workers, and the verdicts follow the difference put in. The error rates, which need thousands
of studies, are checked through the command line (tests/integration/test_power_cli.py)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.study.design.plan import make_plan
from sim.study.design.spec import load_design
from sim.study.errors import StudyError
from sim.study.participants.model import Population
from sim.study.power.sample_size import PowerQuestion, PowerRow, needed, power_rows, study_layout

DESIGN = load_design()


def question(**changes: object) -> PowerQuestion:
    fields: dict = dict(test=2, difference=0.0, sd_between=0.02, sesoi=0.02, participants=(6,), simulations=30, seed=4)
    fields.update(changes)
    return PowerQuestion(**fields)


def test_the_layout_has_each_participants_planned_trials_of_the_test_in_their_order_of_conditions():
    layout = study_layout(DESIGN, 2, 4, seed=9)
    per_participant = len(DESIGN.test2_paths) * len(DESIGN.test2_speed_sets) * 2
    assert layout.participant.tolist() == [p for p in range(1, 5) for _ in range(per_participant)]
    assert layout.vr_first.tolist() == [p % 2 == 1 for p in range(1, 5) for _ in range(per_participant)]
    planned = [t for t in make_plan(DESIGN, 2, 9).trials if t.test == 2]
    mine = layout.participant == 2
    assert layout.path[mine].tolist() == [t.path for t in planned]
    assert layout.factor[mine].tolist() == [t.speed_set for t in planned]
    assert layout.vr[mine].tolist() == [t.condition == "vr" for t in planned]
    assert np.isnan(layout.value).all()
    test1 = study_layout(DESIGN, 1, 4, seed=9)
    assert set(test1.factor.tolist()) == {f"{standoff:g} m" for standoff in DESIGN.test1_standoffs}


def test_the_question_takes_its_tests_difference_and_spread_and_is_checked():
    base = Population()
    assert question(test=1, difference=0.1, sd_between=0.03).population(base).vr_distance_shift == 0.1
    assert question(test=1, difference=0.1, sd_between=0.03).population(base).distance_shift_sd == 0.03
    shifted = question(difference=-0.01, sd_between=0.0).population(base)
    assert (shifted.vr_comfort_shift, shifted.comfort_shift_sd) == (-0.01, 0.0)
    assert shifted.vr_distance_shift == base.vr_distance_shift
    for changes, problem in (
        ({"test": 3}, "test must be one of"),
        ({"sesoi": 0.0}, "SESOI must be > 0"),
        ({"sd_between": -0.1}, "SD between participants must be >= 0"),
        ({"participants": (3, 8)}, "must be 4..500"),
        ({"participants": ()}, "must be 4..500"),
        ({"simulations": 0}, "simulations must be 1..100000"),
        ({"difference": float("nan")}, "difference must be finite"),
    ):
        with pytest.raises(StudyError, match=problem):
            question(**changes)


def test_the_figures_do_not_depend_on_the_number_of_workers():
    # 12 simulations a size: enough for the figures to depend on the seed, few enough for three Pythons' runs
    asked = question(participants=(4, 6), simulations=12)
    here = power_rows(asked, DESIGN, workers=1)
    progress: list[int] = []
    pooled = power_rows(asked, DESIGN, workers=2, progress=progress.append)
    assert here == pooled
    assert sum(progress) == 24
    assert [row.participants for row in here] == [4, 6] and all(row.simulations == 12 for row in here)
    assert power_rows(question(seed=5, participants=(4, 6), simulations=12), DESIGN, workers=1) != here


def test_a_large_difference_is_found_different_and_none_is_not():
    far = power_rows(question(difference=0.06, participants=(8,)), DESIGN, workers=1)[0]
    assert far.p_different == 1.0 and far.p_equivalent == 0.0
    none = power_rows(question(difference=0.0, sd_between=0.005, participants=(8,)), DESIGN, workers=1)[0]
    assert none.p_equivalent == 1.0 and none.p_different < 0.2


def test_needed_is_the_smallest_number_reaching_the_power():
    rows = [PowerRow(8, 100, 0.1, 0.5, 0.0), PowerRow(12, 100, 0.05, 0.85, 0.0), PowerRow(16, 100, 0.04, 0.95, 0.0)]
    assert needed(rows, 0.8, "equivalent") == 12
    assert needed(rows, 0.9, "equivalent") == 16
    assert needed(rows[::-1], 0.8, "equivalent") == 12
    assert needed(rows, 0.8, "different") is None
    with pytest.raises(StudyError, match="verdict must be"):
        needed(rows, 0.8, "same")
