"""The motion limits a plan must keep before any motion, and the check that says, one line per refusal, which limit a
plan's samples or its braking would break. Pure logic.

A robot's limits are its URDF's (the joints' position range and velocity; a URDF states no acceleration or jerk) and,
where one is known, its maker's published table (KNOWN_TABLES, picked by table_for), the lower of the two where both
speak. A maker may publish a kind of limit for none of its joints (Universal Robots publish no acceleration or
jerk): that kind is then unknown (None), never made up, and the check says it was not checked (coverage). The check
applies a declared safety margin: a motion may use that fraction of each velocity, acceleration and jerk limit; a
position must stay within the URDF's range itself. These are the toolkit's own checks; they never replace the
robot's own stop.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.robots import RobotSpec
from sim.study.safety.errors import SafetyError

__all__ = [
    "DEFAULT_MARGIN",
    "PublishedLimits",
    "PANDA_LIMITS",
    "UR5_LIMITS",
    "UR10_LIMITS",
    "IIWA7_LIMITS",
    "IIWA14_LIMITS",
    "XARM5_LIMITS",
    "XARM6_LIMITS",
    "XARM7_LIMITS",
    "KNOWN_TABLES",
    "names_fit",
    "table_for",
    "MotionLimits",
    "limits_for",
    "coverage",
    "Exceedance",
    "POSITION_TOLERANCE",
    "position_exceedances",
    "motion_exceedances",
    "motion_refusals",
]

DEFAULT_MARGIN = 0.8  # a plan may use this fraction of every limit


@dataclass(frozen=True)
class PublishedLimits:
    """A maker's table: per joint (in the maker's joint order) and for the end effector in Cartesian space. None
    where the maker publishes no such limit (`unpublished` says so, for the check's "not checked")."""

    source: str
    robots: tuple[str, ...]  # the robot names it applies to: a name, or a name followed by "_..." (ur5_robot)
    joints: tuple[tuple[str, ...], ...]  # the joints' names in order, one tuple per naming in use; see names_fit
    velocity: tuple[float, ...]  # rad/s (m/s for a prismatic joint)
    acceleration: tuple[float, ...] | None  # rad/s²
    jerk: tuple[float, ...] | None  # rad/s³
    cartesian_velocity: float | None = None  # m/s
    cartesian_acceleration: float | None = None  # m/s²
    cartesian_jerk: float | None = None  # m/s³
    unpublished: str = ""  # why a kind above is None


def _degrees(*values: float) -> tuple[float, ...]:
    return tuple(math.radians(value) for value in values)


def _numbered(stem: str, count: int) -> tuple[str, ...]:
    return tuple(f"{stem}{k}" for k in range(1, count + 1))


# Franka's documentation of its control interface (frankaemika.github.io/docs/control_parameters.html): joint and
# Cartesian velocity, acceleration and jerk.
PANDA_LIMITS = PublishedLimits(
    source="Franka Control Interface limits for the Panda",
    robots=("panda",),
    joints=(_numbered("joint", 7),),
    velocity=(2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61),
    acceleration=(15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0),
    jerk=(7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0),
    cartesian_velocity=1.7,
    cartesian_acceleration=13.0,
    cartesian_jerk=6500.0,
)
_UR_JOINTS = (
    "shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint",
)  # fmt: skip
_UR_NONE = "Universal Robots publish none; ur_description: acceleration limits are not publicly available"
# The CB3 user manuals (UR5 and UR10, version 3.13) as ros-industrial/universal_robot's
# ur_description/config/ur5|ur10/joint_limits.yaml (which Universal_Robots_ROS_Driver loads) cite them: joint
# speed only. The e-series (ur5e, ur10e) are other robots with other figures: their names do not match.
UR5_LIMITS = PublishedLimits(
    source="UR5 (CB3) user manual 3.13, via ur_description's joint_limits.yaml",
    robots=("ur5",),
    joints=(_UR_JOINTS,),
    velocity=_degrees(180, 180, 180, 180, 180, 180),
    acceleration=None,
    jerk=None,
    unpublished=_UR_NONE,
)
UR10_LIMITS = PublishedLimits(
    source="UR10 (CB3) user manual 3.13, via ur_description's joint_limits.yaml",
    robots=("ur10",),
    joints=(_UR_JOINTS,),
    velocity=_degrees(120, 120, 180, 180, 180, 180),
    acceleration=None,
    jerk=None,
    unpublished=_UR_NONE,
)
_IIWA_JOINTS = (_numbered("joint_", 7), _numbered("joint_a", 7))  # iiwa_stack, pybullet's; kuka_experimental's
_IIWA_NONE = "KUKA publish none; the specification gives the axes' speeds only"
# KUKA's "LBR iiwa 7 R800, LBR iiwa 14 R820 Specification", section 4.3.2 "Axis data" (also drake's
# iiwa_description/README.md and iiwa_constants.cc for the 14): the axes' maximum speeds.
IIWA7_LIMITS = PublishedLimits(
    source="KUKA LBR iiwa 7 R800 specification, axis data",
    robots=("iiwa7", "lbr_iiwa_7", "lbr_iiwa7", "lbr_iiwa_7_r800", "iiwa_7_r800"),
    joints=_IIWA_JOINTS,
    velocity=_degrees(98, 98, 100, 130, 140, 180, 180),
    acceleration=None,
    jerk=None,
    unpublished=_IIWA_NONE,
)
# The 14 R820 is the slower of the two in every axis: a robot named only "iiwa" or "lbr_iiwa" (iiwa_stack's default
# name, pybullet's kuka_iiwa/model.urdf, which are the 14's model) is held to it.
IIWA14_LIMITS = PublishedLimits(
    source="KUKA LBR iiwa 14 R820 specification, axis data",
    robots=("iiwa", "lbr_iiwa", "iiwa14", "lbr_iiwa_14", "lbr_iiwa14", "lbr_iiwa_14_r820", "iiwa_14_r820"),
    joints=_IIWA_JOINTS,
    velocity=_degrees(85, 85, 100, 75, 130, 135, 135),
    acceleration=None,
    jerk=None,
    unpublished=_IIWA_NONE,
)
_XARM_NONE = "UFACTORY publish none per joint; xarm_ros's joint_limits.yaml sets no acceleration limit"
# UFACTORY's xArm specification (maximum joint speed 180°/s) as xArm-Developer/xarm_ros's
# xarm5|xarm7_moveit_config/config/joint_limits.yaml state it: max_velocity 3.14 rad/s, no acceleration.


def _xarm(joints: int) -> PublishedLimits:
    return PublishedLimits(
        source=f"UFACTORY xArm {joints} specification, via xarm_ros's joint_limits.yaml",
        robots=(f"xarm{joints}", f"xarm_{joints}"),
        joints=(_numbered("joint", joints),),
        velocity=(3.14,) * joints,
        acceleration=None,
        jerk=None,
        unpublished=_XARM_NONE,
    )


XARM5_LIMITS, XARM6_LIMITS, XARM7_LIMITS = _xarm(5), _xarm(6), _xarm(7)
KNOWN_TABLES = (
    PANDA_LIMITS, UR5_LIMITS, UR10_LIMITS, IIWA7_LIMITS, IIWA14_LIMITS, XARM5_LIMITS, XARM6_LIMITS, XARM7_LIMITS,
)  # fmt: skip


def _name_fits(name: str, robot_name: str) -> bool:
    return robot_name == name or robot_name.startswith(f"{name}_")


def names_fit(table: PublishedLimits, joint_names: Sequence[str]) -> bool:
    """Whether the URDF's joints are the table's, in its order: each is the table's name, or ends with "_" or "/"
    and it (panda_joint1 for joint1, a prefix for a second arm)."""
    for naming in table.joints:
        if len(naming) == len(joint_names) and all(
            ours == theirs or ours.endswith((f"_{theirs}", f"/{theirs}")) for ours, theirs in zip(joint_names, naming)
        ):
            return True
    return False


def table_for(robot: RobotSpec) -> PublishedLimits | None:
    """The published table of the robot its name says (the longest of the tables' names that fits: lbr_iiwa_7_r800
    is the 7's, lbr_iiwa the 14's); None when no table's name fits. SafetyError when the named robot's joints are not
    the table's (their count, or their names in order): its limits would be applied to the wrong joints."""
    robot_name = robot.name.lower()
    fitting = [(len(name), table) for table in KNOWN_TABLES for name in table.robots if _name_fits(name, robot_name)]
    if not fitting:
        return None
    table = max(fitting, key=lambda pair: pair[0])[1]
    _check_fit(table, robot)
    return table


def _check_fit(table: PublishedLimits, robot: RobotSpec) -> None:
    kinds = (("velocity", table.velocity), ("acceleration", table.acceleration), ("jerk", table.jerk))
    for name, values in kinds:
        if values is not None and len(values) != robot.dof:
            raise SafetyError(
                f"{table.source}: {len(values)} joint {name} limits for {robot.name}'s {robot.dof} joints"
            )
    if not names_fit(table, robot.joint_names):
        expected = " or ".join(", ".join(naming) for naming in table.joints)
        raise SafetyError(
            f"{table.source}: {robot.name}'s joints ({', '.join(robot.joint_names)}) are not the table's ({expected})"
        )


@dataclass(frozen=True)
class MotionLimits:
    """What a motion of one robot may reach; None where nothing is known (a URDF gives no acceleration or jerk, and
    a maker may publish none): `unknown` says why, for what the check says it did not check."""

    joint_names: tuple[str, ...]
    lower: np.ndarray  # the URDF's position range; ±inf for a continuous joint
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray | None
    jerk: np.ndarray | None
    cartesian_velocity: float | None
    cartesian_acceleration: float | None
    cartesian_jerk: float | None
    source: str  # where the limits come from: "URDF", or "URDF and <the table's source>"
    unknown: str = ""  # why a kind above is None


def limits_for(robot: RobotSpec, table: PublishedLimits | None = None) -> MotionLimits:
    """The robot's URDF limits, with its published table (`table`, or table_for's) where there is one."""
    if table is None:
        table = table_for(robot)
    else:
        _check_fit(table, robot)
    continuous = np.array([kind == "continuous" for kind in robot.joint_types], dtype=bool)
    lower = np.where(continuous, -np.inf, np.asarray(robot.lower, dtype=float))  # derive's ±2π is no limit
    upper = np.where(continuous, np.inf, np.asarray(robot.upper, dtype=float))
    velocity = np.array(robot.max_velocity, dtype=float)
    names = tuple(robot.joint_names)
    if table is None:
        unknown = f"no published table for {robot.name}"
        return MotionLimits(names, lower, upper, velocity, None, None, None, None, None, "URDF", unknown)
    return MotionLimits(
        names, lower, upper, np.minimum(velocity, table.velocity),
        None if table.acceleration is None else np.array(table.acceleration, dtype=float),
        None if table.jerk is None else np.array(table.jerk, dtype=float),
        table.cartesian_velocity, table.cartesian_acceleration, table.cartesian_jerk,
        f"URDF and {table.source}", table.unpublished,
    )  # fmt: skip


def _listed(items: Sequence[str]) -> str:
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} and {items[-1]}"


def coverage(robot_name: str, limits: MotionLimits, margin: float) -> tuple[str, str]:
    """What the check held a motion to, as "within <robot>'s ... limits (<source>) ... at <margin>", and what it did
    not check and why ("" when it checked every kind): never "within its limits" where a kind is unknown."""
    kinds = ("velocity", "acceleration", "jerk")
    joint_bounds = (limits.velocity, limits.acceleration, limits.jerk)
    joint = [kind for kind, bound in zip(kinds, joint_bounds) if bound is not None]
    cartesian_bounds = (limits.cartesian_velocity, limits.cartesian_acceleration, limits.cartesian_jerk)
    cartesian = [kind for kind, bound in zip(kinds, cartesian_bounds) if bound is not None]
    held = f"its joint {_listed(joint)} limits"
    if cartesian:
        held += f" and the end effector's {_listed(cartesian)} limits"
    within = f"within {robot_name}'s joint position limits and, at {margin:.0%}, {held} ({limits.source})"
    missing = [f"joint {_listed([kind for kind in kinds if kind not in joint])}"] if len(joint) < 3 else []
    if len(cartesian) < 3:
        missing.append(f"the end effector's {_listed([kind for kind in kinds if kind not in cartesian])}")
    return within, f"{'; '.join(missing)} ({limits.unknown})" if missing else ""


_UNITS = {"velocity": "rad/s", "acceleration": "rad/s²", "jerk": "rad/s³"}


def _derivatives(times: np.ndarray, values: np.ndarray) -> list[np.ndarray]:
    """Velocity, acceleration and jerk of samples on a grid, by central differences (one-sided at the ends)."""
    out = []
    current = values
    for _ in range(3):
        current = np.gradient(current, times, axis=0)
        out.append(current)
    return out


@dataclass(frozen=True)
class Exceedance:
    """One limit a motion exceeds, at its worst sample. A position has no margin: it is past the URDF's range
    itself (allowed = limit, margin 1)."""

    what: str  # the motion: "approach diagonal", "braking from a press at t = 0.84 s"
    subject: str  # a joint's name, or "the end effector's"
    kind: str  # position, velocity, acceleration or jerk
    value: float
    unit: str
    time: float  # s into the motion
    allowed: float  # margin · limit
    limit: float
    margin: float
    source: str

    @property
    def ratio(self) -> float:
        """How far past its limit, to keep the worst of several: value / allowed; for a position 1 + the distance
        past (a position's limit may be 0 or negative)."""
        if self.kind == "position":
            return 1.0 + abs(self.value - self.limit)
        return self.value / self.allowed

    @property
    def line(self) -> str:
        if self.kind == "position":
            side = "upper" if self.value > self.limit else "lower"
            return (
                f"{self.what}: {self.subject} position {self.value:.4f} {self.unit} at t = {self.time:.2f} s is past "
                f"its {side} limit {self.limit:g} ({self.source})"
            )
        return (
            f"{self.what}: {self.subject} {self.kind} {self.value:.3f} {self.unit} at t = {self.time:.2f} s exceeds "
            f"{self.allowed:.3f}, {self.margin:.0%} of its limit {self.limit:g} ({self.source})"
        )


POSITION_TOLERANCE = 1e-9  # rad or m past a limit that is still on it (RobotSpec.within_limits's)


def position_exceedances(
    what: str, times: np.ndarray, joint_positions: np.ndarray, limits: MotionLimits
) -> list[Exceedance]:
    """Each joint whose samples go past its URDF range, at its sample furthest past."""
    q = np.asarray(joint_positions, dtype=float)
    past = np.maximum(q - limits.upper, limits.lower - q)  # > 0 past a limit, on one side at most
    found = []
    for j in np.flatnonzero(past.max(axis=0) > POSITION_TOLERANCE):
        k = int(np.argmax(past[:, j]))
        limit = float(limits.upper[j] if q[k, j] > limits.upper[j] else limits.lower[j])
        subject, value, time = limits.joint_names[j], float(q[k, j]), float(times[k])
        found.append(Exceedance(what, subject, "position", value, "rad", time, limit, limit, 1.0, "URDF"))
    return found


def motion_exceedances(
    what: str,
    times: Sequence[float] | np.ndarray,
    joint_positions: np.ndarray,
    limits: MotionLimits,
    margin: float = DEFAULT_MARGIN,
    world_positions: np.ndarray | None = None,
    derivatives: Sequence[np.ndarray] | None = None,
) -> list[Exceedance]:
    """Every limit a sampled motion exceeds, each at its worst sample (positions first); [] when it keeps them all.
    Limits that are None (unknown) are skipped: coverage says what was not checked. `derivatives` gives
    the joint velocities, accelerations and jerks when they are known exactly (a braking's); otherwise they come from
    the samples."""
    if not (math.isfinite(margin) and 0 < margin <= 1):
        raise SafetyError(f"the safety margin is the fraction of each limit a motion may use, in (0, 1]; got {margin}")
    t = np.asarray(times, dtype=float)
    q = np.asarray(joint_positions, dtype=float)
    found = position_exceedances(what, t, q, limits) if len(t) else []
    if len(t) < 4:
        return found  # too few samples to have a jerk: nothing moves that a rate limit could refuse
    joint = list(derivatives) if derivatives is not None else _derivatives(t, q)
    for kind, values, bound in zip(
        ("velocity", "acceleration", "jerk"), joint, (limits.velocity, limits.acceleration, limits.jerk)
    ):
        if bound is None:
            continue
        allowed = margin * np.asarray(bound)
        ratio = np.abs(values) / allowed
        for j in np.flatnonzero(ratio.max(axis=0) > 1.0):
            k = int(np.argmax(ratio[:, j]))
            found.append(
                Exceedance(
                    what, limits.joint_names[j], kind, float(abs(values[k, j])), _UNITS[kind], float(t[k]),
                    float(allowed[j]), float(bound[j]), margin, limits.source,
                )
            )  # fmt: skip
    if world_positions is not None:
        cartesian = _derivatives(t, np.asarray(world_positions, dtype=float))
        bounds = (limits.cartesian_velocity, limits.cartesian_acceleration, limits.cartesian_jerk)
        for kind, values, limit in zip(("velocity", "acceleration", "jerk"), cartesian, bounds):
            if limit is None:
                continue
            norms = np.linalg.norm(values, axis=1)
            k = int(np.argmax(norms))
            if norms[k] > margin * limit:
                unit = _UNITS[kind].replace("rad", "m")
                found.append(
                    Exceedance(
                        what, "the end effector's", kind, float(norms[k]), unit, float(t[k]), margin * limit, limit,
                        margin, limits.source,
                    )
                )  # fmt: skip
    return found


def motion_refusals(
    what: str,
    times: Sequence[float] | np.ndarray,
    joint_positions: np.ndarray,
    limits: MotionLimits,
    margin: float = DEFAULT_MARGIN,
    world_positions: np.ndarray | None = None,
    derivatives: Sequence[np.ndarray] | None = None,
) -> list[str]:
    """One line per limit a sampled motion exceeds (motion_exceedances), naming `what`, the joint or the end
    effector, the limit and the margin."""
    found = motion_exceedances(what, times, joint_positions, limits, margin, world_positions, derivatives)
    return [exceedance.line for exceedance in found]
