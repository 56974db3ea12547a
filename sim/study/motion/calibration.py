"""A tracker calibrated into the scene's world frame, and its jitter at rest (pure logic: points in, numbers out).

calibration   the experimenter touches marked points of the scene (their world coordinates known) with a tracked
              point; the rigid transform (rotation and translation, no scale) that takes the tracker's coordinates of
              those touches onto the points' world coordinates is fitted by least squares (Kabsch's SVD solution,
              the reflection excluded), and its residuals are the distances left between each touch so moved and
              its point. A fit whose largest residual is above the declared bound is refused: a wrong point touched,
              a marker that slipped, or a tracker frame that drifted would otherwise move every measure silently
jitter        the RMS distance of a body's positions at rest from their mean (m): what a tracker adds to a still
              body, and so to a withdrawal's peak speed
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from sim.study.motion.errors import MotionError

__all__ = ["MIN_POINTS", "RigidTransform", "Calibration", "fit_calibration", "jitter"]

MIN_POINTS = 3  # three points not on one line fix a rigid transform
# the touched points must span a plane: their second principal spread at least this (m), or the rotation about
# their line is left to the noise
MIN_SPREAD = 0.02


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
class Calibration:
    transform: RigidTransform  # tracker -> world
    names: tuple[str, ...]  # the marked points, in the order touched
    world: np.ndarray  # (n, 3) their world coordinates
    touched: np.ndarray  # (n, 3) the touches in the tracker's frame
    residuals: np.ndarray  # (n,) m: each touch, moved into the world, to its point
    bound: float  # m: the largest residual accepted

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.residuals**2)))

    @property
    def max(self) -> float:
        return float(np.max(self.residuals))

    @property
    def worst(self) -> str:
        return self.names[int(np.argmax(self.residuals))]

    def to_data(self) -> dict[str, object]:
        """As JSON-ready data: the transform (matrix and translation), the points and the residuals."""
        return {
            "rotation": [[float(v) for v in row] for row in self.transform.rotation],
            "translation": [float(v) for v in self.transform.translation],
            "residual_rms_m": self.rms,
            "residual_max_m": self.max,
            "bound_m": self.bound,
            "points": [
                {"name": name, "world": [float(v) for v in w], "tracker": [float(v) for v in t], "residual_m": float(r)}
                for name, w, t, r in zip(self.names, self.world, self.touched, self.residuals)
            ],
        }

    @staticmethod
    def from_data(data: Mapping[str, object], source: str = "calibration") -> Calibration:
        """From `to_data`'s data; the fit is made again from its points (and checked against its bound)."""
        try:
            points = data["points"]
            bound = float(data["bound_m"])  # type: ignore[arg-type]
            assert isinstance(points, list)
            names = [str(p["name"]) for p in points]
            world = [[float(v) for v in p["world"]] for p in points]
            touched = [[float(v) for v in p["tracker"]] for p in points]
        except (KeyError, TypeError, ValueError, AssertionError) as error:
            raise MotionError(f"{source} is not a saved calibration: {error!r}") from None
        return fit_calibration(names, np.array(world), np.array(touched), bound)


def fit_calibration(names: Sequence[str], world: np.ndarray, touched: np.ndarray, bound: float) -> Calibration:
    """The rigid transform taking `touched` (n, 3, the tracker's frame) onto `world` (n, 3) by least squares, with
    its residuals. MotionError: fewer than MIN_POINTS points, points on a line, or a largest residual above `bound`
    (m), naming the point."""
    world, touched = np.asarray(world, dtype=float), np.asarray(touched, dtype=float)
    if world.ndim != 2 or world.shape[1:] != (3,) or world.shape != touched.shape or len(names) != len(world):
        raise MotionError(f"a calibration needs one touch per marked point, got {len(names)} names, {touched.shape}")
    if len(world) < MIN_POINTS:
        raise MotionError(f"a calibration needs at least {MIN_POINTS} points, got {len(world)}")
    if not (np.all(np.isfinite(world)) and np.all(np.isfinite(touched))):
        raise MotionError("a calibration's points must be finite")
    if not (math.isfinite(bound) and bound > 0):
        raise MotionError(f"a calibration's bound must be a positive length, got {bound!r}")
    for what, points in (("marked points", world), ("touches", touched)):
        spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
        if spread[1] < MIN_SPREAD:
            raise MotionError(f"the {what} lie on a line (spread {spread[1]:.4f} m across it): touch points apart")
    world_mean, touched_mean = world.mean(axis=0), touched.mean(axis=0)
    covariance = (touched - touched_mean).T @ (world - world_mean)
    u, _, vt = np.linalg.svd(covariance)
    flip = np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T)) or 1.0])  # a rotation, never a mirror
    rotation = vt.T @ flip @ u.T
    transform = RigidTransform(rotation, world_mean - rotation @ touched_mean)
    residuals = np.linalg.norm(transform.apply(touched) - world, axis=1)
    fitted = Calibration(transform, tuple(names), world, touched, residuals, float(bound))
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
