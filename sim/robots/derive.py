"""A `RobotSpec` from a URDF's tree plus optional overrides: everything not overridden is derived. Pure logic.

The rules (README, "Bring your own robot"):
  base link     the URDF's root link
  end effector  the leaf at the end of the longest chain of moving joints below the base. When two or more leaves
                end such chains and they are a gripper's fingers (each one's last moving joint hangs from the same
                link, the hand), the hand: its tool frame if it has exactly one (a leaf fixed to it), else the hand
                link itself, said in a note. Other ties are ambiguous: an error lists them (choose with --ee-link)
  joints        the moving joints (revolute, continuous, prismatic) from the base to the end effector, in order;
                the moving joints off that chain (e.g. a gripper's fingers) are held where they start
  limits        from <limit>; a continuous joint gets a full turn each way (±2π); stated defaults where the URDF
                has none (MISSING_* below), each with a note
  home          the middle of every joint's limits (0 for continuous joints)
  name          the URDF's robot name, made a valid ROS name; topics are /<name>/...
Floating and planar joints cannot be driven by a position drive: such a URDF is refused.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.robots.errors import RobotError
from sim.robots.spec import RobotSpec, ScenarioDefaults
from sim.robots.urdf_model import MOVING_TYPES, UrdfJoint, UrdfModel

__all__ = [
    "LIMIT_KEYS",
    "MISSING_REVOLUTE_RANGE",
    "MISSING_PRISMATIC_RANGE",
    "MISSING_REVOLUTE_VELOCITY",
    "MISSING_PRISMATIC_VELOCITY",
    "RobotOverrides",
    "ros_name",
    "end_effector",
    "derive_robot",
]

LIMIT_KEYS = ("lower", "upper", "velocity", "effort")
MISSING_REVOLUTE_RANGE = math.pi  # rad each way, for a revolute joint whose <limit> gives no range
MISSING_PRISMATIC_RANGE = 0.1  # m each way
MISSING_REVOLUTE_VELOCITY = 1.0  # rad/s
MISSING_PRISMATIC_VELOCITY = 0.25  # m/s
# A missing effort means an unlimited drive force (inf), never a drive that cannot move.


@dataclass(frozen=True)
class RobotOverrides:
    """What a robot's YAML or the command line sets instead of deriving it; None/empty = derive."""

    name: str | None = None
    base_link: str | None = None
    ee_link: str | None = None
    home: tuple[float, ...] | None = None
    limits: Mapping[str, Mapping[str, float]] = field(default_factory=dict)  # joint -> {lower, upper, ...}
    scenario_defaults: ScenarioDefaults = field(default_factory=ScenarioDefaults)


def ros_name(text: str) -> str:
    """`text` as a ROS graph name component: letters, digits and _, not starting with a digit."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", text.strip())
    if name and not name[0].isalpha():
        name = "robot_" + name
    return name


def _moving_count(model: UrdfModel, base: str, link: str) -> int:
    return sum(joint.moving for joint in model.path(base, link))


def end_effector(model: UrdfModel, base: str, source: str = "URDF", notes: list[str] | None = None) -> str:
    """The leaf below `base` at the end of the longest chain of moving joints; for a gripper's fingers, the hand they
    hang from (its tool frame if it has one), said in `notes` (RobotError when ambiguous)."""
    below = [leaf for leaf in model.leaves() if leaf != base and _is_below(model, base, leaf)]
    counts = {leaf: _moving_count(model, base, leaf) for leaf in below}
    longest = max(counts.values(), default=0)
    if longest == 0:
        raise RobotError(
            f"{source}: robot {model.name!r} has no moving joint below link {base!r} "
            f"(moving joints are {', '.join(MOVING_TYPES)})"
        )
    candidates = [leaf for leaf, count in counts.items() if count == longest]
    if len(candidates) == 1:
        return candidates[0]
    # A finger may end in more than one leaf (a fingertip frame, a pad): one joint, one finger.
    fingers = list(
        {joint.name: joint for joint in (_last_moving_joint(model, base, leaf) for leaf in candidates)}.values()
    )
    hands = {finger.parent for finger in fingers}
    hand = hands.pop() if len(hands) == 1 else ""
    # Fingers: two or more joints from one hand, which the arm carries (not the base of two arms).
    if hand and len(fingers) >= 2 and _moving_count(model, base, hand) > 0:
        tools = [
            joint.child for joint in model.joints if joint.parent == hand and not joint.moving and joint.child in below
        ]
        chosen = tools[0] if len(tools) == 1 else hand
        what = f"the tool frame of {hand!r}" if chosen != hand else "the hand"
        if notes is not None:
            notes.append(
                f"end effector {chosen!r}: {what}, from which the gripper's fingers hang "
                f"({', '.join(sorted(finger.name for finger in fingers))}, held where they start); choose another with "
                f"--ee-link"
            )
        return chosen
    raise RobotError(
        f"{source}: the end effector of robot {model.name!r} is ambiguous, {len(candidates)} leaves end a "
        f"chain of {longest} moving joints: {', '.join(candidates)}; choose one with --ee-link "
        f"(or ee_link in the robot's YAML)"
    )


def _last_moving_joint(model: UrdfModel, base: str, leaf: str) -> UrdfJoint:
    """The moving joint nearest `leaf` on its path from `base` (there is one: the leaf ends a moving chain)."""
    return [joint for joint in model.path(base, leaf) if joint.moving][-1]


def _is_below(model: UrdfModel, base: str, link: str) -> bool:
    while link != base:
        joint = model.joint_above(link)
        if joint is None:
            return False
        link = joint.parent
    return True


def _moves(model: UrdfModel, link: str) -> bool:
    """Whether a moving joint lies anywhere between the root and `link`."""
    joint = model.joint_above(link)
    while joint is not None:
        if joint.moving:
            return True
        joint = model.joint_above(joint.parent)
    return False


def _limits(joint: UrdfJoint, notes: list[str], source: str) -> tuple[float, float, float, float]:
    """(lower, upper, velocity, effort) of a moving joint from its <limit>, with the stated defaults."""
    limit = joint.limit
    prismatic = joint.joint_type == "prismatic"
    unit, speed_unit = ("m", "m/s") if prismatic else ("rad", "rad/s")
    if joint.joint_type == "continuous":
        lower, upper = -2.0 * math.pi, 2.0 * math.pi
    else:
        lower = 0.0 if limit is None or limit.lower is None else limit.lower
        upper = 0.0 if limit is None or limit.upper is None else limit.upper
        if lower > upper:
            raise RobotError(
                f"{source}: joint {joint.name!r} has <limit lower={lower:g} upper={upper:g}>: lower above upper"
            )
        if upper == lower:  # URDF's defaults are 0 and 0: no range was given
            span = MISSING_PRISMATIC_RANGE if prismatic else MISSING_REVOLUTE_RANGE
            notes.append(f"joint {joint.name!r} has no position range in its <limit>; using ±{span:g} {unit}")
            lower, upper = -span, span
    velocity = None if limit is None else limit.velocity
    if velocity is None or not velocity > 0:
        velocity = MISSING_PRISMATIC_VELOCITY if prismatic else MISSING_REVOLUTE_VELOCITY
        notes.append(f"joint {joint.name!r} has no velocity limit; using {velocity:g} {speed_unit}")
    effort = None if limit is None else limit.effort
    if effort is None or not effort > 0:
        effort = math.inf
        notes.append(f"joint {joint.name!r} has no effort limit; its drive force is unlimited")
    return lower, upper, velocity, effort


def _apply_limit_overrides(
    names: Sequence[str], table: np.ndarray, overrides: Mapping[str, Mapping[str, float]], source: str
) -> None:
    for joint, values in overrides.items():
        if joint not in names:
            raise RobotError(
                f"{source}: limits for joint {joint!r}, which is not a controlled joint ({', '.join(names)})"
            )
        for key, value in values.items():
            if key not in LIMIT_KEYS:
                raise RobotError(f"{source}: joint {joint!r} limit {key!r} is not one of {', '.join(LIMIT_KEYS)}")
            if not (isinstance(value, (int, float)) and not math.isnan(value)):
                raise RobotError(f"{source}: joint {joint!r} limit {key} must be a number, got {value!r}")
            table[names.index(joint), LIMIT_KEYS.index(key)] = float(value)


def _check_scenario_defaults(own: ScenarioDefaults, names: Sequence[str], source: str) -> None:
    if own.one_joint is not None and own.one_joint not in names:
        raise RobotError(
            f"{source}: scenario_defaults.one_joint names joint {own.one_joint!r}, which is not a controlled "
            f"joint ({', '.join(names)})"
        )
    for what, values in (
        ("sweep.centres", own.sweep_centres),
        ("sweep.amplitudes", own.sweep_amplitudes),
    ):
        if values is not None and len(values) != len(names):
            raise RobotError(
                f"{source}: scenario_defaults.{what} needs {len(names)} numbers (for {', '.join(names)}), "
                f"got {len(values)}"
            )
    for what, values in (
        ("ik_goal", own.ik_goal_position),
        ("orientation_goal", own.orientation_goal_position),
        ("ik_goal.rpy", own.ik_goal_rpy),
        ("orientation_goal.rpy", own.orientation_goal_rpy),
    ):
        if values is not None and len(values) != 3:
            raise RobotError(f"{source}: scenario_defaults.{what} needs 3 numbers, got {len(values)}")


def derive_robot(
    model: UrdfModel,
    urdf_path: Path,
    overrides: RobotOverrides = RobotOverrides(),
    source: str = "",
    cli_args: tuple[str, ...] = (),
) -> RobotSpec:
    """The robot of `model` (read from `urdf_path`) with `overrides` applied; `source` names it in errors."""
    source = source or str(urdf_path)
    for joint in model.joints:
        if joint.joint_type in ("floating", "planar"):
            raise RobotError(
                f"{source}: joint {joint.name!r} is {joint.joint_type}, which a position drive cannot "
                f"move; supported joint types: {', '.join(MOVING_TYPES)}, fixed"
            )
    if not any(joint.moving for joint in model.joints):
        raise RobotError(
            f"{source}: URDF robot {model.name!r} has no moving joint (moving joints are {', '.join(MOVING_TYPES)})"
        )
    base = overrides.base_link or model.root
    if base not in model.links:
        raise RobotError(f"{source}: no link {base!r} for the base; links: {', '.join(model.links)}")
    notes: list[str] = []
    ee = overrides.ee_link or end_effector(model, base, source, notes)
    if ee not in model.links:
        raise RobotError(f"{source}: no link {ee!r} for the end effector; links: {', '.join(model.links)}")
    if not _is_below(model, base, ee):
        raise RobotError(f"{source}: end-effector link {ee!r} is not below base link {base!r}")
    chain = [joint for joint in model.path(base, ee) if joint.moving]
    if not chain:
        raise RobotError(f"{source}: no moving joint between base link {base!r} and end-effector link {ee!r}")

    names = [joint.name for joint in chain]
    table = np.array([_limits(joint, notes, source) for joint in chain], dtype=float)
    _apply_limit_overrides(names, table, overrides.limits, source)
    lower, upper, velocity, effort = table.T
    for j, name in enumerate(names):
        if not lower[j] < upper[j] or not (velocity[j] > 0 and effort[j] > 0):
            raise RobotError(
                f"{source}: joint {name!r} limits must have lower < upper and velocity, effort > 0; "
                f"got lower {lower[j]:g}, upper {upper[j]:g}, velocity {velocity[j]:g}, "
                f"effort {effort[j]:g}"
            )
    types = tuple(joint.joint_type for joint in chain)
    if overrides.home is None:
        home = np.where(np.array(types) == "continuous", 0.0, (lower + upper) / 2.0)
    else:
        home = np.array(overrides.home, dtype=float)
        if home.shape != (len(names),) or not np.all(np.isfinite(home)):
            raise RobotError(
                f"{source}: home needs {len(names)} finite numbers (for {', '.join(names)}), got {list(overrides.home)}"
            )
        outside = [name for name, q, lo, hi in zip(names, home, lower, upper) if not lo - 1e-9 <= q <= hi + 1e-9]
        if outside:
            raise RobotError(f"{source}: home {home.tolist()} is outside the limits of {', '.join(outside)}")

    _check_scenario_defaults(overrides.scenario_defaults, names, source)
    name = ros_name(overrides.name or model.name or urdf_path.stem)
    if not name:
        raise RobotError(f"{source}: the robot has no usable name; give one with --name")
    moving_links = [link for link in model.links if _moves(model, link)]
    inertia_less = tuple(link for link in moving_links if model.links[link].mass is None)
    zeroed = tuple(link for link in moving_links if not model.links[link].inertia_is_physical())
    return RobotSpec(
        name=name,
        urdf_path=urdf_path,
        joint_names=tuple(names),
        joint_types=types,
        lower=lower.copy(),
        upper=upper.copy(),
        max_velocity=velocity.copy(),
        max_effort=effort.copy(),
        base_link=base,
        ee_link=ee,
        topic_prefix=f"/{name}",
        home=home,
        scenario_defaults=overrides.scenario_defaults,
        default_inertia_links=inertia_less,
        zeroed_inertia_links=zeroed,
        notes=tuple(notes),
        cli_args=cli_args,
    )
