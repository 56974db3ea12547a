"""Loading a robot from what a user types after --robot: a bundled name, a URDF path or a robot YAML path.

A robot YAML holds overrides as data (every key optional except `urdf` in a YAML given on its own):

    urdf: pybullet_data:franka_panda/panda.urdf   # relative to the YAML's folder, or inside pybullet_data
    name: panda                                   # topics are /<name>/...
    base_link: panda_link0
    ee_link: panda_link8
    home: [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
    limits:                                       # per joint, any of lower, upper, velocity, effort
      panda_joint1: {lower: -2.8973, upper: 2.8973, velocity: 2.175, effort: 87}
    scenario_defaults:                            # computed from the robot when absent
      one_joint: {joint: panda_joint1, waypoints: [0.25, 1.0]}
      ik_goal: {position: [0.5, 0.375, 0.75]}     # rpy: [r, p, y] for a full pose
      orientation_goal: {position: [0.3, 0.5, 0.75], rpy: [0.785, 0.628, 1.047]}
      sweep: {centres: [...], amplitudes: [...]}

The old name of `scenario_defaults:`, `scenarios:`, is still read, with a warning, and in it the old name of
`sweep`, `trial`.

`--robot path/to/arm.urdf` also reads `path/to/arm.yaml` when it exists. Command-line overrides win over the YAML.
"""

from __future__ import annotations

import argparse
import functools
import logging
import math
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

from sim.cli_values import CliValueError, parse_numbers
from sim.robots.derive import RobotOverrides, derive_robot
from sim.robots.errors import RobotError
from sim.robots.spec import RobotSpec, ScenarioDefaults
from sim.robots.urdf_model import parse_urdf

__all__ = [
    "ROBOTS_DIR",
    "ROBOT_NAMES",
    "load_robot",
    "find_ros_package",
    "add_robot_arguments",
    "add_robot_overrides",
    "overrides_from_args",
    "robot_from_args",
]

log = logging.getLogger(__name__)

ROBOTS_DIR = Path(__file__).resolve().parent
ROBOT_NAMES: tuple[str, ...] = ("panda", "igt")  # the robots shipped as ROBOTS_DIR/<name>.yaml
_YAML_KEYS = ("urdf", "name", "base_link", "ee_link", "home", "limits", "scenario_defaults", "scenarios")
_SCENARIO_KEYS = {
    "one_joint": ("joint", "waypoints"),
    "ik_goal": ("position", "rpy"),
    "orientation_goal": ("position", "rpy"),
    "sweep": ("centres", "amplitudes"),
}
_PYBULLET_DATA = "pybullet_data:"


def _read_yaml(path: Path) -> dict[str, Any]:
    import yaml

    try:
        data = yaml.safe_load(path.read_text())
    except OSError as error:
        raise RobotError(f"cannot read robot YAML {path}: {error.strerror}") from None
    except yaml.YAMLError as error:
        raise RobotError(f"robot YAML {path} is not valid YAML: {error}".replace("\n", " ")) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise RobotError(f"robot YAML {path} must be a mapping of keys ({', '.join(_YAML_KEYS)})")
    unknown = [key for key in data if key not in _YAML_KEYS]
    if unknown:
        raise RobotError(f"robot YAML {path}: unknown key(s) {unknown}; known: {', '.join(_YAML_KEYS)}")
    return data


def _numbers(value: object, what: str) -> tuple[float, ...]:
    if (
        not isinstance(value, list)
        or not value
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    ):
        raise RobotError(f"{what} must be a list of finite numbers, got {value!r}")
    return tuple(float(v) for v in value)


def _text(value: object, what: str) -> str:
    if not isinstance(value, str) or not value:
        raise RobotError(f"{what} must be a non-empty string, got {value!r}")
    return value


def _scenario_defaults(value: object, source: Path) -> ScenarioDefaults:
    if not isinstance(value, dict):
        raise RobotError(f"{source}: scenario_defaults must be a mapping of {', '.join(_SCENARIO_KEYS)}")
    fields: dict[str, Any] = {}
    for scenario, entry in value.items():
        allowed = _SCENARIO_KEYS.get(scenario)
        if allowed is None:
            raise RobotError(f"{source}: unknown scenario default {scenario!r}; known: {', '.join(_SCENARIO_KEYS)}")
        if not isinstance(entry, dict) or any(key not in allowed for key in entry):
            raise RobotError(f"{source}: scenario_defaults.{scenario} takes {', '.join(allowed)}, got {entry!r}")
        where = f"{source}: scenario_defaults.{scenario}"
        if scenario == "one_joint":
            fields["one_joint"] = _text(entry.get("joint"), f"{where}.joint")
            fields["one_joint_waypoints"] = _numbers(entry.get("waypoints"), f"{where}.waypoints")
        elif scenario == "sweep":
            fields["sweep_centres"] = _numbers(entry.get("centres"), f"{where}.centres")
            fields["sweep_amplitudes"] = _numbers(entry.get("amplitudes"), f"{where}.amplitudes")
        else:
            prefix = "ik_goal" if scenario == "ik_goal" else "orientation_goal"
            fields[f"{prefix}_position"] = _numbers(entry.get("position"), f"{where}.position")
            if "rpy" in entry or scenario == "orientation_goal":
                fields[f"{prefix}_rpy"] = _numbers(entry.get("rpy"), f"{where}.rpy")
    return ScenarioDefaults(**fields)


def _limits(value: object, source: Path) -> dict[str, dict[str, float]]:
    if not isinstance(value, dict) or not all(isinstance(entry, dict) for entry in value.values()):
        raise RobotError(f"{source}: limits must map joint names to {{lower, upper, velocity, effort}}")
    return {str(joint): dict(entry) for joint, entry in value.items()}


def _overrides(data: Mapping[str, Any], source: Path) -> RobotOverrides:
    return RobotOverrides(
        name=None if data.get("name") is None else _text(data["name"], f"{source}: name"),
        base_link=None if data.get("base_link") is None else _text(data["base_link"], f"{source}: base_link"),
        ee_link=None if data.get("ee_link") is None else _text(data["ee_link"], f"{source}: ee_link"),
        home=None if data.get("home") is None else _numbers(data["home"], f"{source}: home"),
        limits=_limits(data.get("limits", {}), source),
        scenario_defaults=_scenario_defaults(_scenario_defaults_entry(data, source), source),
    )


def _scenario_defaults_entry(data: Mapping[str, Any], source: Path) -> object:
    """`scenario_defaults:`, or its old name `scenarios:` (with a warning); not both."""
    if "scenarios" not in data:
        return data.get("scenario_defaults", {})
    if "scenario_defaults" in data:
        raise RobotError(f"{source}: give scenario_defaults only (scenarios is its old name)")
    log.warning("%s: 'scenarios:' is deprecated; rename it 'scenario_defaults:'", source)
    old = data["scenarios"]
    if isinstance(old, dict) and "trial" in old:  # the sweep's old name
        old = {("sweep" if key == "trial" else key): value for key, value in old.items()}
    return old


def _urdf_of(yaml_path: Path, value: object) -> Path:
    text = _text(value, f"{yaml_path}: urdf")
    if text.startswith(_PYBULLET_DATA):
        import pybullet_data

        return Path(pybullet_data.getDataPath()) / text[len(_PYBULLET_DATA) :]
    path = Path(text).expanduser()
    return path if path.is_absolute() else yaml_path.parent / path


def _files(reference: str) -> tuple[Path | None, Path | None]:
    """(URDF, YAML) for a bundled name or a YAML path (URDF None: the YAML names it), or a URDF path (YAML: the one
    beside it, if any)."""
    if reference in ROBOT_NAMES:
        return None, ROBOTS_DIR / f"{reference}.yaml"
    path = Path(reference).expanduser()
    if path.suffix in (".yaml", ".yml"):
        if not path.is_file():
            raise RobotError(f"robot YAML not found: {path}")
        return None, path.resolve()
    if path.suffix == ".xacro" or path.name.endswith(".urdf.xacro"):
        raise RobotError(f"{path} is a xacro file; expand it first: xacro {path} > {path.stem}.urdf")
    if path.suffix != ".urdf" and not path.is_file():
        raise RobotError(
            f"unknown robot {reference!r}: give a URDF path (…/arm.urdf), a robot YAML or one of "
            f"{', '.join(ROBOT_NAMES)}"
        )
    if not path.is_file():
        raise RobotError(f"URDF not found: {path}")
    sibling = path.with_suffix(".yaml")
    return path.resolve(), sibling.resolve() if sibling.is_file() else None


def load_robot(
    reference: str,
    name: str | None = None,
    base_link: str | None = None,
    ee_link: str | None = None,
    home: tuple[float, ...] | None = None,
) -> RobotSpec:
    """The robot `reference` names (a bundled name, a URDF path or a robot YAML path), with the given overrides
    winning over its YAML's. RobotError names the file and the value when it cannot be loaded."""
    given_urdf, yaml_path = _files(reference)
    data = _read_yaml(yaml_path) if yaml_path is not None else {}
    if yaml_path is not None and "urdf" in data:
        urdf = _urdf_of(yaml_path, data["urdf"]).resolve()
        if given_urdf is not None and urdf != given_urdf:
            raise RobotError(f"{yaml_path} names URDF {urdf}, but {given_urdf} was given")
    elif given_urdf is None:
        raise RobotError(f"robot YAML {yaml_path} has no urdf: key naming the robot's URDF")
    else:
        urdf = given_urdf
    if not urdf.is_file():
        raise RobotError(f"URDF not found: {urdf}" + (f" (named in {yaml_path})" if yaml_path else ""))
    try:
        text = urdf.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise RobotError(f"cannot read URDF {urdf}: {error}") from None
    model = parse_urdf(text, str(urdf))
    overrides = _overrides(data, yaml_path) if yaml_path is not None else RobotOverrides()
    overrides = replace(
        overrides,
        name=name or overrides.name,
        base_link=base_link or overrides.base_link,
        ee_link=ee_link or overrides.ee_link,
        home=overrides.home if home is None else home,
    )
    # Child processes get the same robot: the bundled name, or the absolute path of the file that was given.
    given_yaml = reference not in ROBOT_NAMES and Path(reference).suffix in (".yaml", ".yml")
    cli_args = ["--robot", reference if reference in ROBOT_NAMES else str(yaml_path if given_yaml else urdf)]
    for option, value in (("--name", name), ("--base-link", base_link), ("--ee-link", ee_link)):
        if value is not None:
            cli_args += [option, value]
    if home is not None:
        cli_args += ["--home", *(repr(float(v)) for v in home)]
    robot = derive_robot(model, urdf, overrides, str(yaml_path or urdf), tuple(cli_args))
    for note in robot.notes:
        log.warning("robot %s: %s", robot.name, note)
    return robot


@functools.lru_cache(maxsize=None)
def find_ros_package(name: str) -> Path | None:
    """Where ROS has package `name` (rospack's search of ROS_PACKAGE_PATH and the system's packages), or None."""
    try:
        import rospkg
    except ImportError:  # no ROS here: package:// URIs are then looked up beside the URDF only
        return None
    try:
        return Path(rospkg.RosPack().get_path(name))
    except rospkg.ResourceNotFound:
        return None


# --------------------------------------------------------------------------------------------- command line
def add_robot_arguments(parser: argparse.ArgumentParser, default: str = "panda") -> None:
    """--robot and its overrides, the same for every entry point."""
    group = parser.add_argument_group("robot")
    group.add_argument(
        "--robot",
        default=default,
        help=f"a URDF path, a robot YAML path or one of {', '.join(ROBOT_NAMES)} (default {default})",
    )
    add_robot_overrides(group)


def add_robot_overrides(group: argparse._ActionsContainer) -> None:
    """The overrides of what is derived from a URDF: --name, --base-link, --ee-link, --home."""
    group.add_argument("--name", help="the robot's name (topics /<name>/...); default: the URDF's robot name")
    group.add_argument("--base-link", help="default: the URDF's root link")
    group.add_argument(
        "--ee-link", help="default: the end of the longest chain of moving joints; of a gripper, the hand's tool frame"
    )
    group.add_argument("--home", nargs="+", metavar="Q", help="home joint positions; default: mid-range")


def overrides_from_args(args: argparse.Namespace) -> dict[str, Any]:
    """`load_robot`'s keyword overrides from `add_robot_overrides`' options, the ones given only (RobotError when
    --home is not numbers). An empty value is one not given: a launch file passes its arguments' empty defaults."""
    home_given = args.home is not None and any(token.strip() for token in args.home)
    try:
        home = parse_numbers(args.home, "--home") if home_given else None
    except CliValueError as error:
        raise RobotError(str(error)) from None
    given = {"name": args.name, "base_link": args.base_link, "ee_link": args.ee_link}
    if home is not None:
        given["home"] = tuple(home)
    return {key: value for key, value in given.items() if value}


def robot_from_args(args: argparse.Namespace) -> RobotSpec:
    """The robot `add_robot_arguments`' options name (RobotError or CliValueError when they are bad)."""
    return load_robot(args.robot, **overrides_from_args(args))
