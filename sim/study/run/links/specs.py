"""Which link each condition uses, as the runner's --link option gives it, and the arms' drivers' presets. Pure.

A condition's link is `stream` (the stand-in's, the default), a driver's preset, or a trajectory controller's
namespace with its joint-states topic (`NAMESPACE,JOINT_STATES_TOPIC`). The presets name where each driver puts its
controller and its joint states in its own launch files' defaults; a lab that remaps them gives the namespace.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from sim.study.run.errors import RunError

__all__ = [
    "STREAM",
    "STALE_AFTER",
    "TRACKING_TOLERANCE",
    "SURFACE_TOLERANCE",
    "DISTANCE_FLOOR",
    "TrajectoryLinkSpec",
    "PRESETS",
    "link_spec",
    "link_specs",
]

STREAM = "stream"
STALE_AFTER = 0.25  # s without a new joint state during a motion: the feed is stale and the arm is stopped
TRACKING_TOLERANCE = 0.1  # rad: the largest joint error against the commanded path before the arm is stopped
# m: the most the arm's tracking error may change its distance to the hand (the achieved state's against the commanded
# one's): judged where it matters for the floor, at the robot's surface nearest the hand
SURFACE_TOLERANCE = 0.005
DISTANCE_FLOOR = 0.01  # m: no planned point, braked rest or achieved state may come closer to the hand


@dataclass(frozen=True)
class TrajectoryLinkSpec:
    """A ros_control joint_trajectory_controller: its namespace and where the arm's joint states come."""

    namespace: str  # e.g. /position_joint_trajectory_controller
    joint_states_topic: str
    preset: str = ""  # the driver's preset it came from; "" when given by its namespace
    stale_after: float = STALE_AFTER
    tracking_tolerance: float = TRACKING_TOLERANCE
    floor: float = DISTANCE_FLOOR
    speed_scale: float = 1.0  # the rehearsal's reduced speed: the approach's timing stretched by 1 / speed_scale
    surface_tolerance: float = SURFACE_TOLERANCE

    @property
    def label(self) -> str:
        return f"{self.preset} ({self.namespace})" if self.preset else self.namespace


PRESETS: Mapping[str, TrajectoryLinkSpec] = {
    "franka_ros": TrajectoryLinkSpec(
        "/position_joint_trajectory_controller", "/franka_state_controller/joint_states", "franka_ros"
    ),
    "ur_robot_driver": TrajectoryLinkSpec("/scaled_pos_joint_traj_controller", "/joint_states", "ur_robot_driver"),
    "iiwa_stack": TrajectoryLinkSpec(
        "/iiwa/PositionJointInterface_trajectory_controller", "/iiwa/joint_states", "iiwa_stack"
    ),
    "xarm_ros": TrajectoryLinkSpec("/xarm/xarm7_traj_controller", "/xarm/joint_states", "xarm_ros"),
}


def _topic(text: str, what: str, given: str) -> str:
    name = text.strip().rstrip("/")
    if not name.startswith("/") or len(name) < 2 or any(c.isspace() for c in name):
        raise RunError(f"--link: {what} must be an absolute ROS name such as /arm/controller, got {given!r}")
    return name


def link_spec(text: str) -> TrajectoryLinkSpec | None:
    """A link as --link gives it after `CONDITION=`: None for the stream, else the trajectory controller."""
    given = text.strip()
    if given == STREAM:
        return None
    if given in PRESETS:
        return PRESETS[given]
    namespace, comma, topic = given.partition(",")
    if not comma:
        raise RunError(
            f"--link: {given!r} is neither {STREAM}, a preset ({', '.join(PRESETS)}) nor NAMESPACE,JOINT_STATES_TOPIC"
        )
    return TrajectoryLinkSpec(_topic(namespace, "the namespace", given), _topic(topic, "the joint-states topic", given))


def link_specs(
    given: Iterable[str],
    conditions: Iterable[str],
    stale_after: float = STALE_AFTER,
    tracking_tolerance: float = TRACKING_TOLERANCE,
    floor: float = DISTANCE_FLOOR,
    speed_scale: float = 1.0,
    surface_tolerance: float = SURFACE_TOLERANCE,
) -> dict[str, TrajectoryLinkSpec]:
    """--link CONDITION=LINK, each condition once: the conditions on a trajectory controller (the rest stream)."""
    known = list(conditions)
    checked = ((stale_after, "--stale-after"), (tracking_tolerance, "--tracking-tolerance"))
    for value, name in (*checked, (surface_tolerance, "--surface-tolerance")):
        if not (math.isfinite(value) and value > 0):
            raise RunError(f"{name} must be > 0, got {value!r}")
    if not (math.isfinite(floor) and floor >= 0):
        raise RunError(f"--floor must be >= 0 m, got {floor!r}")
    if not (math.isfinite(speed_scale) and 0.0 < speed_scale <= 1.0):
        raise RunError(f"--rehearsal-speed must be in (0, 1], got {speed_scale!r}")
    chosen: dict[str, TrajectoryLinkSpec] = {}
    seen: set[str] = set()
    for text in given:
        condition, equals, link = text.partition("=")
        condition = condition.strip()
        if not equals or condition not in known or condition in seen:
            raise RunError(f"--link must be CONDITION=LINK, a condition of {', '.join(known)} once, got {text!r}")
        seen.add(condition)
        spec = link_spec(link)
        if spec is not None:
            chosen[condition] = TrajectoryLinkSpec(
                spec.namespace, spec.joint_states_topic, spec.preset, stale_after, tracking_tolerance, floor,
                speed_scale, surface_tolerance,
            )  # fmt: skip
    return chosen
