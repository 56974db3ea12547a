"""The motion limits a plan must keep before any motion, and the check that says, one line per refusal, which limit a
plan's samples or its braking would break. Pure logic.

A robot's limits are its URDF's (the joints' velocity; a URDF states no acceleration or jerk) and, where one is
known, its maker's published table (KNOWN_TABLES; the Panda's from Franka's documentation of its control interface),
the lower of the two where both speak. The check applies a declared safety margin: a motion may use that fraction of
each limit. These are the toolkit's own checks; they never replace the robot's own stop.
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
    "KNOWN_TABLES",
    "MotionLimits",
    "limits_for",
    "Exceedance",
    "motion_exceedances",
    "motion_refusals",
]

DEFAULT_MARGIN = 0.8  # a plan may use this fraction of every limit


@dataclass(frozen=True)
class PublishedLimits:
    """A maker's table: per joint (in the URDF's joint order) and for the end effector in Cartesian space."""

    source: str
    velocity: tuple[float, ...]  # rad/s (m/s for a prismatic joint)
    acceleration: tuple[float, ...]  # rad/s²
    jerk: tuple[float, ...]  # rad/s³
    cartesian_velocity: float  # m/s
    cartesian_acceleration: float  # m/s²
    cartesian_jerk: float  # m/s³


PANDA_LIMITS = PublishedLimits(
    source="Franka Control Interface limits for the Panda",
    velocity=(2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61),
    acceleration=(15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0),
    jerk=(7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0),
    cartesian_velocity=1.7,
    cartesian_acceleration=13.0,
    cartesian_jerk=6500.0,
)
KNOWN_TABLES = {"panda": PANDA_LIMITS}  # by the robot's name (its YAML's `name`)


@dataclass(frozen=True)
class MotionLimits:
    """What a motion of one robot may reach; None where nothing is known (a URDF gives no acceleration or jerk)."""

    joint_names: tuple[str, ...]
    velocity: np.ndarray
    acceleration: np.ndarray | None
    jerk: np.ndarray | None
    cartesian_velocity: float | None
    cartesian_acceleration: float | None
    cartesian_jerk: float | None
    source: str  # where the limits come from: "URDF", or "URDF and <the table's source>"


def limits_for(robot: RobotSpec, table: PublishedLimits | None = None) -> MotionLimits:
    """The robot's URDF limits, with its published table (`table`, or the known one for its name) where there is one."""
    table = table if table is not None else KNOWN_TABLES.get(robot.name)
    velocity = np.array(robot.max_velocity, dtype=float)
    if table is None:
        return MotionLimits(tuple(robot.joint_names), velocity, None, None, None, None, None, "URDF")
    for name, values in (("velocity", table.velocity), ("acceleration", table.acceleration), ("jerk", table.jerk)):
        if len(values) != robot.dof:
            raise SafetyError(
                f"{table.source}: {len(values)} joint {name} limits for {robot.name}'s {robot.dof} joints"
            )
    return MotionLimits(
        tuple(robot.joint_names),
        np.minimum(velocity, table.velocity),
        np.array(table.acceleration, dtype=float),
        np.array(table.jerk, dtype=float),
        table.cartesian_velocity,
        table.cartesian_acceleration,
        table.cartesian_jerk,
        f"URDF and {table.source}",
    )


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
    """One limit a motion exceeds, at its worst sample."""

    what: str  # the motion: "approach diagonal", "braking from a press at t = 0.84 s"
    subject: str  # a joint's name, or "the end effector's"
    kind: str  # velocity, acceleration or jerk
    value: float
    unit: str
    time: float  # s into the motion
    allowed: float  # margin · limit
    limit: float
    margin: float
    source: str

    @property
    def ratio(self) -> float:
        return self.value / self.allowed

    @property
    def line(self) -> str:
        return (
            f"{self.what}: {self.subject} {self.kind} {self.value:.3f} {self.unit} at t = {self.time:.2f} s exceeds "
            f"{self.allowed:.3f}, {self.margin:.0%} of its limit {self.limit:g} ({self.source})"
        )


def motion_exceedances(
    what: str,
    times: Sequence[float] | np.ndarray,
    joint_positions: np.ndarray,
    limits: MotionLimits,
    margin: float = DEFAULT_MARGIN,
    world_positions: np.ndarray | None = None,
    derivatives: Sequence[np.ndarray] | None = None,
) -> list[Exceedance]:
    """Every limit a sampled motion exceeds, each at its worst sample; [] when it keeps them all. `derivatives` gives
    the joint velocities, accelerations and jerks when they are known exactly (a braking's); otherwise they come from
    the samples."""
    if not (math.isfinite(margin) and 0 < margin <= 1):
        raise SafetyError(f"the safety margin is the fraction of each limit a motion may use, in (0, 1]; got {margin}")
    t = np.asarray(times, dtype=float)
    q = np.asarray(joint_positions, dtype=float)
    if len(t) < 4:
        return []  # too few samples to have a jerk: nothing moves that a limit could refuse
    joint = list(derivatives) if derivatives is not None else _derivatives(t, q)
    found = []
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
