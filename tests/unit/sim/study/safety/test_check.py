"""sim.study.safety.check: a plan is refused, one line per limit, for its samples or for its braking from any press."""

from __future__ import annotations

import re

from sim.study.safety.check import plan_refusals
from sim.study.safety.limits import limits_for
from tests.unit.sim.study.safety.plans import PANDA, panda_plan


def test_a_plan_within_the_limits_and_braking_within_them_may_run() -> None:
    path, joints = panda_plan("diagonal", 0.5)
    assert plan_refusals("diagonal", path, joints, limits_for(PANDA)) == []


def test_a_braking_harsher_than_the_robot_allows_is_refused_once_per_limit_at_its_worst_press() -> None:
    path, joints = panda_plan("diagonal", 0.5)
    refusals = plan_refusals("diagonal", path, joints, limits_for(PANDA), deceleration=12.0, jerk=20000.0)
    assert refusals and all(line.startswith("diagonal, braking from a press at t = ") for line in refusals)
    assert any("panda_joint" in line and " jerk " in line and "80% of its limit" in line for line in refusals)
    limits_named = [re.match(r".*?: (.* (velocity|acceleration|jerk)) ", line).group(1) for line in refusals]  # type: ignore[union-attr]
    assert len(limits_named) == len(set(limits_named))  # each limit once


def test_a_plan_whose_samples_exceed_the_limits_is_refused_for_them() -> None:
    path, joints = panda_plan("straight", 0.3)
    refusals = plan_refusals("straight", path, joints, limits_for(PANDA))
    assert any(line.startswith("straight: panda_joint5 velocity") for line in refusals)
