"""The options that choose a command's scene and robot, shared by the study's commands."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim.robots import RobotSpec, add_robot_overrides, overrides_from_args
from sim.study.design.scene import Scene, scene_robot
from sim.wire.contract import STEP_S

__all__ = ["add_design_option", "add_robot_options", "add_scene_options", "robot_from_args", "scene_and_robot"]


def add_design_option(command: argparse.ArgumentParser, help: str = "") -> None:
    command.add_argument("--design", type=Path, help=help or "design YAML (default: the bundled design.yaml)")


def add_robot_options(command: argparse.ArgumentParser) -> None:
    """--scene, and --robot with its overrides."""
    command.add_argument(
        "--scene",
        type=Path,
        help="scene YAML (default: the bundled scene.yaml; for another --robot, the scene proposed for it)",
    )
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


def scene_and_robot(args: argparse.Namespace) -> tuple[Scene, RobotSpec]:
    """A command's scene and robot from --scene and --robot: without --scene, another robot than the bundled
    scene's gets the scene proposed for it (sim.study.design.fit)."""
    from sim.study.design.fit import scene_for  # pybullet: only for the commands that need a scene
    from sim.study.design.progress import progress_bar

    with progress_bar("scenes tried for the arm", "scene") as progress:  # on a terminal: the proposal takes a while
        return scene_for(args.scene, args.robot, overrides_from_args(args), progress=progress)
