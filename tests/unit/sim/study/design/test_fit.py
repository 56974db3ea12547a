"""sim.study.design.fit: an arm's proportions, the candidate scenes built from them, and a scene written and read
back (the proposals themselves, with pybullet, are in tests/integration/test_study_arms.py)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.geometry.kinematics import chain_for
from sim.study.design.fit import candidate_scene, proportions, scene_to_data
from sim.study.design.scene import load_scene, parse_scene, scene_robot

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
