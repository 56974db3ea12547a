"""A URDF's tree as plain data: links, joints, their limits and origins. Pure logic (parses text, reads no file).

Only what the toolkit needs is kept: the kinematic tree (parent, child, origin, axis), the joint limits and which
links carry an `<inertial>`. Visuals, collisions, transmissions and gazebo tags are left to pybullet and RViz.
Only the `<joint>` and `<link>` elements directly under `<robot>` count: `<transmission>` elements hold `<joint>`
elements of their own (without a type), which are not joints of the tree.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from sim.robots.errors import RobotError

__all__ = ["MOVING_TYPES", "KNOWN_TYPES", "UrdfLimit", "UrdfJoint", "UrdfLink", "UrdfModel", "urdf_root", "parse_urdf"]

MOVING_TYPES = ("revolute", "continuous", "prismatic")
KNOWN_TYPES = (*MOVING_TYPES, "fixed", "floating", "planar")


@dataclass(frozen=True)
class UrdfLimit:
    """A `<limit>` as written; None where an attribute is absent."""

    lower: float | None
    upper: float | None
    velocity: float | None
    effort: float | None


@dataclass(frozen=True)
class UrdfJoint:
    name: str
    joint_type: str  # one of KNOWN_TYPES
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    axis: tuple[float, float, float]  # unit vector in the joint frame (URDF default: x)
    limit: UrdfLimit | None

    @property
    def moving(self) -> bool:
        return self.joint_type in MOVING_TYPES


@dataclass(frozen=True)
class UrdfLink:
    name: str
    mass: float | None  # None: no <inertial> (pybullet then gives the link 1 kg and a unit inertia)
    inertia: tuple[float, float, float, float, float, float] | None = None  # ixx, ixy, ixz, iyy, iyz, izz

    def inertia_is_physical(self) -> bool:
        """Whether the principal moments are >= 0 and each at most the sum of the others (pybullet sets an
        inertia that is not to zero). True when no tensor is stated."""
        if self.inertia is None:
            return True
        ixx, ixy, ixz, iyy, iyz, izz = self.inertia
        moments = np.linalg.eigvalsh([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])  # ascending
        return bool(moments[0] >= 0.0 and moments[0] + moments[1] >= moments[2])


@dataclass(frozen=True)
class UrdfModel:
    """A robot's tree. `joints` keep the file's order."""

    name: str
    links: dict[str, UrdfLink]
    joints: tuple[UrdfJoint, ...]

    @property
    def root(self) -> str:
        children = {joint.child for joint in self.joints}
        roots = [name for name in self.links if name not in children]
        if len(roots) != 1:
            raise RobotError(f"URDF robot {self.name!r} must have exactly one root link, found {roots}")
        return roots[0]

    def joint_above(self, link: str) -> UrdfJoint | None:
        return next((joint for joint in self.joints if joint.child == link), None)

    def path(self, base: str, tip: str) -> list[UrdfJoint]:
        """The joints from `base` down to `tip`, in order; RobotError if `tip` is not below `base`."""
        for name in (base, tip):
            if name not in self.links:
                raise RobotError(f"URDF robot {self.name!r} has no link {name!r}; links: {sorted(self.links)}")
        path: list[UrdfJoint] = []
        link = tip
        while link != base:
            joint = self.joint_above(link)
            if joint is None:
                raise RobotError(f"link {tip!r} is not below link {base!r} in URDF robot {self.name!r}")
            path.append(joint)
            link = joint.parent
        return path[::-1]

    def leaves(self) -> list[str]:
        parents = {joint.parent for joint in self.joints}
        return [name for name in self.links if name not in parents]


def _floats(
    element: ET.Element | None, attribute: str, default: tuple[float, float, float], what: str
) -> tuple[float, float, float]:
    text = None if element is None else element.get(attribute)
    if text is None:
        return default
    try:
        values = [float(value) for value in text.split()]
    except ValueError:
        raise RobotError(f"{what}: {attribute}={text!r} is not three numbers") from None
    if len(values) != 3 or not all(math.isfinite(value) for value in values):
        raise RobotError(f"{what}: {attribute}={text!r} is not three finite numbers")
    return values[0], values[1], values[2]


def _optional_float(element: ET.Element, attribute: str, what: str) -> float | None:
    text = element.get(attribute)
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        raise RobotError(f"{what}: {attribute}={text!r} is not a number") from None
    if math.isnan(value):
        raise RobotError(f"{what}: {attribute} is NaN")
    return value


def _joint(element: ET.Element, source: str) -> UrdfJoint:
    name = element.get("name")
    if not name:
        raise RobotError(f"{source}: a <joint> has no name")
    what = f"{source}: joint {name!r}"
    joint_type = element.get("type")
    if joint_type not in KNOWN_TYPES:
        raise RobotError(f"{what} has type {joint_type!r}; URDF joint types are {', '.join(KNOWN_TYPES)}")
    ends = {}
    for end in ("parent", "child"):
        found = element.find(end)
        ends[end] = "" if found is None else found.get("link", "")
        if not ends[end]:
            raise RobotError(f"{what} has no <{end} link=...>")
    origin = element.find("origin")
    axis = _floats(element.find("axis"), "xyz", (1.0, 0.0, 0.0), f"{what} axis")
    norm = math.sqrt(sum(value * value for value in axis))
    if joint_type in MOVING_TYPES and norm < 1e-12:
        raise RobotError(f"{what} has a zero axis")
    if norm >= 1e-12:
        axis = (axis[0] / norm, axis[1] / norm, axis[2] / norm)
    limit_element = element.find("limit")
    limit = None
    if limit_element is not None:
        limit = UrdfLimit(
            *(
                _optional_float(limit_element, key, f"{what} <limit>")
                for key in ("lower", "upper", "velocity", "effort")
            )
        )
    return UrdfJoint(
        name,
        joint_type,
        ends["parent"],
        ends["child"],
        _floats(origin, "xyz", (0.0, 0.0, 0.0), f"{what} origin"),
        _floats(origin, "rpy", (0.0, 0.0, 0.0), f"{what} origin"),
        axis,
        limit,
    )


def _link(element: ET.Element, source: str) -> UrdfLink:
    name = element.get("name")
    if not name:
        raise RobotError(f"{source}: a <link> has no name")
    inertial = element.find("inertial")
    if inertial is None:
        return UrdfLink(name, None)
    mass_element = inertial.find("mass")
    mass = None if mass_element is None else _optional_float(mass_element, "value", f"{source}: link {name!r} mass")
    inertia_element = inertial.find("inertia")
    inertia = None
    if inertia_element is not None:
        values = [
            _optional_float(inertia_element, key, f"{source}: link {name!r} inertia")
            for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        ]
        inertia = (
            values[0] or 0.0,
            values[1] or 0.0,
            values[2] or 0.0,
            values[3] or 0.0,
            values[4] or 0.0,
            values[5] or 0.0,
        )
    return UrdfLink(name, 0.0 if mass is None else mass, inertia)


def urdf_root(text: str, source: str = "URDF") -> ET.Element:
    """The <robot> element of a URDF document (a byte-order mark and a default XML namespace tolerated)."""
    try:
        root = ET.fromstring(text.lstrip("\ufeff"))
    except ET.ParseError as error:
        raise RobotError(f"{source} is not XML: {error}") from None
    if root.tag.startswith("{"):  # a default XML namespace on <robot>: the elements are URDF's all the same
        for element in root.iter():
            element.tag = element.tag.rpartition("}")[2]
    if root.tag != "robot":
        raise RobotError(f"{source} is not a URDF: its root element is <{root.tag}>, not <robot>")
    return root


def parse_urdf(text: str, source: str = "URDF") -> UrdfModel:
    """The tree of a URDF document; `source` (e.g. its path) names it in errors."""
    root = urdf_root(text, source)
    links: dict[str, UrdfLink] = {}
    for element in root.findall("link"):
        link = _link(element, source)
        if link.name in links:
            raise RobotError(f"{source}: link {link.name!r} is defined twice")
        links[link.name] = link
    joints = tuple(_joint(element, source) for element in root.findall("joint"))
    seen: set[str] = set()
    parent_of: dict[str, str] = {}
    for joint in joints:
        if joint.name in seen:
            raise RobotError(f"{source}: joint {joint.name!r} is defined twice")
        seen.add(joint.name)
        for end in (joint.parent, joint.child):
            if end not in links:
                raise RobotError(f"{source}: joint {joint.name!r} names link {end!r}, which is not defined")
        if joint.child in parent_of:
            raise RobotError(f"{source}: link {joint.child!r} is the child of two joints")
        parent_of[joint.child] = joint.parent
    if not links:
        raise RobotError(f"{source} defines no <link>")
    model = UrdfModel(root.get("name", ""), links, joints)
    top = model.root
    for name in links:  # every link must hang from the root: links in a cycle have a parent each, yet no root
        current, hops = name, 0
        while current != top:
            current, hops = parent_of[current], hops + 1
            if hops > len(links):
                raise RobotError(f"{source}: link {name!r} is in a cycle of joints, not below the root {top!r}")
    return model
