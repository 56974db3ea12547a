"""Piecewise polynomial trajectories: waypoints hit exactly, boundary conditions, derivatives, validation."""

import numpy as np
import pytest

from sim.geometry.trajectory import PolynomialTrajectory, TrajectoryError, TrajectorySample

TIMES = np.array([0.0, 0.7, 1.5, 3.0, 3.2])


def _waypoints(dim: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-2.0, 2.0, size=(len(TIMES), dim))


@pytest.mark.parametrize("order", ["cubic", "quintic"])
@pytest.mark.parametrize("dim", [1, 3, 7])
def test_hits_every_waypoint_exactly_with_zero_velocity(order, dim):
    points = _waypoints(dim)
    traj = PolynomialTrajectory(TIMES, points, order=order)
    sample = traj.sample(TIMES)
    np.testing.assert_array_equal(sample.positions, points)
    np.testing.assert_allclose(sample.velocities, 0.0, atol=1e-9)
    if order == "quintic":
        np.testing.assert_allclose(sample.accelerations, 0.0, atol=1e-8)
    for t, p in zip(TIMES, points):
        np.testing.assert_array_equal(traj.sample(t).positions, p)


@pytest.mark.parametrize("order", ["cubic", "quintic"])
def test_velocity_and_acceleration_match_finite_differences(order):
    traj = PolynomialTrajectory(TIMES, _waypoints(3, seed=1), order=order)
    t = np.linspace(TIMES[0] + 1e-3, TIMES[-1] - 1e-3, 2001)
    h = 1e-6
    s = traj.sample(t)
    fd_vel = (traj.sample(t + h).positions - traj.sample(t - h).positions) / (2 * h)
    fd_acc = (traj.sample(t + h).velocities - traj.sample(t - h).velocities) / (2 * h)
    # Central differences are exact to O(h²) except within h of a knot, where the acceleration may jump (cubic).
    away = np.min(np.abs(t[:, None] - TIMES[None, :]), axis=1) > 2 * h
    np.testing.assert_allclose(s.velocities, fd_vel, atol=1e-5)
    np.testing.assert_allclose(s.accelerations[away], fd_acc[away], atol=1e-4)


def test_quintic_is_continuous_in_acceleration_and_cubic_in_velocity():
    points = _waypoints(2, seed=2)
    for order in ("cubic", "quintic"):
        traj = PolynomialTrajectory(TIMES, points, order=order)
        left, right = traj.sample(TIMES[1:-1] - 1e-11), traj.sample(TIMES[1:-1] + 1e-11)
        np.testing.assert_allclose(left.velocities, right.velocities, atol=1e-6)
        if order == "quintic":
            np.testing.assert_allclose(left.accelerations, right.accelerations, atol=1e-5)


def test_given_waypoint_velocities_are_met():
    points = _waypoints(2, seed=3)
    velocities = np.random.default_rng(4).uniform(-1, 1, size=points.shape)
    for order in ("cubic", "quintic"):
        traj = PolynomialTrajectory(TIMES, points, order=order, velocities=velocities)
        s = traj.sample(TIMES[:-1])
        np.testing.assert_allclose(s.velocities, velocities[:-1], atol=1e-9)
        np.testing.assert_allclose(traj.sample(TIMES[-1]).velocities, velocities[-1], atol=1e-8)


def test_holds_end_points_outside_the_time_span():
    points = _waypoints(3, seed=5)
    traj = PolynomialTrajectory(TIMES + 1.0, points)
    s = traj.sample(np.array([-5.0, 0.0, 0.99, 4.3, 100.0]))
    np.testing.assert_array_equal(s.positions[:3], np.repeat(points[:1], 3, axis=0))
    np.testing.assert_array_equal(s.positions[3:], np.repeat(points[-1:], 2, axis=0))
    np.testing.assert_array_equal(s.velocities, 0.0)
    np.testing.assert_array_equal(s.accelerations, 0.0)


def test_shapes_and_properties():
    traj = PolynomialTrajectory([0.0, 1.0], [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    assert (traj.start_time, traj.end_time, traj.dim) == (0.0, 1.0, 3)
    scalar = traj.sample(0.5)
    assert isinstance(scalar, TrajectorySample)
    assert scalar.positions.shape == scalar.velocities.shape == scalar.accelerations.shape == (3,)
    np.testing.assert_allclose(scalar.positions, [0.5, 1.0, 1.5])  # symmetric profile: half-way at mid-time
    many = traj.sample(np.linspace(0, 1, 11))
    assert many.positions.shape == many.velocities.shape == many.accelerations.shape == (11, 3)
    flat = PolynomialTrajectory([0.0, 2.0], [1.0, -1.0], order="cubic")
    assert flat.dim == 1 and flat.sample(1.0).positions.shape == (1,)


def test_peak_velocity_of_a_rest_to_rest_quintic():
    traj = PolynomialTrajectory([0.0, 2.0], [[0.0], [1.0]])
    assert traj.sample(1.0).velocities[0] == pytest.approx(15 / 8 * 1.0 / 2.0)  # 15/8 · Δp / T


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"times": [0.0, 1.0, 1.0], "waypoints": [[0], [1], [2]]}, "strictly increasing"),
        ({"times": [0.0, 2.0, 1.0], "waypoints": [[0], [1], [2]]}, "times[1]=2.0"),
        ({"times": [0.0], "waypoints": [[0]]}, "at least 2"),
        ({"times": [0.0, 1.0], "waypoints": [[0], [1], [2]]}, "waypoints must have shape (2, dim)"),
        ({"times": [0.0, 1.0], "waypoints": [[0], [1]], "order": "linear"}, "'linear'"),
        ({"times": [0.0, 1.0], "waypoints": [[0, 0], [1, 1]], "velocities": [[0], [0]]}, "velocities"),
        ({"times": [0.0, np.nan], "waypoints": [[0], [1]]}, "finite"),
    ],
)
def test_invalid_input_is_rejected_naming_the_problem(kwargs, fragment):
    with pytest.raises(TrajectoryError) as err:
        PolynomialTrajectory(**kwargs)
    assert fragment in str(err.value)
