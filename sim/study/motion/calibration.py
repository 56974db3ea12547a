"""A tracker calibrated into the scene's world frame, and its jitter at rest (pure logic: points in, numbers out).

calibration   the experimenter touches marked points of the scene (their world coordinates known) with a tracked
              point; the rigid transform (rotation and translation, no scale) that takes the tracker's coordinates of
              those touches onto the points' world coordinates is fitted by least squares (Kabsch's SVD solution),
              and its residuals are the distances left between each touch so moved and its point, in-sample and
              left out one at a time (each point predicted by the fit to the others). A calibration that would be
              wrong without saying so is refused, naming why:
              - points too near one line (their RMS distance from their best line below MIN_OFF_LINE): the rotation
                about that line would be left to the noise;
              - points too near one plane (their RMS distance from their best plane below the bound): points in
                one plane are matched equally well by a rotation and by its mirror image through that plane, so a
                tracker whose frame is mirrored (a driver's swapped axes, e.g. mocap_optitrack's old Y/Z swap) would
                be fitted exactly, and every body above the table relayed as far below it. Only points off the
                plane tell the two apart: with their RMS distance from it at least the bound, the mirror image of a
                proper tracker leaves residuals of twice the bound or more, far from what its noise may. (The
                tracker's declared "up" or its bodies' orientations could tell them apart too, but a wrong axis
                convention is the very mistake to catch, and a driver that mirrors positions need not mirror
                orientations alike; the points' geometry depends on neither.) So at least 4 points, not in a plane;
              - touches whose spread is not the points' (outside UNIT_RANGE times it): the tracker's unit, named
                when it is a usual one (millimetres: about 1000 times);
              - touches that a mirror image fits (within the bound) better than any rotation: the tracker's frame
                is mirrored, said so;
              - a largest in-sample residual above the bound: a wrong point touched, a marker that slipped, or a
                tracker frame that drifted, naming the worst point.
              The tracked point sits `tip` above the surface it touches (a marker ball's radius; every marked point
              is on a top face, touched from above): the fit takes the point `tip` above each marked point, as a
              rigid fit cannot see an offset common to every touch (it would move the translation, every pose by it)
jitter        the RMS distance of a body's positions at rest from their mean (m): what a tracker adds to a still
              body, and so to a withdrawal's peak speed
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from sim.study.motion.errors import MotionError

__all__ = [
    "MIN_POINTS",
    "MIN_OFF_LINE",
    "UNIT_RANGE",
    "UP",
    "RigidTransform",
    "Spread",
    "SavedPoints",
    "Calibration",
    "spread",
    "check_spread",
    "saved_points",
    "fit_calibration",
    "jitter",
]

MIN_POINTS = 4  # three points off one line fix a rigid transform; a fourth off their plane, its handedness
MIN_OFF_LINE = 0.1  # m: the points' RMS distance from their best line, at least
UNIT_RANGE = (0.5, 2.0)  # the touches' spread over the points', outside which the tracker's unit is taken to differ
UP = np.array([0.0, 0.0, 1.0])  # the world's up: the marked points are touched from above
UNITS = ((1000.0, "millimetres"), (100.0, "centimetres"), (39.37, "inches"))  # a tracker's unit, by its scale


@dataclass(frozen=True)
class RigidTransform:
    """world = rotation @ tracker + translation."""

    rotation: np.ndarray  # (3, 3), proper (det +1)
    translation: np.ndarray  # (3,)

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Points (3,) or (n, 3) in the tracker's frame, in the world."""
        return np.asarray(points, dtype=float) @ self.rotation.T + self.translation

    def apply_rotation(self, rotation: np.ndarray) -> np.ndarray:
        """An orientation (3, 3) in the tracker's frame, in the world."""
        return self.rotation @ np.asarray(rotation, dtype=float)

    def inverse(self) -> RigidTransform:
        return RigidTransform(self.rotation.T, -self.rotation.T @ self.translation)


@dataclass(frozen=True)
class Spread:
    """How far a point set is from degenerate, per point (it does not grow with their number)."""

    off_line: float  # m: the points' RMS distance from their best-fitting line
    off_plane: float  # m: their RMS distance from their best-fitting plane


def spread(points: np.ndarray) -> Spread:
    """The RMS distances of `points` (n, 3) from their best line and plane (the principal axes of their spread)."""
    points = np.asarray(points, dtype=float)
    values = np.zeros(3)
    found = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    values[: len(found)] = found
    n = len(points)
    return Spread(math.sqrt((values[1] ** 2 + values[2] ** 2) / n), math.sqrt(values[2] ** 2 / n))


def check_spread(points: np.ndarray, bound: float, what: str = "marked points") -> Spread:
    """`points`' spread, or MotionError when they lie too near one line (the rotation about it left to the noise)
    or one plane (a mirrored tracker fitted as well as a proper one; see the module's docstring)."""
    if len(points) < MIN_POINTS:
        raise MotionError(
            f"a calibration needs at least {MIN_POINTS} points, not all in one plane, got {len(points)}: with fewer "
            "a mirrored tracker frame fits as well as a proper one"
        )
    found = spread(points)
    if found.off_line < MIN_OFF_LINE:
        raise MotionError(
            f"the {what} lie near one line (RMS {found.off_line * 1000:.1f} mm from it, at least "
            f"{MIN_OFF_LINE * 1000:.0f} mm needed): the rotation about it would be left to the noise; choose points "
            "apart"
        )
    if found.off_plane < bound:
        raise MotionError(
            f"the {what} lie near one plane (RMS {found.off_plane * 1000:.1f} mm from it, at least the bound's "
            f"{bound * 1000:.1f} mm needed): a mirrored tracker frame would fit them as well as a proper one; add a "
            "point off their plane"
        )
    return found


def _fit(world: np.ndarray, touched: np.ndarray, handedness: float) -> tuple[np.ndarray, np.ndarray]:
    """The orthogonal matrix of determinant `handedness` (+1 a rotation, -1 a mirror) and the translation taking
    `touched` onto `world` best by least squares."""
    world_mean, touched_mean = world.mean(axis=0), touched.mean(axis=0)
    u, _, vt = np.linalg.svd((touched - touched_mean).T @ (world - world_mean))
    unconstrained = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    matrix = vt.T @ np.diag([1.0, 1.0, handedness * unconstrained]) @ u.T
    return matrix, world_mean - matrix @ touched_mean


def _residuals(world: np.ndarray, touched: np.ndarray, handedness: float) -> np.ndarray:
    matrix, translation = _fit(world, touched, handedness)
    return np.linalg.norm(touched @ matrix.T + translation - world, axis=1)


def _mirror_fits_better(world: np.ndarray, touched: np.ndarray) -> bool:
    """Whether the best orthogonal fit, unconstrained, is a mirror (then it leaves less than any rotation)."""
    u, _, vt = np.linalg.svd((touched - touched.mean(axis=0)).T @ (world - world.mean(axis=0)))
    return bool(np.linalg.det(vt.T @ u.T) < 0)


def _left_out(world: np.ndarray, touched: np.ndarray) -> np.ndarray:
    """Each point's distance from where the rotation fitted to the other points takes its touch (NaN where those
    lie on a line)."""
    out = np.full(len(world), math.nan)
    for k in range(len(world)):
        keep = np.arange(len(world)) != k
        if spread(world[keep]).off_line < 1e-6:
            continue
        matrix, translation = _fit(world[keep], touched[keep], 1.0)
        out[k] = float(np.linalg.norm(matrix @ touched[k] + translation - world[k]))
    return out


def _scale_text(ratio: float) -> str:
    if ratio >= 10:
        digits = int(math.floor(math.log10(ratio))) - 1
        return f"{round(ratio, -digits):.0f}"
    return f"{ratio:.2g}"


def _check_units(world: np.ndarray, touched: np.ndarray) -> None:
    size = math.sqrt(np.mean(np.sum((world - world.mean(axis=0)) ** 2, axis=1)))
    ratio = math.sqrt(np.mean(np.sum((touched - touched.mean(axis=0)) ** 2, axis=1))) / size
    if UNIT_RANGE[0] <= ratio <= UNIT_RANGE[1]:
        return
    named = [unit for scale, unit in UNITS if abs(ratio / scale - 1.0) < 0.25]
    guess = f"{named[0]}? the tracker must give metres" if named else "check the tracker's unit and the points touched"
    raise MotionError(
        f"calibration refused: the touches are about {_scale_text(ratio)}× as far apart as the scene's points: {guess}"
    )


@dataclass(frozen=True)
class Calibration:
    transform: RigidTransform  # tracker -> world
    names: tuple[str, ...]  # the marked points, in the order touched
    world: np.ndarray  # (n, 3) their world coordinates
    touched: np.ndarray  # (n, 3) the touches in the tracker's frame
    residuals: np.ndarray  # (n,) m: each touch, moved into the world, to its point (`tip` above it)
    bound: float  # m: the largest residual accepted
    tip: float  # m: the tracked point's height above the surface it touches
    left_out: np.ndarray  # (n,) m: each point's residual under the fit to the others (NaN: not made)
    geometry: Spread  # of the marked points

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.residuals**2)))

    @property
    def max(self) -> float:
        return float(np.max(self.residuals))

    @property
    def worst(self) -> str:
        return self.names[int(np.argmax(self.residuals))]

    @property
    def left_out_rms(self) -> float:
        """The RMS of the left-out residuals (NaN when none could be made)."""
        known = self.left_out[np.isfinite(self.left_out)]
        return float(np.sqrt(np.mean(known**2))) if len(known) else math.nan

    @property
    def left_out_max(self) -> float:
        known = self.left_out[np.isfinite(self.left_out)]
        return float(np.max(known)) if len(known) else math.nan

    @property
    def left_out_worst(self) -> str:
        known = np.where(np.isfinite(self.left_out), self.left_out, -1.0)
        return self.names[int(np.argmax(known))]

    def to_data(self) -> dict[str, object]:
        """As JSON-ready data: the transform (matrix and translation), the tip, the points and the residuals."""

        def number(value: float) -> float | None:
            return float(value) if math.isfinite(value) else None

        return {
            "rotation": [[float(v) for v in row] for row in self.transform.rotation],
            "translation": [float(v) for v in self.transform.translation],
            "tip_m": self.tip,
            "residual_rms_m": self.rms,
            "residual_max_m": self.max,
            "left_out_rms_m": number(self.left_out_rms),
            "left_out_max_m": number(self.left_out_max),
            "bound_m": self.bound,
            "off_line_rms_m": self.geometry.off_line,
            "off_plane_rms_m": self.geometry.off_plane,
            "points": [
                {
                    "name": name,
                    "world": [float(v) for v in w],
                    "tracker": [float(v) for v in t],
                    "residual_m": float(r),
                    "left_out_m": number(float(o)),
                }
                for name, w, t, r, o in zip(self.names, self.world, self.touched, self.residuals, self.left_out)
            ],
        }

    @staticmethod
    def from_data(data: Mapping[str, object], source: str = "calibration", bound: float | None = None) -> Calibration:
        """From `to_data`'s data; the fit is made again from its points and checked as a new one is, against its
        own bound or `bound`."""
        saved = saved_points(data, source)
        return fit_calibration(
            saved.names, saved.world, saved.touched, saved.bound if bound is None else bound, saved.tip
        )


@dataclass(frozen=True)
class SavedPoints:
    names: tuple[str, ...]
    world: np.ndarray  # (n, 3)
    touched: np.ndarray  # (n, 3)
    tip: float  # m
    bound: float  # m


def _vector(value: object, where: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != 3:
        count = f"{len(value)} coordinates" if isinstance(value, list) else repr(value)
        raise MotionError(f"{where} must be 3 coordinates, got {count}")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise MotionError(f"{where} must be 3 numbers, got {value!r}")
    return np.array(value, dtype=float)


def _length(data: Mapping[str, object], key: str, source: str) -> float:
    value = data.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise MotionError(f"{source} is not a saved calibration: {key} must be a length in m, got {value!r}")
    return float(value)


def saved_points(data: Mapping[str, object], source: str = "calibration") -> SavedPoints:
    """A saved calibration's points, tip and bound, read as `to_data` writes them; MotionError names what is not."""
    if not isinstance(data, Mapping):
        raise MotionError(f"{source} is not a saved calibration: not a mapping")
    points = data.get("points")
    if not isinstance(points, list) or not points:
        raise MotionError(f"{source} is not a saved calibration: no list of points")
    names, world, touched = [], [], []
    for k, point in enumerate(points, start=1):
        if not isinstance(point, Mapping) or not isinstance(point.get("name"), str):
            raise MotionError(f"{source} is not a saved calibration: point {k} has no name")
        where = f"{source}: point {k} ({point['name']})'s"
        names.append(point["name"])
        world.append(_vector(point.get("world"), f"{where} world"))
        touched.append(_vector(point.get("tracker"), f"{where} tracker"))
    tip, bound = _length(data, "tip_m", source), _length(data, "bound_m", source)
    return SavedPoints(tuple(names), np.array(world), np.array(touched), tip, bound)


def fit_calibration(
    names: Sequence[str], world: np.ndarray, touched: np.ndarray, bound: float, tip: float = 0.0
) -> Calibration:
    """The rigid transform taking `touched` (n, 3, the tracker's frame) onto `world` (n, 3) raised by `tip` (m) by
    least squares, with its residuals, in-sample and left out. MotionError, in one line: fewer than MIN_POINTS
    points, points near a line or a plane, touches in another unit, a mirrored tracker frame, or a largest residual
    above `bound` (m), naming the point."""
    world, touched = np.asarray(world, dtype=float), np.asarray(touched, dtype=float)
    if world.ndim != 2 or world.shape[1:] != (3,) or world.shape != touched.shape or len(names) != len(world):
        raise MotionError(f"a calibration needs one touch per marked point, got {len(names)} names, {touched.shape}")
    if not (np.all(np.isfinite(world)) and np.all(np.isfinite(touched))):
        raise MotionError("a calibration's points must be finite")
    if not (math.isfinite(bound) and bound > 0):
        raise MotionError(f"a calibration's bound must be a positive length, got {bound!r}")
    if not (math.isfinite(tip) and tip >= 0):
        raise MotionError(f"a calibration's tip must be a length, 0 or more, got {tip!r}")
    found = check_spread(world, bound)
    _check_units(world, touched)
    target = world + tip * UP
    rotation, translation = _fit(target, touched, 1.0)
    transform = RigidTransform(rotation, translation)
    residuals = np.linalg.norm(transform.apply(touched) - target, axis=1)
    fitted = Calibration(
        transform, tuple(names), world, touched, residuals, float(bound), float(tip), _left_out(target, touched), found
    )
    if _mirror_fits_better(target, touched):
        mirrored = _residuals(target, touched, -1.0)
        if np.max(mirrored) <= bound:
            raise MotionError(
                f"calibration refused: the tracker's frame is mirrored: check its axis convention (a mirror image of "
                f"the touches fits the points within {np.max(mirrored) * 1000:.1f} mm, the best rotation leaves "
                f"{fitted.max * 1000:.1f} mm at {fitted.worst})"
            )
    if fitted.max > bound:
        raise MotionError(
            f"calibration refused: its largest residual is {fitted.max * 1000:.1f} mm (at {fitted.worst}; RMS "
            f"{fitted.rms * 1000:.1f} mm), above the bound of {bound * 1000:.1f} mm: touch the points again"
        )
    return fitted


def jitter(positions: np.ndarray) -> float:
    """The RMS distance (m) of a body's positions at rest (n, 3) from their mean; NaN for fewer than two."""
    points = np.asarray(positions, dtype=float).reshape(-1, 3)
    if len(points) < 2:
        return math.nan
    return float(np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1))))
