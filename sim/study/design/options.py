"""The options that choose a command's scene and robot, shared by the study's commands."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim.robots import RobotSpec, add_robot_overrides, overrides_from_args
from sim.study.design.scene import Scene, scene_robot
from sim.wire.contract import STEP_S

__all__ = ["add_design_option", "add_robot_options", "add_scene_options", "robot_from_args"]


def add_design_option(command: argparse.ArgumentParser, help: str = "") -> None:
    command.add_argument("--design", type=Path, help=help or "design YAML (default: the bundled design.yaml)")


def add_robot_options(command: argparse.ArgumentParser) -> None:
    """--scene, and --robot with its overrides."""
    command.add_argument("--scene", type=Path, help="scene YAML (default: the bundled scene.yaml)")
    robot = command.add_argument_group("robot (default: the scene's, with its ee_link)")
    robot.add_argument("--robot", help="a URDF path, a robot YAML path or a bundled name, in the scene's place")
    add_robot_overrides(robot)


def add_scene_options(command: argparse.ArgumentParser) -> None:
    """The robot's options and the control step."""
    add_robot_options(command)
    command.add_argument("--dt", type=float, default=STEP_S, help=f"control step in s (default {STEP_S})")


def robot_from_args(scene: Scene, args: argparse.Namespace) -> RobotSpec:
    """The robot of a command: the scene's, or the one --robot names; the overrides on top."""
    return scene_robot(scene, args.robot, overrides_from_args(args))
