"""The study's approach paths: end-effector motions towards the patient's hand, as task-space geometry and timing.
Pure logic.

Every path is a curve from a start point to an end point that lies `standoff` from the hand (the distance from the
end-effector point to the hand's nearest point, as the participant judges it): test 1 uses stand-offs of a few
centimetres to decimetres, test 2 ends on top of the hand (ON_TOP, 2 cm). The curve passes through a via point
half-way (a quadratic Bézier through it; a straight line where there is none). Shapes are given in the hand frame:
origin at the centre of the hand's top face, x the horizontal direction from the robot's base towards the hand, z up;
a scene may scale them (its approach_scale) for an arm that cannot reach the thesis's starts.

  straight      from above and in front (the robot's side), a straight line
  vertical      from high above the hand, straight down
  lateral_arc   from the side away from the participant, sweeping round to the front
  over_the_top  from beyond the hand, up over it through a high via point, then down onto it
  diagonal      from above, in front and to the side, a straight line

Timing: minimum-jerk along the arc length, s(τ) = L·(10τ³ − 15τ⁴ + 6τ⁵), which starts and ends at rest with zero
acceleration and peaks at 1.875·L/T half-way; T is the shortest whole number of steps dt with that peak at most
the requested speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.study.design.errors import DesignError
from sim.study.design.scene import Box, Scene
from sim.wire.contract import STEP_S

__all__ = [
    "PATH_NAMES",
    "ON_TOP",
    "MIN_STANDOFF",
    "MAX_STANDOFF",
    "PathShape",
    "SHAPES",
    "ApproachPath",
    "hand_frame",
    "end_point",
    "approach_path",
    "minimum_jerk",
]

ON_TOP = 0.02  # m: test 2's end, on top of the hand
MIN_STANDOFF, MAX_STANDOFF = 0.01, 0.3  # m
MIN_TRAVEL = 0.05  # m: every path starts at least this much farther from the hand than it ends
_PEAK_FACTOR = 1.875  # minimum jerk: peak speed = 1.875 · length / duration
_DENSE = 4001  # samples of the curve for its arc length
# End points already found, by their exact inputs (the hand's box, the direction, the stand-off): a scene's fit asks
# for the same ones again and again (every speed of a stand-off, each screen of a candidate, its plans), some four
# times over for one found, and each is 80 halvings. Emptied when full.
_END_POINTS: dict[tuple[bytes, bytes, float, bytes, float], np.ndarray] = {}
_END_POINTS_KEPT = 4096


@dataclass(frozen=True)
class PathShape:
    name: str
    start: tuple[float, float, float]  # hand frame, m
    via: tuple[float, float, float] | None  # passed half-way; None: a straight line
    approach: tuple[float, float, float]  # direction from the hand towards the end point (normalised on use)
    description: str


SHAPES: dict[str, PathShape] = {
    shape.name: shape
    for shape in (
        PathShape("straight", (-0.30, 0.0, 0.30), None, (-1.0, 0.0, 1.0), "a straight line from above and in front"),
        PathShape("vertical", (0.0, 0.0, 0.40), None, (0.0, 0.0, 1.0), "straight down from high above the hand"),
        PathShape(
            "lateral_arc",
            (0.02, 0.34, 0.24),
            (-0.20, 0.24, 0.26),
            (-1.0, 0.0, 1.0),
            "an arc from the side away from the participant round to the front",
        ),
        PathShape(
            "over_the_top",
            (0.12, 0.0, 0.36),
            (0.02, 0.0, 0.46),
            (0.0, 0.0, 1.0),
            "from beyond the hand, up over it and down onto it",
        ),
        PathShape(
            "diagonal",
            (-0.20, 0.22, 0.30),
            None,
            (-0.2, 0.22, 0.30),
            "a straight line from above, in front and to the side",
        ),
    )
}
PATH_NAMES: tuple[str, ...] = tuple(SHAPES)


@dataclass(frozen=True)
class ApproachPath:
    name: str
    standoff: float  # m, end point to the hand
    peak_speed: float  # m/s, the profile's actual peak (at most the requested one)
    dt: float
    times: np.ndarray  # (N,) s, k·dt
    positions: np.ndarray  # (N, 3) world, m
    speeds: np.ndarray  # (N,) m/s along the path
    length: float  # m

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    @property
    def start(self) -> np.ndarray:
        return self.positions[0]

    @property
    def end(self) -> np.ndarray:
        return self.positions[-1]


def hand_frame(scene: Scene) -> np.ndarray:
    """3x3 world ← hand frame (x: horizontal from the robot's base towards the hand, z up)."""
    towards = scene.hand.top[:2] - scene.base_position[:2]
    norm = float(np.linalg.norm(towards))
    if norm < 1e-6:
        raise DesignError("the hand is right under the robot's base: no direction to approach it from")
    x = np.array([towards[0] / norm, towards[1] / norm, 0.0])
    z = np.array([0.0, 0.0, 1.0])
    return np.column_stack([x, np.cross(z, x), z])


def end_point(hand: Box, direction: np.ndarray, standoff: float) -> np.ndarray:
    """The point along `direction` (world, from the hand's top centre) at `standoff` from the hand's nearest point.
    A negative `standoff` puts it that far from the top centre the other way, into the hand: the end-effector point
    of a tool whose surface stops short of it (a tool frame beyond the gripper's geometry) must end inside the hand
    for that surface to end at a small stand-off."""
    unit = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    if standoff < 0.0:
        return hand.top + standoff * unit
    size, position = np.asarray(hand.size, dtype=float), np.asarray(hand.position, dtype=float)
    key = (size.tobytes(), position.tobytes(), float(hand.yaw), unit.tobytes(), float(standoff))
    found = _END_POINTS.get(key)
    if found is None:
        low, high = 0.0, standoff + float(np.linalg.norm(hand.size))  # distance grows monotonically along the ray
        for _ in range(80):
            middle = (low + high) / 2.0
            low, high = (middle, high) if hand.distance(hand.top + middle * unit) < standoff else (low, middle)
        found = hand.top + (low + high) / 2.0 * unit
        if len(_END_POINTS) >= _END_POINTS_KEPT:
            _END_POINTS.clear()
        _END_POINTS[key] = found
    return found.copy()  # (the caller's own: the one kept is never handed out)


def minimum_jerk(tau: np.ndarray) -> np.ndarray:
    """s(τ)/L for τ in [0, 1]."""
    tau = np.clip(tau, 0.0, 1.0)
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


def _curve(start: np.ndarray, via: np.ndarray | None, end: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(len(u), 3): the quadratic Bézier from start to end through via at u = ½ (a line without via)."""
    control = (start + end) / 2.0 if via is None else 2.0 * via - (start + end) / 2.0
    u = u[:, None]
    return (1.0 - u) ** 2 * start + 2.0 * u * (1.0 - u) * control + u**2 * end


def approach_path(
    scene: Scene, name: str, standoff: float, peak_speed: float, dt: float = STEP_S, ee_standoff: float | None = None
) -> ApproachPath:
    """Path `name` of SHAPES to `standoff` (m) from the hand, timed to peak at most at `peak_speed` (m/s). The path
    is the end-effector point's; `ee_standoff` is that point's own stand-off where the robot's nearest surface is
    not that point (sim.study.design.feasibility finds it; negative: inside the hand, see end_point), else the
    stand-off itself."""
    shape = SHAPES.get(name)
    if shape is None:
        raise DesignError(f"unknown path {name!r}; known paths: {', '.join(PATH_NAMES)}")
    if not (math.isfinite(standoff) and MIN_STANDOFF <= standoff <= MAX_STANDOFF):
        raise DesignError(f"stand-off must be {MIN_STANDOFF}..{MAX_STANDOFF} m, got {standoff!r}")
    if not (math.isfinite(peak_speed) and 0.0 < peak_speed <= 1.0):
        raise DesignError(f"peak speed must be > 0 and at most 1 m/s, got {peak_speed!r}")
    if not (math.isfinite(dt) and dt > 0.0):
        raise DesignError(f"dt must be > 0 s, got {dt!r}")
    frame = hand_frame(scene)
    top = scene.hand.top
    start = top + frame @ (scene.approach_scale * np.array(shape.start))
    via = None if shape.via is None else top + frame @ (scene.approach_scale * np.array(shape.via))
    point_standoff = standoff if ee_standoff is None else ee_standoff
    end = end_point(scene.hand, frame @ np.array(shape.approach), point_standoff)
    # A start too near the hand for this stand-off (a large one, on small shapes or with a tool that reaches far
    # beyond the end-effector point) moves out from the hand along its own direction: every path travels at least
    # MIN_TRAVEL. The thesis's shapes at their size never need it.
    if scene.hand.distance(start) < point_standoff + MIN_TRAVEL:
        start = end_point(scene.hand, start - top, point_standoff + MIN_TRAVEL)
    dense_u = np.linspace(0.0, 1.0, _DENSE)
    dense = _curve(start, via, end, dense_u)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    length = float(arc[-1])
    steps = max(1, math.ceil(_PEAK_FACTOR * length / (peak_speed * dt) - 1e-9))
    duration = steps * dt
    times = np.arange(steps + 1) * dt
    travelled = length * minimum_jerk(times / duration)
    positions = _curve(start, via, end, np.interp(travelled, arc, dense_u))
    positions[0], positions[-1] = start, end
    tau = times / duration
    speeds = length / duration * 30.0 * tau**2 * (1.0 - tau) ** 2  # d/dt of L·s(t/T)
    return ApproachPath(name, standoff, float(speeds.max()), dt, times, positions, speeds, length)
