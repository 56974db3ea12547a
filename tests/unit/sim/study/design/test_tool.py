"""sim.study.design.tool: the tool axis of an arm, and the approach orientation that points it down."""

from __future__ import annotations

import numpy as np

from sim.geometry.kinematics import chain_for
from sim.robots import load_robot
from sim.study.design.tool import approach_rotation, tool_axis
from tests.robot_files import THIRD_PARTY_URDFS

DOWN = np.array([0.0, 0.0, -1.0])


def test_the_panda_points_down_at_home_so_keeps_its_home_orientation() -> None:
    robot = load_robot("panda")
    chain = chain_for(robot)
    home = chain.fk(robot.home)
    assert np.allclose(home[:3, :3] @ tool_axis(chain, robot.home), DOWN, atol=1e-6)
    assert np.allclose(approach_rotation(chain, robot.home, DOWN), home[:3, :3], atol=1e-9)


def test_an_upright_arm_turns_its_flange_down_about_a_horizontal_axis() -> None:
    robot = load_robot(str(THIRD_PARTY_URDFS["lbr_iiwa"]))
    chain = chain_for(robot)
    assert np.allclose(tool_axis(chain, robot.home), [0.0, 0.0, 1.0], atol=1e-6)  # the flange's z, up at home
    rotation = approach_rotation(chain, robot.home, DOWN)
    assert np.allclose(rotation @ tool_axis(chain, robot.home), DOWN, atol=1e-9)
    assert np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-9) and np.isclose(np.linalg.det(rotation), 1.0)
