"""What the VR page's server serves, as data: the robot's URDF with its meshes renamed to URLs, the page's settings
(scene, topics, joints) and which file a URL names. Pure logic: no socket, and no file is read here.

The same server serves the reality condition's stop button page (`python -m sim.study button`), a page of its own
(button.html) from the same folder, sharing the VR page's modules for ROS (connection.js, rostcp.js, clock.js) and
the trial's rules (study.js); it has no robot, no scene and no npm package.

A URL names a file only through a fixed table: the page's own files, the parts of the npm packages the page
imports, and the folders that hold the robot's meshes (a mesh's .mtl and textures sit beside it). Nothing else on
the machine can be reached, whatever the path says.
"""

from __future__ import annotations

import json
import mimetypes
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.geometry.frames import matrix_to_quat
from sim.robots import RobotSpec
from sim.robots.meshes import resolve_shapes
from sim.robots.urdf_model import urdf_root
from sim.study.design.scene import Box, Scene
from sim.study.design.spec import CONDITIONS
from sim.study.run.protocol import BODIES, INPUTS, PAGE_CLOCK_TOPIC, PROTOCOL
from sim.study.run.tracking import REST_S, TRACKING_TOPIC, announcement
from sim.study.views.errors import ViewError
from sim.study.views.live import COLOURS
from sim.study.views.vr.access import SECRET_PARAMETER
from sim.wire.rosmsgs import JOINT_STATE

__all__ = [
    "WEB_DIR",
    "ROS_PATH",
    "POSE_SOURCE",
    "POSE_CONDITIONS",
    "REST_WORDS",
    "PAGE_FILES",
    "EMULATION_FILES",
    "FRAME_TIME_FILES",
    "BUTTON_PAGE_FILES",
    "GAMEPAD_EMULATION_FILES",
    "PageFiles",
    "PAGES",
    "Site",
    "make_site",
    "make_button_site",
    "page_settings",
    "pose_conditions_from",
    "button_settings",
    "content_type",
]

WEB_DIR = Path(__file__).resolve().parent / "web"
ROS_PATH = "/ros"  # the WebSocket that is passed through to the endpoint
# What the VR page's tracked body is named as a pose source, in the session's tracking record and the report: the
# headset (its viewer pose) and its controllers (their grips), whatever the headset's make
POSE_SOURCE = "headset"
# The conditions whose trials the page tracks by default: VR's. In reality another tracker (a relay) is the source,
# unless the headset is worn there too with passthrough (`vr --pose-conditions vr,reality`)
POSE_CONDITIONS = ("vr",)
# What the panel says during the rest at the session's start ({seconds}: as declared; {left}: whole seconds left)
REST_WORDS = {
    "title": "Please hold still",
    "lines": [
        "Keep your head and both hands still for {seconds} s:",
        "the headset measures how steady its tracking is.",
        "{left} s",
    ],
}
PAGE_FILES = (
    "index.html",
    "page.css",
    "page.js",
    "scene.js",
    "robot.js",
    "panel.js",
    "controllers.js",
    "headset.js",
    "frameloop.js",
    "tracking.js",
    "poses.js",
    "rest.js",
    "topics.js",
    "connection.js",
    "rostcp.js",
    "clock.js",
    "study.js",
    "presses.js",
    "address.js",
)
# Modules served and loaded only when the server is started for them, in the order the page loads them: the emulated
# headset before the page asks for WebXR, then the tests' probe (window.vrPage); the bench's frame-time instrument.
EMULATION_FILES = ("emulation.js", "probe.js")
FRAME_TIME_FILES = ("frametime.js",)
# URL prefix -> folder under the npm packages (node_modules): what the page imports, and only that
_VENDOR = {
    "/vendor/three/build/": "three/build",
    "/vendor/three/examples/jsm/": "three/examples/jsm",
    "/vendor/urdf-loader/src/": "urdf-loader/src",
}
_EMULATION_VENDOR = {"/vendor/iwer/build/": "iwer/build"}  # the emulated headset, only when asked for
_ROBOT_PREFIX = "/robot/"
# The stop button's page: its own entry and modules, and the VR page's for ROS and the trial's rules
BUTTON_PAGE_FILES = (
    "button.html",
    "button.css",
    "button.js",
    "gamepad.js",
    "presses.js",
    "connection.js",
    "rostcp.js",
    "clock.js",
    "study.js",
    "address.js",
)
# The emulated gamepad before the page reads any, then the tests' probe (window.buttonPage)
GAMEPAD_EMULATION_FILES = ("gamepademulation.js", "buttonprobe.js")


@dataclass(frozen=True)
class PageFiles:
    """One page the server may serve: its entry (served at /), its modules and styles (under /app/), the modules
    served and loaded only for tests, and the npm packages it imports (URL prefix -> folder under node_modules)."""

    entry: str
    files: tuple[str, ...]
    emulation: tuple[str, ...]
    vendor: dict[str, str]
    emulation_vendor: dict[str, str]


PAGES = {
    "vr": PageFiles("index.html", PAGE_FILES, EMULATION_FILES, _VENDOR, _EMULATION_VENDOR),
    "button": PageFiles("button.html", BUTTON_PAGE_FILES, GAMEPAD_EMULATION_FILES, {}, {}),
}


@dataclass(frozen=True)
class Site:
    urdf: str  # the robot's URDF, every mesh and texture a URL under /robot/<folder>/
    mesh_folders: tuple[Path, ...]  # /robot/<k>/ is mesh_folders[k]
    settings: dict[str, Any]  # the page's /settings.json
    web_dir: Path = WEB_DIR
    emulation: bool = False  # serve the emulated headset (IWER) or gamepad and the tests' probe, and load them
    frame_time: bool = False  # serve the frame-time instrument and load it: bench/vr_frame_bench.py (the VR page's)
    page: str = "vr"  # which of PAGES: the VR page, or the stop button's

    @property
    def files(self) -> PageFiles:
        return PAGES[self.page]

    @property
    def entry(self) -> str:
        """The page's HTML file, served at /."""
        return self.files.entry

    @property
    def instruments(self) -> tuple[str, ...]:
        """The page's modules beyond its files that this site serves and the page loads, in that order."""
        return (self.files.emulation if self.emulation else ()) + (FRAME_TIME_FILES if self.frame_time else ())

    def file_for(self, url_path: str) -> Path | None:
        """The file a request's path names, or None when it names nothing the page may have."""
        if url_path in ("/", f"/{self.entry}"):
            return self.web_dir / self.entry
        if url_path.startswith("/app/"):
            name = url_path[len("/app/") :]
            return self.web_dir / name if name in self.files.files or name in self.instruments else None
        vendor = dict(self.files.vendor, **(self.files.emulation_vendor if self.emulation else {}))
        for prefix, folder in vendor.items():
            if url_path.startswith(prefix):
                return _inside(self.web_dir / "node_modules" / folder, url_path[len(prefix) :])
        if url_path.startswith(_ROBOT_PREFIX):
            index, _, rest = url_path[len(_ROBOT_PREFIX) :].partition("/")
            if index.isdigit() and int(index) < len(self.mesh_folders):
                return _inside(self.mesh_folders[int(index)], rest)
        return None


def _inside(folder: Path, relative: str) -> Path | None:
    """folder/relative when `relative` is plain: names joined by single slashes, none of them `.` or `..`, no
    backslash."""
    parts = relative.split("/")
    if "\\" in relative or any(part in ("", ".", "..") for part in parts):
        return None
    return folder.joinpath(*parts)


def _urls_for_meshes(urdf_text: str) -> tuple[str, tuple[Path, ...]]:
    """The URDF (filenames already absolute) with each mesh and texture as `robot/<k>/<name>`, relative to the
    page's root as urdf-loader resolves them; and the folders, k in order."""
    root = urdf_root(urdf_text)
    folders: list[Path] = []
    for element in list(root.iter("mesh")) + list(root.iter("texture")):
        filename = element.get("filename")
        if not filename:
            continue
        path = Path(filename)
        if path.parent not in folders:
            folders.append(path.parent)
        element.set("filename", f"{_ROBOT_PREFIX[1:]}{folders.index(path.parent)}/{path.name}")
    return ET.tostring(root, encoding="unicode"), tuple(folders)


def _box(box: Box) -> dict[str, Any]:
    return {"size": box.size.tolist(), "xyz": box.position.tolist(), "yaw": box.yaw}


def pose_conditions_from(text: str) -> tuple[str, ...]:
    """`vr --pose-conditions`: comma-separated conditions, or none; ViewError names what is not one."""
    conditions = tuple(c.strip() for c in text.split(",") if c.strip())
    conditions = () if conditions == ("none",) else conditions
    _check_pose_conditions(conditions)
    return conditions


def _check_pose_conditions(conditions: tuple[str, ...]) -> None:
    if any(c not in CONDITIONS for c in conditions) or len(set(conditions)) != len(conditions):
        raise ViewError(
            f"--pose-conditions must be some of {', '.join(CONDITIONS)} (each once) or none, "
            f"got {','.join(conditions)!r}"
        )


def page_settings(
    robot: RobotSpec, scene: Scene, pose_conditions: tuple[str, ...] = POSE_CONDITIONS, rest: float = REST_S
) -> dict[str, Any]:
    """What the page needs to know beyond the URDF: the scene in the world frame (ROS: x forward, z up), the
    robot's base pose, the joints it is sent, the study's topics with their types (the runner's status, the
    participant's inputs, the tracked body's poses and the pose source's announcement), the trial protocol's table,
    and the page's announcement of itself as the pose source of `pose_conditions` (none: the page sends no pose and
    rests not), whose trials alone it sends poses in: sent, latched, with its first poses, and again with its jitter
    once the participant has rested for `rest` s at the session's start (the page fills jitter_m and rest_s). It has
    no calibration: the headset's own tracking places it in the scene."""
    _check_pose_conditions(pose_conditions)
    x, y, z, w = matrix_to_quat(scene.base_pose[:3, :3])
    return {
        "robot": {
            "urdf": "/robot.urdf",
            "joint_names": list(robot.joint_names),
            "base": {"xyz": scene.base_position.tolist(), "quaternion_xyzw": [x, y, z, w]},
        },
        "table": _box(scene.table),
        "pedestal": None if scene.pedestal is None else _box(scene.pedestal),  # what the robot stands on
        "hand": _box(scene.hand),
        "seat": scene.seat.tolist(),
        "topics": {
            "joint_states": [robot.joint_states_topic, JOINT_STATE],
            "trial": list(PROTOCOL.status),
            **{name: list(PROTOCOL.inputs[name]) for name in INPUTS},
            **{body: list(PROTOCOL.poses[body]) for body in BODIES},  # the tracked body's, sent during trials
            "tracking": [TRACKING_TOPIC, "std_msgs/String"],  # the page's announcement as a pose source
            "page_clock": [PAGE_CLOCK_TOPIC, "std_msgs/String"],  # its clock's, after each sample
        },
        # its announcement (its jitter not yet measured), or None: it tracks no condition
        "pose_source": json.loads(announcement(POSE_SOURCE, pose_conditions, {}, None, None))
        if pose_conditions
        else None,
        "rest": {"seconds": rest, **REST_WORDS} if pose_conditions else None,  # at the session's start
        "protocol": PROTOCOL.data,  # the trial protocol's table, as the runner reads it
        "stop_source": PROTOCOL.stop_source("vr"),  # what the page's presses are named
        "ros_path": ROS_PATH,
        "key_parameter": SECRET_PARAMETER,  # which part of the page's address is the launch's key, to take out of it
        "colours": {name: list(COLOURS[name]) for name in ("table", "hand")},
    }


def make_site(
    robot: RobotSpec,
    scene: Scene,
    urdf_text: str,
    find_package: Callable[[str], Path | None],
    emulation: bool = False,
    web_dir: Path = WEB_DIR,
    frame_time: bool = False,
    pose_conditions: tuple[str, ...] = POSE_CONDITIONS,
    rest: float = REST_S,
) -> Site:
    """The site for `robot` (its URDF text given) in `scene`, tracking `pose_conditions` after a rest of `rest` s
    (page_settings); a mesh that is nowhere is left out of the picture, as in the physics (sim.robots.meshes)."""
    resolved, _missing = resolve_shapes(urdf_text, robot.urdf_path.parent, find_package)
    urdf, folders = _urls_for_meshes(resolved)
    settings = page_settings(robot, scene, pose_conditions, rest)
    settings["emulation"] = emulation
    return Site(urdf, folders, settings, web_dir, emulation, frame_time)


def button_settings(emulation: bool = False) -> dict[str, Any]:
    """What the stop button's page needs: the trial's status and the stop's topics with their types, the trial
    protocol's table, the stop source its presses are named by (the reality condition's) and the WebSocket's path."""
    return {
        "topics": {
            "trial": list(PROTOCOL.status),
            "stop": list(PROTOCOL.inputs["stop"]),
            "page_clock": [PAGE_CLOCK_TOPIC, "std_msgs/String"],
        },
        "protocol": PROTOCOL.data,
        "stop_source": PROTOCOL.stop_source("reality"),
        "ros_path": ROS_PATH,
        "key_parameter": SECRET_PARAMETER,
        "emulation": emulation,
    }


def make_button_site(emulation: bool = False, web_dir: Path = WEB_DIR) -> Site:
    """The stop button's page: no robot, no meshes; with `emulation`, the emulated gamepad and the tests' probe."""
    return Site("", (), button_settings(emulation), web_dir, emulation, False, "button")


def content_type(path: Path) -> str:
    """The Content-Type a browser needs (modules must be JavaScript; .obj/.mtl are text)."""
    suffix = path.suffix.lower()
    known = {".js": "text/javascript", ".mjs": "text/javascript", ".obj": "text/plain", ".mtl": "text/plain"}
    if suffix in known:
        return known[suffix] + "; charset=utf-8"
    guessed, _ = mimetypes.guess_type(path.name)
    return guessed or "application/octet-stream"
