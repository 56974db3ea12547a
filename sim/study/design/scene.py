"""The study's scene as data: where the robot, the table, the hand and the participant are (a small YAML, see
scene.yaml beside this file), read (parse_scene) and written (scene_to_data) in this one place, so that the two
agree. Pure logic, but for reading the YAML in `load_scene`."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sim.geometry.frames import rpy_to_matrix
from sim.robots import RobotError, RobotSpec, load_robot
from sim.study.design.errors import DesignError
from sim.study.design.yamlfile import read_yaml

if TYPE_CHECKING:
    from sim.geometry.kinematics import KinematicChain

__all__ = [
    "DEFAULT_SCENE",
    "DISTANCES",
    "Box",
    "Scene",
    "parse_scene",
    "scene_to_data",
    "scaling_note",
    "scene_robot",
    "load_scene",
]

DEFAULT_SCENE = Path(__file__).resolve().parent / "scene.yaml"
_KEYS = ("robot", "ee_link", "base", "pedestal", "table", "hand", "seat", "distance", "approach_scale")
# How the robot's distance to the hand is measured: from its collision geometry's nearest point to the hand's
# surface, or (the thesis's) from the end-effector point, e.g. the point between a gripper's fingertips.
DISTANCES = ("surface", "ee_point")
_REQUIRED = ("robot", "base", "table", "hand", "seat")


@dataclass(frozen=True)
class Box:
    """An axis-aligned box turned by `yaw` about z: the table, the hand."""

    size: np.ndarray  # (3,) full lengths along its own x, y, z
    position: np.ndarray  # (3,) its centre in the world
    yaw: float = 0.0

    @property
    def rotation(self) -> np.ndarray:
        return rpy_to_matrix(0.0, 0.0, self.yaw)

    @property
    def top(self) -> np.ndarray:
        """The centre of its top face."""
        return self.position + np.array([0.0, 0.0, self.size[2] / 2.0])

    def nearest_point(self, point: np.ndarray) -> np.ndarray:
        """The box's point (world) nearest to `point`; `point` itself inside."""
        rotation = self.rotation
        local = rotation.T @ (np.asarray(point, dtype=float) - self.position)
        return self.position + rotation @ np.clip(local, -self.size / 2.0, self.size / 2.0)

    def distance(self, point: np.ndarray) -> float:
        """Distance from `point` (world) to the box's nearest point; 0 inside."""
        return float(np.linalg.norm(np.asarray(point, dtype=float) - self.nearest_point(point)))


@dataclass(frozen=True)
class Scene:
    robot: str  # what --robot takes: a bundled name or a URDF / robot YAML path
    ee_link: str | None  # the point that approaches the hand (e.g. between the gripper's fingertips); None: the robot's
    base_position: np.ndarray  # the robot's base link in the world
    base_rpy: np.ndarray
    table: Box
    hand: Box
    seat: np.ndarray  # the participant's eyes
    distance: str = "surface"  # one of DISTANCES
    # The approach paths' shapes (their starts and via points, from the hand) scaled by this, for an arm that cannot
    # reach the thesis's; stand-offs and speeds are the design's whatever it is
    approach_scale: float = 1.0
    # What the robot stands on, on the table top under its base, where it is mounted higher than the table (a
    # pedestal, a stand); None: on the table itself
    pedestal: Box | None = None

    @property
    def base_pose(self) -> np.ndarray:
        """4x4 world ← base link."""
        pose = np.eye(4)
        pose[:3, :3] = rpy_to_matrix(*self.base_rpy)
        pose[:3, 3] = self.base_position
        return pose

    def to_base(self, world_points: np.ndarray) -> np.ndarray:
        """World points (…, 3) in the robot's base frame, where its kinematics work."""
        pose = self.base_pose
        return (np.asarray(world_points, dtype=float) - pose[:3, 3]) @ pose[:3, :3]

    def to_base_direction(self, world_direction: np.ndarray) -> np.ndarray:
        """A world direction in the robot's base frame."""
        return rpy_to_matrix(*self.base_rpy).T @ np.asarray(world_direction, dtype=float)

    def to_world(self, base_points: np.ndarray) -> np.ndarray:
        pose = self.base_pose
        return np.asarray(base_points, dtype=float) @ pose[:3, :3].T + pose[:3, 3]

    def end_effector(self, chain: KinematicChain, positions: np.ndarray) -> np.ndarray:
        """The chain's end effector in the world at joint positions `positions` (FK, then the base pose)."""
        return self.to_world(chain.fk(positions)[:3, 3][None])[0]


def scaling_note(scene: Scene) -> str:
    """What of the design's paths the scene changes for its arm, in one line: "" when nothing (check, scene and the
    report say it)."""
    if scene.approach_scale == 1.0:
        return ""
    return (
        f"the paths' shapes (their starts and via points, from the hand) are scaled × {scene.approach_scale:g} for "
        "the arm's reach (approach_scale); stand-offs, speeds and approach directions are the design's"
    )


def _vector(value: object, size: int, what: str) -> np.ndarray:
    if not (
        isinstance(value, list)
        and len(value) == size
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    ):
        raise DesignError(f"{what} must be {size} finite numbers, got {value!r}")
    return np.array(value, dtype=float)


def _mapping(data: Mapping[str, Any], key: str, allowed: tuple[str, ...], source: str) -> Mapping[str, Any]:
    value = data.get(key)
    if not isinstance(value, dict):
        raise DesignError(f"{source}: {key} must be a mapping with {', '.join(allowed)}, got {value!r}")
    unknown = [k for k in value if k not in allowed]
    if unknown:
        raise DesignError(f"{source}: {key} has unknown key(s) {unknown}; known: {', '.join(allowed)}")
    return value


def _box(data: Mapping[str, Any], key: str, source: str) -> Box:
    entry = _mapping(data, key, ("size", "xyz", "yaw"), source)
    size = _vector(entry.get("size"), 3, f"{source}: {key}.size")
    if np.any(size <= 0):
        raise DesignError(f"{source}: {key}.size must be > 0, got {size.tolist()}")
    yaw = entry.get("yaw", 0.0)
    if not (isinstance(yaw, (int, float)) and not isinstance(yaw, bool) and math.isfinite(yaw)):
        raise DesignError(f"{source}: {key}.yaw must be a finite number, got {yaw!r}")
    return Box(size, _vector(entry.get("xyz"), 3, f"{source}: {key}.xyz"), float(yaw))


def _mounting(xyz: object, pedestal: object, table: Box, yaw: float, source: str) -> tuple[np.ndarray, Box | None]:
    """The robot's base position and what it stands on. Its base link's origin is its mounting face (as a ROS
    description has it). base.xyz of two values (x, y): the robot stands by construction on the table top, or on the
    `pedestal` ({height, size: [x, y]}, on the table top under the base), so that lowering the table lowers the robot
    with it. Three values: the base exactly there (the scene says where), on a pedestal's top where one is given."""
    if isinstance(xyz, list) and len(xyz) == 2:
        where = _vector(xyz, 2, f"{source}: base.xyz")
    else:
        where = _vector(xyz, 3, f"{source}: base.xyz (x, y: the robot on the table, or x, y, z)")
    top = float(table.top[2])
    stand = None
    if pedestal is not None:
        entry = _mapping({"pedestal": pedestal}, "pedestal", ("height", "size"), source)
        height, size = entry.get("height"), _vector(entry.get("size"), 2, f"{source}: pedestal.size")
        if not (isinstance(height, (int, float)) and not isinstance(height, bool) and 0.0 < height < 5.0):
            raise DesignError(f"{source}: pedestal.height must be a number of metres above 0, got {height!r}")
        if np.any(size <= 0):
            raise DesignError(f"{source}: pedestal.size must be > 0, got {size.tolist()}")
        stand = Box(np.array([size[0], size[1], height]), np.array([where[0], where[1], top + height / 2.0]), yaw)
        top += float(height)
    if where.size == 2:
        return np.array([where[0], where[1], top]), stand
    if stand is not None and abs(where[2] - top) > 1e-3:
        raise DesignError(
            f"{source}: base.xyz puts the base at z = {where[2]:.3f} m, its pedestal's top is at z = {top:.3f} m: "
            "give base.xyz as x, y alone to stand it on the pedestal"
        )
    return where, stand


def parse_scene(data: object, source: str = "scene") -> Scene:
    """A Scene from the YAML's data; DesignError names the key and the value."""
    if not isinstance(data, dict):
        raise DesignError(f"{source} must be a mapping of {', '.join(_KEYS)}")
    unknown = [key for key in data if key not in _KEYS]
    missing = [key for key in _REQUIRED if key not in data]
    if unknown or missing:
        raise DesignError(
            f"{source}: unknown key(s) {unknown}, missing key(s) {missing}; a scene has {', '.join(_KEYS)}"
        )
    robot = data["robot"]
    if not isinstance(robot, str) or not robot:
        raise DesignError(f"{source}: robot must be a robot name or a URDF path, got {robot!r}")
    base = _mapping(data, "base", ("xyz", "rpy"), source)
    seat = _mapping(data, "seat", ("xyz",), source)
    ee_link = data.get("ee_link")
    if ee_link is not None and (not isinstance(ee_link, str) or not ee_link):
        raise DesignError(f"{source}: ee_link must be a link name, got {ee_link!r}")
    distance = data.get("distance", "surface")
    if distance not in DISTANCES:
        raise DesignError(f"{source}: distance must be one of {', '.join(DISTANCES)}, got {distance!r}")
    scale = data.get("approach_scale", 1.0)
    if not (isinstance(scale, (int, float)) and not isinstance(scale, bool) and 0.3 <= scale <= 2.0):
        raise DesignError(f"{source}: approach_scale must be a number from 0.3 to 2, got {scale!r}")
    table = _box(data, "table", source)
    base_rpy = _vector(base.get("rpy", [0.0, 0.0, 0.0]), 3, f"{source}: base.rpy")
    base_xyz, pedestal = _mounting(base.get("xyz"), data.get("pedestal"), table, float(base_rpy[2]), source)
    scene = Scene(
        robot,
        ee_link,
        base_xyz,
        base_rpy,
        table,
        _box(data, "hand", source),
        _vector(seat.get("xyz"), 3, f"{source}: seat.xyz"),
        distance,
        float(scale),
        pedestal,
    )
    table_top = scene.table.position[2] + scene.table.size[2] / 2.0
    hand_bottom = scene.hand.position[2] - scene.hand.size[2] / 2.0
    if abs(hand_bottom - table_top) > 0.005:
        raise DesignError(
            f"{source}: the hand must rest on the table: its underside is at z = {hand_bottom:.4f} m, "
            f"the table top at z = {table_top:.4f} m"
        )
    return scene


def scene_to_data(scene: Scene) -> dict:
    """The scene as its YAML's data (parse_scene reads it back)."""

    def box(value: Box) -> dict:
        return {"size": _rounded(value.size), "xyz": _rounded(value.position), "yaw": round(float(value.yaw), 6)}

    data = {
        "robot": scene.robot,
        "ee_link": scene.ee_link,
        "base": {"xyz": _base_xyz(scene), "rpy": _rounded(scene.base_rpy)},
        "pedestal": None
        if scene.pedestal is None
        else {"height": round(float(scene.pedestal.size[2]), 6), "size": _rounded(scene.pedestal.size[:2])},
        "table": box(scene.table),
        "hand": box(scene.hand),
        "seat": {"xyz": _rounded(scene.seat)},
        "distance": scene.distance,
        "approach_scale": scene.approach_scale,
    }
    return {key: value for key, value in data.items() if value is not None}


def _base_xyz(scene: Scene) -> list[float]:
    """base.xyz as x, y where the robot stands on the table or its pedestal (lowering the table lowers it too)."""
    stands_on = float(scene.table.top[2]) + (0.0 if scene.pedestal is None else float(scene.pedestal.size[2]))
    on_top = abs(float(scene.base_position[2]) - stands_on) < 1e-6
    return _rounded(scene.base_position[:2] if on_top else scene.base_position)


def _rounded(values: np.ndarray) -> list[float]:
    return [round(float(v), 6) for v in values]


def scene_robot(scene: Scene, robot: str | None = None, overrides: Mapping[str, Any] | None = None) -> RobotSpec:
    """The scene's robot, its end effector the scene's `ee_link` where one is given; or `robot` (a command line's
    --robot), which the scene's `ee_link` does not apply to since it names a link of the scene's robot. `overrides`
    (load_robot's keywords from the command line) win over both."""
    keywords = dict(overrides or {})
    if not robot and scene.ee_link:
        keywords.setdefault("ee_link", scene.ee_link)
    try:
        return load_robot(robot or scene.robot, **keywords)
    except RobotError as error:
        whose = "the given robot" if robot else "the scene's robot"
        raise DesignError(f"{whose}: {error}") from None


def load_scene(path: Path | None = None) -> Scene:
    """The scene in `path` (default: the bundled scene.yaml)."""
    path = DEFAULT_SCENE if path is None else Path(path)
    return parse_scene(read_yaml(path, "scene"), str(path))
