"""What a result computed for a robot (its self-contact verdict, a scene fitted to it) depends on, as one text for
the cache's key: the URDF's text, the content of every file its shapes name (meshes and textures, found the way the
physics finds them), and what was derived from the URDF with its YAML's and its command line's overrides. Where the
files lie is no part of it: the same arm written into another folder is the same arm, and an edited mesh makes
another one.

`shape_filenames` and `derived_fields` are pure; `robot_identity` reads the files.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sim.robots.loading import find_ros_package
from sim.robots.meshes import resolve_filename
from sim.robots.spec import RobotSpec
from sim.robots.urdf_model import urdf_root

__all__ = ["derived_fields", "robot_identity", "shape_filenames"]

# RobotSpec's fields that say where the robot was found, not what it is (the notes come from the URDF's text)
_WHERE = ("urdf_path", "cli_args", "notes")


def shape_filenames(urdf_text: str) -> list[str]:
    """Every mesh and texture filename the URDF names, in document order, each once (those resolve_shapes resolves)."""
    root = urdf_root(urdf_text)
    names = [
        element.get("filename", "")
        for element in root.iter()
        if element.tag == "texture" or (element.tag == "mesh" and element.get("filename"))
    ]
    return list(dict.fromkeys(names))


def derived_fields(robot: RobotSpec) -> dict[str, Any]:
    """What the robot is, as JSON-ready data: every field of its spec but where it was found (its path and command
    line). A YAML's or the command line's overrides (name, links, home, limits, scenario defaults) show up here."""
    data: dict[str, Any] = {}
    for field in dataclasses.fields(robot):
        if field.name in _WHERE:
            continue
        value = getattr(robot, field.name)
        if isinstance(value, np.ndarray):
            value = value.tolist()
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            value = dataclasses.asdict(value)
        data[field.name] = value
    return data


def robot_identity(robot: RobotSpec, find_package: Callable[[str], Path | None] = find_ros_package) -> str:
    """The robot's content as one text (JSON): its URDF's text, each shape file's name with the SHA-256 of the file
    it resolves to (None where it is nowhere), and derived_fields."""
    urdf = robot.urdf_path
    text = urdf.read_text(encoding="utf-8")
    files: list[list[Any]] = []
    for filename in shape_filenames(text):
        found = resolve_filename(filename, urdf.parent, find_package)
        files.append([filename, None if found is None else hashlib.sha256(found.read_bytes()).hexdigest()])
    return json.dumps({"urdf": text, "files": files, "robot": derived_fields(robot)}, sort_keys=True)
