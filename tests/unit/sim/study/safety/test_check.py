"""sim.study.safety.check: a plan is refused, one line per limit, for its samples or for its braking from any press."""

from __future__ import annotations

import re

import numpy as np

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


def test_a_design_beyond_the_pandas_acceleration_limit_is_refused_and_one_under_the_floor_too() -> None:
    from sim.study.design.feasibility import PlannedApproach
    from sim.study.safety.check import design_refusals

    path, joints = panda_plan("diagonal", 0.5)
    distances = np.linspace(0.3, 0.005, len(path.times))
    planned = PlannedApproach(path, joints, np.gradient(joints, path.dt, axis=0), 0.005, {}, distances)
    limits = limits_for(PANDA)
    assert design_refusals(limits, {("diagonal", 0.005, 0.5): planned}) == []
    # the plan's accelerations are beyond 2% of the Panda's: refused, one line per limit, naming it
    refusals = design_refusals(limits, {("diagonal", 0.005, 0.5): planned}, margin=0.02, floor=0.01)
    assert any(re.match(r"diagonal to 0.005 m at 0.5 m/s: panda_joint\d acceleration .* 2% of its limit", line)
               for line in refusals)  # fmt: skip
    assert refusals[-1] == "diagonal to 0.005 m at 0.5 m/s: comes 0.0050 m from the hand, under the floor of 0.01 m"


def test_a_plan_and_its_braking_past_a_joints_position_limit_are_refused_naming_the_joint() -> None:
    import dataclasses

    path, joints = panda_plan("diagonal", 0.5)
    limits = limits_for(PANDA)
    j = int(np.argmax(np.ptp(joints, axis=0)))  # the joint that moves most: its limit put halfway along the plan
    halfway = float((joints[0, j] + joints[-1, j]) / 2)
    if joints[-1, j] > joints[0, j]:
        tight = dataclasses.replace(limits, upper=np.where(np.arange(7) == j, halfway, limits.upper))
    else:
        tight = dataclasses.replace(limits, lower=np.where(np.arange(7) == j, halfway, limits.lower))
    refusals = plan_refusals("diagonal", path, joints, tight)
    joint = f"panda_joint{j + 1} position"
    assert any(line.startswith(f"diagonal: {joint} ") and f"limit {halfway:g} (URDF)" in line for line in refusals)
    assert any(line.startswith("diagonal, braking from a press at t = ") and joint in line for line in refusals)


def test_a_plan_the_separation_rule_would_brake_before_its_stand_off_is_refused_naming_the_time_and_the_terms() -> None:
    from sim.study.design.feasibility import PlannedApproach
    from sim.study.safety.check import design_refusals
    from sim.study.safety.separation import SeparationParameters

    path, joints = panda_plan("diagonal", 0.5)
    distances = np.linspace(0.3, 0.015, len(path.times))  # ends 0.015 m from the hand: under floor + C + Z (0.019 m)
    planned = PlannedApproach(path, joints, np.gradient(joints, path.dt, axis=0), 0.015, {}, distances)
    limits, key = limits_for(PANDA), ("diagonal", 0.015, 0.5)
    assert design_refusals(limits, {key: planned}) == []  # the rule not asked for: the runner's check as it was
    refusals = design_refusals(limits, {key: planned}, floor=0.01, separation=SeparationParameters())
    assert len(refusals) == 1
    assert re.match(
        r"diagonal to 0.015 m at 0.5 m/s: at t = \d+\.\d\d s the separation 0\.0\d+ m less S_p 0\.\d{3} m: "
        r"hand 0\.000, robot 0\.\d{3}, braking 0\.\d{3}, C\+Z 0\.009 \(lead 0\.25 s, hand 0 m/s\) leaves -?0\.\d+ m, "
        r"under the floor 0\.01 m: the monitor would brake before the stand-off$",
        refusals[0],
    )
    # a stand-off that clears floor + C + Z passes with a resting hand, and is refused for a hand closing at 0.1 m/s
    clear = PlannedApproach(path, joints, planned.velocities, 0.03, {}, np.linspace(0.3, 0.03, len(path.times)))
    assert design_refusals(limits, {key: clear}, floor=0.01, separation=SeparationParameters()) == []
    closing = design_refusals(limits, {key: clear}, floor=0.01, separation=SeparationParameters(), hand_speed=0.1)
    assert len(closing) == 1 and "(lead 0.25 s, hand 0.1 m/s)" in closing[0]
