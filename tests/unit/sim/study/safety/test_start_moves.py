"""sim.study.safety.start_moves: the move to each path's start, as the link sends it, from home and from any rest on
a path, against the robot's limits."""

from __future__ import annotations

import dataclasses

import numpy as np

from sim.control.scenarios import approach
from sim.study.design.feasibility import PlannedApproach
from sim.study.safety.limits import limits_for
from sim.study.safety.start_moves import quintic_ratios, start_move_refusals
from tests.unit.sim.study.safety.plans import PANDA, panda_plan


def planned(name: str, speed: float) -> PlannedApproach:
    path, joints = panda_plan(name, speed)
    distances = np.linspace(0.3, 0.02, len(path.times))
    return PlannedApproach(path, joints, np.gradient(joints, path.dt, axis=0), 0.02, {}, distances)


def test_the_closed_form_peaks_are_those_of_the_move_the_link_sends() -> None:
    plan = planned("diagonal", 0.5)
    limits = limits_for(PANDA)
    there = plan.positions[0]
    positions, _ = approach(PANDA, PANDA.home, there, plan.path.dt)
    sampled = np.abs(np.gradient(positions, plan.path.dt, axis=0)).max(axis=0) / (0.8 * limits.velocity)
    (closed,) = quintic_ratios(PANDA, limits, PANDA.home, there, 0.8)
    np.testing.assert_allclose(sampled, closed[0], rtol=0.01, atol=1e-6)


def test_the_moves_to_the_pandas_starts_within_its_limits_may_run() -> None:
    approaches = {("diagonal", 0.02, 0.5): planned("diagonal", 0.5), ("vertical", 0.02, 0.3): planned("vertical", 0.3)}
    assert start_move_refusals(PANDA, limits_for(PANDA), approaches) == []


def test_a_move_to_a_start_beyond_a_limit_is_refused_from_home_and_from_a_rest_on_a_path() -> None:
    approaches = {("diagonal", 0.02, 0.5): planned("diagonal", 0.5)}
    limits = limits_for(PANDA)
    slow = dataclasses.replace(limits, velocity=limits.velocity / 20)  # the move keeps to half the URDF's speeds
    refusals = start_move_refusals(PANDA, slow, approaches)
    assert any(
        line.startswith("the move from home to the start of diagonal to 0.02 m at 0.5 m/s: panda_joint")
        and " velocity " in line
        and "80% of its limit" in line
        for line in refusals
    ), refusals
    # from the start itself home is no move: only the way back from a rest on the path (its end) is refused
    at_start = dataclasses.replace(PANDA, home=approaches[("diagonal", 0.02, 0.5)].positions[0].copy())
    refusals = start_move_refusals(at_start, slow, approaches)
    assert refusals and all(
        line.startswith("the move to the start of diagonal to 0.02 m at 0.5 m/s from a rest at t = ")
        and "of diagonal to 0.02 m at 0.5 m/s: panda_joint" in line
        for line in refusals
    ), refusals
    names = [line.split(": ")[1].split(" ")[0:2] for line in refusals]
    assert len(names) == len({tuple(n) for n in names})  # each limit once per start, at its worst rest
