"""Robots as data: a robot is its URDF, plus optional overrides in a small YAML (see sim.robots.loading).

`load_robot("panda")`, `load_robot("path/to/arm.urdf")` or `load_robot("path/to/arm.yaml")`; entry points take the
same through `add_robot_arguments` / `robot_from_args` (the campaign, with its list of robots: `add_robot_overrides`
/ `overrides_from_args`). Everything not overridden is derived from the URDF (sim.robots.derive): base and
end-effector links, controlled joints, limits, home and topic prefix.
"""

from __future__ import annotations

from sim.robots.errors import RobotError
from sim.robots.loading import (
    ROBOT_NAMES,
    ROBOTS_DIR,
    add_robot_arguments,
    add_robot_overrides,
    find_ros_package,
    load_robot,
    overrides_from_args,
    robot_from_args,
)
from sim.robots.spec import RobotSpec, ScenarioDefaults

__all__ = [
    "ROBOTS_DIR",
    "ROBOT_NAMES",
    "RobotError",
    "RobotSpec",
    "ScenarioDefaults",
    "load_robot",
    "find_ros_package",
    "add_robot_arguments",
    "add_robot_overrides",
    "overrides_from_args",
    "robot_from_args",
]
