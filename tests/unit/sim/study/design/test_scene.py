"""sim.study.design.scene: the study's robot is the scene's, or one a command line names in its place."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from sim.robots import add_robot_arguments, overrides_from_args
from sim.study.design.scene import load_scene, scene_robot
from sim.study.errors import StudyError
from tests.robot_files import LIFT_ARM, PANDA_WITH_HAND

SCENE = load_scene()


def test_the_scenes_robot_has_the_scenes_end_effector():
    robot = scene_robot(SCENE)
    assert (robot.name, robot.ee_link) == ("panda", "panda_grasptarget")


def test_a_command_lines_robot_takes_the_scenes_place_without_its_end_effector():
    # The scene's ee_link names a link of the scene's robot; another robot's end effector is its own.
    robot = scene_robot(SCENE, str(LIFT_ARM))
    assert robot.ee_link == "tool_tip" and robot.cli_args == ("--robot", str(LIFT_ARM))
    # The Panda from its URDF alone: the gripper rule finds the same point the scene names.
    assert scene_robot(SCENE, str(PANDA_WITH_HAND)).ee_link == "panda_grasptarget"


def test_overrides_win_and_reload_the_same_robot_from_its_arguments():
    robot = scene_robot(SCENE, None, {"ee_link": "panda_hand", "home": (0.1, -0.7, 0, -2.3, 0, 1.6, 0.8)})
    assert robot.ee_link == "panda_hand" and robot.home[0] == pytest.approx(0.1)
    # What simulate passes to the runner, the participants and the engine loads the same robot there.
    parser = argparse.ArgumentParser()
    add_robot_arguments(parser)
    args = parser.parse_args(list(robot.cli_args))
    again = scene_robot(SCENE, args.robot, overrides_from_args(args))
    assert again.ee_link == "panda_hand" and np.array_equal(again.home, robot.home)


@pytest.mark.parametrize(
    "robot, overrides, message",
    [
        ("/no/such/arm.urdf", {}, "the given robot: URDF not found: /no/such/arm.urdf"),
        (None, {"ee_link": "nope"}, "the scene's robot: "),
    ],
)
def test_a_robot_that_cannot_be_used_is_a_study_error_naming_whose(robot, overrides, message):
    with pytest.raises(StudyError, match=message):
        scene_robot(SCENE, robot, overrides)
