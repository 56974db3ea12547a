"""ROS FLU ↔ Unity RUF conversions and the quaternion / Euler / matrix helpers."""

import math

import numpy as np
import pytest

from sim.geometry.frames import (
    FrameError,
    euler_xyz_to_quat,
    matrix_to_quat,
    matrix_to_rpy,
    quat_multiply,
    quat_to_euler_xyz,
    quat_to_matrix,
    ros_to_unity_matrix,
    ros_to_unity_point,
    ros_to_unity_quat,
    rotation_exp,
    rotation_vector,
    rpy_to_matrix,
    unity_to_ros_point,
    unity_to_ros_quat,
)

RNG = np.random.default_rng(1234)


def _random_quats(n: int) -> np.ndarray:
    q = RNG.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _rx(a):
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def _ry(a):
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def _rz(a):
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def test_axes_map_as_in_ros_tcp_connector_flu():
    # ROS forward (x) is Unity forward (z); ROS left (y) is Unity -x (x is right); ROS up (z) is Unity up (y).
    np.testing.assert_array_equal(ros_to_unity_point([1, 0, 0]), [0, 0, 1])
    np.testing.assert_array_equal(ros_to_unity_point([0, 1, 0]), [-1, 0, 0])
    np.testing.assert_array_equal(ros_to_unity_point([0, 0, 1]), [0, 1, 0])
    np.testing.assert_array_equal(ros_to_unity_point([1.0, 2.0, 3.0]), [-2.0, 3.0, 1.0])
    np.testing.assert_array_equal(ros_to_unity_quat([0.1, 0.2, 0.3, 0.9]), [0.2, -0.3, -0.1, 0.9])


def test_points_and_quaternions_round_trip_also_batched():
    points = RNG.normal(size=(100, 3))
    np.testing.assert_array_equal(unity_to_ros_point(ros_to_unity_point(points)), points)
    np.testing.assert_array_equal(ros_to_unity_point(unity_to_ros_point(points)), points)
    quats = _random_quats(100)
    np.testing.assert_array_equal(unity_to_ros_quat(ros_to_unity_quat(quats)), quats)
    np.testing.assert_array_equal(ros_to_unity_quat(unity_to_ros_quat(quats)), quats)


def test_a_rotation_applied_in_ros_equals_the_converted_rotation_applied_in_unity():
    for q_ros in _random_quats(200):
        p_ros = RNG.normal(size=3)
        rotated_then_converted = ros_to_unity_point(quat_to_matrix(q_ros) @ p_ros)
        converted_then_rotated = quat_to_matrix(ros_to_unity_quat(q_ros)) @ ros_to_unity_point(p_ros)
        np.testing.assert_allclose(converted_then_rotated, rotated_then_converted, atol=1e-12)
        np.testing.assert_allclose(
            quat_to_matrix(ros_to_unity_quat(q_ros)), ros_to_unity_matrix(quat_to_matrix(q_ros)), atol=1e-12
        )


def test_ros_yaw_left_is_a_unity_turn_about_up_that_keeps_handedness_semantics():
    # A +90° ROS yaw (counter-clockwise seen from above) turns forward into left.
    q_unity = ros_to_unity_quat(euler_xyz_to_quat(0.0, 0.0, math.pi / 2))
    forward_unity = ros_to_unity_point([1, 0, 0])
    np.testing.assert_allclose(quat_to_matrix(q_unity) @ forward_unity, ros_to_unity_point([0, 1, 0]), atol=1e-12)
    # In Unity that is a rotation about y (up) by -90°: left-handed, positive angles turn clockwise from above.
    np.testing.assert_allclose(q_unity, [0.0, -math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4)], atol=1e-12)


def test_euler_is_fixed_axis_xyz_like_urdf_rpy():
    for roll, pitch, yaw in RNG.uniform(-1.5, 1.5, size=(50, 3)):
        expected = _rz(yaw) @ _ry(pitch) @ _rx(roll)
        np.testing.assert_allclose(rpy_to_matrix(roll, pitch, yaw), expected, atol=1e-12)
        q = euler_xyz_to_quat(roll, pitch, yaw)
        np.testing.assert_allclose(quat_to_matrix(q), expected, atol=1e-12)
        np.testing.assert_allclose(quat_to_euler_xyz(q), (roll, pitch, yaw), atol=1e-9)
        np.testing.assert_allclose(matrix_to_rpy(expected), (roll, pitch, yaw), atol=1e-9)


def test_euler_at_gimbal_lock_still_reproduces_the_rotation():
    for pitch in (math.pi / 2, -math.pi / 2):
        q = euler_xyz_to_quat(0.3, pitch, -0.4)
        np.testing.assert_allclose(rpy_to_matrix(*quat_to_euler_xyz(q)), quat_to_matrix(q), atol=1e-7)


def test_matrix_and_quaternion_round_trip_including_half_turns():
    quats = list(_random_quats(300)) + [
        np.array(v, float) for v in ([1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1])
    ]
    for q in quats:
        q = q if q[3] >= 0 else -q
        back = matrix_to_quat(quat_to_matrix(q))
        assert back[3] >= 0
        # q and -q are the same rotation; with w ≥ 0 they match except exactly at w = 0.
        assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-12


def test_quaternion_product_composes_rotations():
    a, b = _random_quats(2)
    np.testing.assert_allclose(quat_to_matrix(quat_multiply(a, b)), quat_to_matrix(a) @ quat_to_matrix(b), atol=1e-12)


def test_bad_shapes_and_zero_quaternion_are_rejected():
    with pytest.raises(FrameError, match="last dimension of 3"):
        ros_to_unity_point([1.0, 2.0])
    with pytest.raises(FrameError, match="last dimension of 4"):
        ros_to_unity_quat([1.0, 2.0, 3.0])
    with pytest.raises(FrameError, match="zero quaternion"):
        quat_to_matrix([0, 0, 0, 0])
    with pytest.raises(FrameError, match="3x3"):
        matrix_to_quat(np.eye(4))


def test_rotation_vector_exp_round_trip():
    rng = np.random.default_rng(3)
    for _ in range(50):
        v = rng.normal(size=3)
        v *= rng.uniform(0, math.pi - 1e-3) / np.linalg.norm(v)
        np.testing.assert_allclose(rotation_vector(rotation_exp(v)), v, atol=1e-9)
    np.testing.assert_allclose(
        np.abs(rotation_vector(rotation_exp(np.array([0, 0, math.pi])))), [0, 0, math.pi], atol=1e-9
    )
