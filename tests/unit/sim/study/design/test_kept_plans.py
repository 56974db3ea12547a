"""sim.study.design.kept_plans: a plan kept in the cache reads back to the same bits, and the next process of the same
input and code reads it instead of planning again; other code, or a fit's candidate scene, is not served from it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sim.study.design import feasibility, kept_plans
from sim.study.design.feasibility import FITTED, Approaches
from sim.study.design.kept_plans import plan_from_data, plan_to_data
from sim.study.design.paths import ApproachPath
from sim.study.design.planned import PlannedApproach
from sim.study.design.scene import load_scene, scene_robot
from sim.wire.contract import STEP_S

SCENE = load_scene()
PANDA = scene_robot(SCENE)
SHORT = ("vertical", 0.25, 0.15)  # the design's shortest approach


@pytest.fixture(autouse=True)
def own_cache(monkeypatch: pytest.MonkeyPatch, tmp_path: Path):
    monkeypatch.setenv("VR_SIM_CACHE", str(tmp_path / "cache"))
    FITTED.keep({})
    yield
    FITTED.keep({})
    kept_plans.code_fingerprint.cache_clear()  # (a test's "other code" forgotten)


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def test_a_plan_reads_back_to_the_same_bits_nan_infinities_and_signed_zeros_too() -> None:
    awkward = np.array([[0.1 + 0.2, -0.0, 1e-300], [math.pi, -math.inf, 5e-324]])
    path = ApproachPath("straight", 0.08, 0.15, STEP_S, np.array([0.0, 0.02]), awkward[:, :3] * 2, awkward[0, :2], 0.3)
    plan = PlannedApproach(
        path,
        awkward,
        awkward / 3,
        0.08000000320581387,
        {"table": math.inf, "hand": 0.1 + 0.2, "self": math.nan},
        np.array([math.nan, 0.07]),
        ["one problem"],
        1,
        ["a remedy"],
        "axis",
    )
    back = plan_from_data(plan_to_data(plan))
    arrays = [
        (p.path.times, p.path.positions, p.path.speeds, p.positions, p.velocities, p.distances) for p in (plan, back)
    ]
    assert all(same_bits(a, b) for a, b in zip(*arrays))
    assert (back.path.name, back.path.standoff, back.path.peak_speed, back.path.dt, back.path.length) == (
        "straight",
        0.08,
        0.15,
        STEP_S,
        0.3,
    )
    assert back.min_clearance["table"] == math.inf and math.isnan(back.min_clearance["self"])
    assert back.min_clearance["hand"] == 0.1 + 0.2 and back.reached_standoff == plan.reached_standoff
    assert (back.problems, back.unreachable, back.remedies, back.constraints) == (
        ["one problem"],
        1,
        ["a remedy"],
        "axis",
    )


def planning(*_args: object) -> PlannedApproach:
    raise AssertionError("planned again")


def test_the_next_process_of_the_same_input_and_code_reads_the_plan_and_other_code_plans_afresh(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    with Approaches(PANDA, SCENE, STEP_S) as first:  # (a process of its own: nothing in FITTED)
        planned = first.plan(SHORT)
    monkeypatch.setattr(feasibility, "plan_combination", planning)
    with Approaches(PANDA, SCENE, STEP_S) as next_process:
        read = next_process.plan(SHORT)
    assert read is not planned and plan_to_data(read) == plan_to_data(planned)
    assert all(same_bits(getattr(read, name), getattr(planned, name)) for name in ("positions", "velocities"))
    kept_plans.code_fingerprint.cache_clear()
    monkeypatch.setattr(kept_plans, "_SIM", Path(kept_plans.__file__).parent)  # "other code": another fingerprint
    with Approaches(PANDA, SCENE, STEP_S) as edited, pytest.raises(AssertionError, match="planned again"):
        edited.plan(SHORT)


def test_a_fits_candidate_writes_nothing_and_what_it_hands_on_is_kept_by_the_taker(tmp_path: Path) -> None:
    with Approaches(PANDA, SCENE, STEP_S, keep=False) as candidate:
        candidate.plan(SHORT)
        candidate.hand_on()
    assert not (tmp_path / "cache" / "plans").exists()
    with Approaches(PANDA, SCENE, STEP_S) as taker:  # takes it from FITTED, and keeps it for the next process
        taker.plan(SHORT)
    assert len(list((tmp_path / "cache" / "plans").glob("*.json"))) == 1
