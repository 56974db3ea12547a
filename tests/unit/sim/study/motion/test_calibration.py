"""sim.study.motion.calibration: a simulated tracker with a known offset, rotation and jitter is calibrated and its
transform recovered within the jitter's bound; a fit above its bound, too few points or points on a line are
refused; the jitter at rest is the positions' RMS distance from their mean."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.geometry.frames import rpy_to_matrix
from sim.study.design.scene import load_scene
from sim.study.errors import StudyError
from sim.study.motion.calibration import Calibration, RigidTransform, fit_calibration, jitter
from sim.study.run.tracking import marked_points

SCENE_POINTS = marked_points(load_scene())
NAMES = tuple(SCENE_POINTS)
WORLD = np.array([SCENE_POINTS[name] for name in NAMES])
# the tracker's frame in the world: turned about every axis, its origin 2 m away
TRUE = RigidTransform(rpy_to_matrix(0.1, -0.2, 2.5), np.array([1.2, -0.8, 0.9]))


def touches(sd: float, seed: int = 1) -> np.ndarray:
    """What a simulated tracker reports at each marked point: the point in its own frame, plus jitter (SD per axis)."""
    rng = np.random.default_rng(seed)
    return TRUE.inverse().apply(WORLD) + rng.normal(0.0, sd, WORLD.shape)


def test_an_exact_tracker_is_recovered_exactly() -> None:
    fit = fit_calibration(NAMES, WORLD, touches(0.0), bound=1e-6)
    assert np.allclose(fit.transform.rotation, TRUE.rotation, atol=1e-9)
    assert np.allclose(fit.transform.translation, TRUE.translation, atol=1e-9)
    assert fit.max < 1e-9 and np.linalg.det(fit.transform.rotation) == pytest.approx(1.0)


def test_a_jittery_tracker_is_recovered_within_its_jitter() -> None:
    sd = 0.001  # 1 mm per axis
    fit = fit_calibration(NAMES, WORLD, touches(sd), bound=0.01)
    # each residual is about the jitter's size (a 3-D error of SD 1 mm per axis: some 1.6 mm), none far beyond
    assert 0.0 < fit.rms < 3 * sd and fit.max < 5 * sd
    # the fitted transform moves any point of the table's reach within a few jitters of where the true one does
    probe = TRUE.inverse().apply(np.array([[0.55, 0.0, 0.3], [0.0, -0.5, 0.0], [1.1, 0.5, 0.0]]))
    assert np.max(np.linalg.norm(fit.transform.apply(probe) - TRUE.apply(probe), axis=1)) < 3 * sd
    # saved and read again, the same fit
    again = Calibration.from_data(fit.to_data())
    assert np.allclose(again.transform.rotation, fit.transform.rotation) and again.names == NAMES


def test_a_fit_above_its_bound_is_refused_naming_its_worst_point() -> None:
    touched = touches(0.0)
    touched[2] += np.array([0.02, 0.0, 0.0])  # a wrong point touched, 2 cm off
    with pytest.raises(
        StudyError, match=r"calibration refused: its largest residual is [0-9.]+ mm \(at table_corner_1"
    ):
        fit_calibration(NAMES, WORLD, touched, bound=0.005)


def test_too_few_points_or_points_on_a_line_are_refused() -> None:
    with pytest.raises(StudyError, match="at least 3 points, got 2"):
        fit_calibration(NAMES[:2], WORLD[:2], touches(0.0)[:2], bound=0.01)
    line = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.2, 0.0, 0.0]])
    with pytest.raises(StudyError, match="lie on a line"):
        fit_calibration(("a", "b", "c"), line, line, bound=0.01)


def test_a_mirror_is_never_fitted() -> None:
    # touches mirrored in the tracker's frame cannot be matched by a rotation: the fit stays a rotation, and misses
    mirrored = touches(0.0) * np.array([1.0, 1.0, -1.0])
    fit = fit_calibration(NAMES, WORLD, mirrored, bound=10.0)
    assert np.linalg.det(fit.transform.rotation) == pytest.approx(1.0) and fit.max > 0.01


def test_jitter_is_the_rms_distance_from_the_mean() -> None:
    rng = np.random.default_rng(3)
    still = np.array([0.5, 0.1, 0.2]) + rng.normal(0.0, 0.0002, (20000, 3))
    assert jitter(still) == pytest.approx(0.0002 * math.sqrt(3), rel=0.02)
    assert jitter(np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])) == pytest.approx(1.0)
    assert math.isnan(jitter(np.zeros((1, 3))))
