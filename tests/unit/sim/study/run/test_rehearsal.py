"""The rehearsal with the hand out of reach: the plan with every stand-off larger by the clearance."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from sim.study.design.plan import PlannedTrial, SessionPlan
from sim.study.run.errors import RunError
from sim.study.run.rehearsal import out_of_reach


def _plan() -> SessionPlan:
    first = PlannedTrial(1, "reality", 1, "vertical", 0.1, 0.2)
    second = PlannedTrial(2, "vr", 2, "over_the_top", 0.02, 0.3, "fast", 1)
    return SessionPlan(3, 0, ("reality", "vr"), (first, second))


def test_every_approach_ends_the_clearance_further_from_the_hand_and_the_rest_is_as_planned() -> None:
    plan = _plan()
    rehearsal = out_of_reach(plan, 0.15)
    assert [t.standoff for t in rehearsal.trials] == [0.25, 0.17]
    assert [replace(t, standoff=0.0) for t in rehearsal.trials] == [replace(t, standoff=0.0) for t in plan.trials]
    assert replace(rehearsal, trials=plan.trials) == plan


@pytest.mark.parametrize("clearance", [0.0, -0.1, math.nan, math.inf])
def test_a_clearance_that_keeps_nothing_out_of_reach_is_refused(clearance: float) -> None:
    with pytest.raises(RunError, match="--rehearsal-clearance must be > 0 m"):
        out_of_reach(_plan(), clearance)
