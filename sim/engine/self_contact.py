"""Which pairs of a robot's links can really collide, decided the way MoveIt's setup assistant decides it: a pair is
left out of the self-collision check when its links are adjacent (joined by one joint, links without collision
geometry skipped), touch at the robot's default pose, touch in nearly every sampled joint state (by construction:
their meshes overlap), or touch in none of them (they cannot reach each other). Every other pair is checked, so a
real fold of the arm onto itself is still found.

`classify` is the pure decision; `self_contact` samples the robot in pybullet and caches the verdict by the hash of
the robot's content (sim.robots.identity: its URDF, its meshes' bytes, its default pose), so each robot pays for the
sampling once, in whichever folder its files lie.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Tuple

import numpy as np
import pybullet as p

from sim.cache import entry_path, keep
from sim.engine.physics import load_urdf_text
from sim.robots import RobotSpec, find_ros_package
from sim.robots.identity import robot_identity
from sim.robots.meshes import resolve_shapes

__all__ = [
    "ALWAYS_FRACTION",
    "CONTACT_MARGIN",
    "SAMPLES",
    "Pair",
    "SelfContact",
    "classify",
    "link_names",
    "self_contact",
]

CONTACT_MARGIN = 0.005  # m: links closer than this touch
SAMPLES = 2000  # random joint states (MoveIt's assistant defaults to 10000; the verdicts agree well before)
ALWAYS_FRACTION = 0.95  # MoveIt's "min collision fraction": touching this often is by construction
_VERSION = 1  # of the decision; a cached verdict of another version is computed again

Pair = Tuple[str, str]  # two link names, sorted (typing.Tuple: an alias is evaluated at run time, 3.8 has no tuple[])


def pair(a: str, b: str) -> Pair:
    return (a, b) if a <= b else (b, a)


@dataclass(frozen=True)
class SelfContact:
    """The verdict for one robot: the pairs checked, and why each other pair is not."""

    checked: frozenset[Pair]
    ignored: Mapping[Pair, str]  # "adjacent", "default", "always" or "never"

    def checks(self, a: str, b: str) -> bool:
        return pair(a, b) in self.checked


def classify(
    links: Sequence[str],
    adjacent: Iterable[Pair],
    touching_at_default: Iterable[Pair],
    touch_counts: Mapping[Pair, int],
    samples: int,
) -> SelfContact:
    """The verdict from what sampling found: `touch_counts` of each pair over `samples` joint states."""
    reasons: dict[Pair, str] = {}
    for a, b in adjacent:
        reasons[pair(a, b)] = "adjacent"
    for a, b in touching_at_default:
        reasons.setdefault(pair(a, b), "default")
    checked = set()
    for i, a in enumerate(links):
        for b in links[i + 1 :]:
            key = pair(a, b)
            if key in reasons:
                continue
            count = touch_counts.get(key, 0)
            if count == 0:
                reasons[key] = "never"
            elif count >= ALWAYS_FRACTION * samples:
                reasons[key] = "always"
            else:
                checked.add(key)
    return SelfContact(frozenset(checked), reasons)


def link_names(body: int, client: int) -> list[str]:
    """pybullet's links of `body` by index, the base (index -1) first: names[index + 1]."""
    base = p.getBodyInfo(body, physicsClientId=client)[0].decode()
    count = p.getNumJoints(body, physicsClientId=client)
    return [base] + [p.getJointInfo(body, j, physicsClientId=client)[12].decode() for j in range(count)]


def _has_geometry(body: int, link: int, client: int) -> bool:
    return bool(p.getCollisionShapeData(body, link, physicsClientId=client))


def _adjacent(body: int, client: int, names: Sequence[str]) -> list[Pair]:
    """Links joined by a joint; a link without collision geometry passes its parent on to its children."""
    count = p.getNumJoints(body, physicsClientId=client)
    parents = {j: p.getJointInfo(body, j, physicsClientId=client)[16] for j in range(count)}

    def solid_ancestor(link: int) -> int | None:
        while link != -1 and not _has_geometry(body, link, client):
            link = parents[link]
        return link if _has_geometry(body, link, client) else None

    found = []
    for child in range(count):
        if not _has_geometry(body, child, client):
            continue
        parent = solid_ancestor(parents[child])
        if parent is not None:
            found.append(pair(names[parent + 1], names[child + 1]))
    return found


def _touching(body: int, client: int, names: Sequence[str]) -> set[Pair]:
    points = p.getClosestPoints(body, body, CONTACT_MARGIN, physicsClientId=client)
    return {pair(names[c[3] + 1], names[c[4] + 1]) for c in points if c[3] != c[4]}


def _movable(body: int, client: int) -> list[tuple[int, float, float]]:
    """(joint, lower, upper) of every revolute or prismatic joint; a continuous one over a full turn."""
    movable = []
    for j in range(p.getNumJoints(body, physicsClientId=client)):
        info = p.getJointInfo(body, j, physicsClientId=client)
        if info[2] not in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC):
            continue
        lower, upper = float(info[8]), float(info[9])
        if upper <= lower:  # continuous (pybullet gives 0, -1)
            lower, upper = -np.pi, np.pi
        movable.append((j, lower, upper))
    return movable


def sample(robot: RobotSpec, urdf_text: str, samples: int = SAMPLES, seed: int = 0) -> SelfContact:
    """The verdict for `robot` from `samples` random joint states in a pybullet DIRECT client of its own."""
    client = p.connect(p.DIRECT)
    try:
        body = load_urdf_text(urdf_text, robot.urdf_path.name, client)
        names = link_names(body, client)
        solid = [name for index, name in enumerate(names) if _has_geometry(body, index - 1, client)]
        joints = _movable(body, client)
        by_name = {p.getJointInfo(body, j, physicsClientId=client)[1].decode(): j for j, _, _ in joints}
        for name, value in zip(robot.joint_names, robot.home):
            if name in by_name:
                p.resetJointState(body, by_name[name], float(value), physicsClientId=client)
        at_default = _touching(body, client, names)
        counts: dict[Pair, int] = {}
        rng = np.random.default_rng(seed)
        for _ in range(samples):
            for joint, lower, upper in joints:
                p.resetJointState(body, joint, float(rng.uniform(lower, upper)), physicsClientId=client)
            for key in _touching(body, client, names):
                counts[key] = counts.get(key, 0) + 1
        return classify(solid, _adjacent(body, client, names), at_default, counts, samples)
    finally:
        p.disconnect(physicsClientId=client)


def self_contact(robot: RobotSpec, samples: int = SAMPLES) -> SelfContact:
    """`robot`'s verdict, from the cache when this robot (by its content, robot_identity: its URDF, meshes and
    default pose, wherever its files lie) was sampled before."""
    identity = json.dumps([_VERSION, samples, CONTACT_MARGIN, robot_identity(robot)])
    path = entry_path("self_contact", identity, ".json")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return SelfContact(
            frozenset(pair(a, b) for a, b in data["checked"]),
            {pair(a, b): reason for a, b, reason in data["ignored"]},
        )
    except (OSError, ValueError, KeyError, TypeError):
        pass  # not cached yet, or unreadable: computed again
    urdf = robot.urdf_path
    text, _ = resolve_shapes(urdf.read_text(encoding="utf-8"), urdf.parent, find_ros_package)
    verdict = sample(robot, text, samples)
    data = {
        "robot": robot.name,
        "checked": sorted(verdict.checked),
        "ignored": sorted([a, b, reason] for (a, b), reason in verdict.ignored.items()),
    }
    keep(path, json.dumps(data, indent=1))
    return verdict
