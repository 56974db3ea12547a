"""sim.study.design.fit: an arm's proportions, the candidate scenes built from them, a scene written and read back,
and a proposal kept by the arm's content (the proposals themselves, with pybullet, are in
tests/integration/test_study_arms.py)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sim.geometry.kinematics import chain_for
from sim.robots import load_robot
from sim.robots.examples import STUDY_ARMS, write_arm
from sim.study.design import fit
from sim.study.design.errors import DesignError
from sim.study.design.fit import (
    Proportions,
    candidate_scene,
    design_combinations,
    proportions,
    tool_down_out_of_reach,
)
from sim.study.design.scene import DEFAULT_SCENE, load_scene, parse_scene, scene_robot, scene_to_data
from sim.study.design.spec import load_design
from sim.wire.contract import STEP_S

TEMPLATE = load_scene()
PANDA = scene_robot(TEMPLATE)


def test_the_pandas_shoulder_is_its_second_joint_and_its_reach_under_a_metre() -> None:
    found = proportions(PANDA, chain_for(PANDA))
    assert found.shoulder == pytest.approx([0.0, 0.0, 0.333], abs=1e-6)  # panda_joint2, the first horizontal axis
    assert 0.8 < found.reach < 1.1


def test_a_candidate_keeps_the_tables_reach_the_hand_on_it_and_the_seat_beside_it() -> None:
    scene = candidate_scene(TEMPLATE, PANDA, 0.7, -0.1, approach_scale=0.85)
    assert scene.hand.position[:2] == pytest.approx([0.7, 0.0]) and scene.approach_scale == 0.85
    assert scene.hand.position[2] - scene.hand.size[2] / 2 == pytest.approx(-0.1)  # resting on the table top
    assert scene.table.position[2] + scene.table.size[2] / 2 == pytest.approx(-0.1)
    behind = TEMPLATE.table.position[0] - TEMPLATE.table.size[0] / 2
    assert scene.table.position[0] - scene.table.size[0] / 2 == pytest.approx(behind)  # as far behind the base
    beyond = TEMPLATE.table.position[0] + TEMPLATE.table.size[0] / 2 - TEMPLATE.hand.position[0]
    assert scene.table.position[0] + scene.table.size[0] / 2 - 0.7 == pytest.approx(beyond)  # and beyond the hand
    assert scene.seat - scene.hand.top == pytest.approx(TEMPLATE.seat - TEMPLATE.hand.top)
    assert np.allclose(scene.base_position, 0.0)


def test_a_scene_is_written_as_its_yaml_and_read_back() -> None:
    scene = candidate_scene(TEMPLATE, PANDA, 0.62, 0.0, approach_scale=0.7)
    again = parse_scene(scene_to_data(scene))
    for name in ("robot", "ee_link", "distance", "approach_scale"):
        assert getattr(again, name) == getattr(scene, name), name
    for box in ("table", "hand"):
        assert getattr(again, box).position == pytest.approx(getattr(scene, box).position, abs=1e-6)
    assert again.seat == pytest.approx(scene.seat, abs=1e-6)


def test_a_candidate_on_a_lowered_table_stands_the_robot_on_a_pedestal_and_reads_back_so() -> None:
    scene = candidate_scene(TEMPLATE, PANDA, 0.7, -0.1, footprint=(0.25, 0.2))
    assert scene.pedestal is not None and np.allclose(scene.base_position, 0.0)
    assert scene.pedestal.size == pytest.approx([0.25, 0.2, 0.1])  # from the table top up to the base
    assert scene.pedestal.position == pytest.approx([0.0, 0.0, -0.05])
    data = scene_to_data(scene)
    assert data["base"]["xyz"] == [0.0, 0.0] and data["pedestal"] == {"height": 0.1, "size": [0.25, 0.2]}
    again = parse_scene(data)
    assert again.base_position == pytest.approx([0.0, 0.0, 0.0]) and again.pedestal is not None
    assert again.pedestal.position == pytest.approx(scene.pedestal.position)
    assert candidate_scene(TEMPLATE, PANDA, 0.7, 0.0).pedestal is None  # on the table itself


def test_lowering_the_table_lowers_the_robot_standing_on_it_unless_the_scene_places_the_base() -> None:
    data = scene_to_data(candidate_scene(TEMPLATE, PANDA, 0.7, -0.1))
    for box in ("table", "hand"):
        data[box]["xyz"][2] -= 0.2
    data["seat"]["xyz"][2] -= 0.2
    lowered = parse_scene(data)
    assert lowered.base_position[2] == pytest.approx(-0.2) and lowered.pedestal is not None  # on its pedestal still
    assert lowered.pedestal.position[2] == pytest.approx(-0.25)
    data["base"]["xyz"] = [0.0, 0.0, 0.3]  # placed, not on the pedestal's top: said
    with pytest.raises(
        DesignError, match=r"base.xyz puts the base at z = 0.300 m, its pedestal's top is at z = -0.200"
    ):
        parse_scene(data)
    del data["pedestal"]
    assert parse_scene(data).base_position[2] == pytest.approx(0.3)  # placed there, as the scene says


def test_a_wrist_beyond_its_reach_with_the_tool_down_rules_a_candidate_out_with_its_figures() -> None:
    # a desktop arm's proportions (the WidowX-like test arm's): the wrist reaches 0.57 - 0.165 = 0.405 m
    found = Proportions(np.array([0.0, 0.0, 0.111]), 0.57, 0.165)
    vertical = [("vertical", 0.1, 0.15)]
    whole = candidate_scene(TEMPLATE, PANDA, 0.34, 0.0)  # the thesis's shapes: the start 0.40 m above the hand
    assert tool_down_out_of_reach(whole, found, vertical, STEP_S) == (
        "the arm cannot point the tool down at the vertical path's start: its wrist would be 0.60 m from the "
        "shoulder, beyond the wrist's reach (0.40 m)"
    )
    wrist = np.hypot(0.34, 0.035 + 0.4 + 0.165 - 0.111)  # out, and up from the shoulder
    assert wrist == pytest.approx(0.60, abs=0.005)
    small = candidate_scene(TEMPLATE, PANDA, 0.28, -0.17, approach_scale=0.5)
    assert tool_down_out_of_reach(small, found, vertical, STEP_S) == ""
    # a wrist just beyond the estimated reach is left to IK (the reach is sampled, a little short of the truth)
    edge = Proportions(found.shoulder, wrist - 0.02 + 0.165, 0.165)
    assert tool_down_out_of_reach(whole, edge, vertical, STEP_S) == ""


def test_a_fitted_scene_is_kept_by_the_arms_content_shared_across_folders_and_not_past_an_edited_mesh(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("VR_SIM_CACHE", str(tmp_path / "cache"))
    design = next(design for design in STUDY_ARMS if design.overlapping_meshes)
    here, there = (load_robot(str(write_arm(tmp_path / folder, design))) for folder in ("here", "there"))
    combinations, text = design_combinations(load_design()), DEFAULT_SCENE.read_text(encoding="utf-8")
    proposal = candidate_scene(TEMPLATE, here, 0.6, 0.0)
    fit.keep(dataclasses.replace(proposal, robot=str(here.urdf_path)), here, text, combinations, STEP_S)
    assert len(list((tmp_path / "cache" / "scenes").glob("*.yaml"))) == 1

    def fitting(*_args: object, **_kwargs: object) -> fit.Fit:
        raise AssertionError("fitted again")

    monkeypatch.setattr(fit, "fit_scene", fitting)
    kept = fit.fitted_scene(there, TEMPLATE, text, combinations, STEP_S)  # the same arm elsewhere: the same entry
    assert kept.robot == str(there.urdf_path)  # named as this command gave it
    assert kept.hand.position == pytest.approx(proposal.hand.position, abs=1e-6)
    mesh = there.urdf_path.parent / "meshes" / "link2.stl"
    mesh.write_bytes(mesh.read_bytes() + b"\0")
    with pytest.raises(AssertionError, match="fitted again"):
        fit.fitted_scene(there, TEMPLATE, text, combinations, STEP_S)
    with pytest.raises(AssertionError, match="fitted again"):  # another template is another entry too
        fit.fitted_scene(here, TEMPLATE, text + "\n", combinations, STEP_S)
