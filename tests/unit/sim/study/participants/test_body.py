"""sim.study.participants.body: the hand rests on the scene hand and withdraws by the distance put in, toward the seat,
on a minimum-jerk profile of known peak speed; the other bodies rest where they should; the tracking's jitter is
sub-millimetre and reproducible from its stream."""

from __future__ import annotations

import numpy as np
import pytest

from sim.study.design.scene import load_scene
from sim.study.participants.body import (
    HEAD_SWAY,
    TRACKING_JITTER,
    body_layout,
    body_poses,
    min_jerk,
    withdrawal_peak_speed,
)
from sim.study.participants.errors import ParticipantError
from sim.study.participants.model import WITHDRAWAL_DURATION
from sim.study.run.protocol import BODIES

SCENE = load_scene()
LAYOUT = body_layout(SCENE)


def test_the_minimum_jerk_profile_rests_at_both_ends_and_peaks_at_1_875_times_the_mean_speed() -> None:
    assert [min_jerk(f) for f in (-1.0, 0.0, 0.5, 1.0, 2.0)] == pytest.approx([0.0, 0.0, 0.5, 1.0, 1.0])
    fractions = np.linspace(0.0, 1.0, 100_001)
    done = np.array([min_jerk(f) for f in fractions])
    speeds = np.diff(done) / np.diff(fractions)
    assert np.all(speeds >= 0.0) and speeds[0] == pytest.approx(0.0, abs=1e-3) and speeds[-1] < 1e-3
    assert speeds.max() == pytest.approx(1.875, rel=1e-6)
    assert fractions[np.argmax(speeds)] == pytest.approx(0.5, abs=1e-4)
    assert withdrawal_peak_speed(0.03) == pytest.approx(1.875 * 0.03 / WITHDRAWAL_DURATION)


def test_the_hand_rests_on_the_scene_hand_then_withdraws_by_the_distance_toward_the_seat() -> None:
    press, distance = 3.0, 0.025
    rest = body_poses(LAYOUT, press - 1.0, distance, press)["right_hand"][0]
    assert rest == pytest.approx(SCENE.hand.top)  # on the hand's top surface
    assert body_poses(LAYOUT, press, distance, press)["right_hand"][0] == pytest.approx(rest)
    times = np.arange(press - 0.5, press + 2.0, 0.001)
    hand = np.array([body_poses(LAYOUT, t, distance, press)["right_hand"][0] for t in times])
    displacement = hand - rest
    assert np.linalg.norm(displacement, axis=1).max() == pytest.approx(distance, abs=1e-12)  # the distance truth
    assert np.allclose(displacement[:, 2], 0.0)  # horizontal
    # toward the seat: away from the robot's approach to the hand
    toward_seat = (SCENE.seat - SCENE.hand.top)[:2] / np.linalg.norm((SCENE.seat - SCENE.hand.top)[:2])
    assert displacement[-1, :2] == pytest.approx(distance * toward_seat)
    done = times >= press + WITHDRAWAL_DURATION
    assert np.allclose(displacement[done], displacement[-1], atol=1e-15)
    half = body_poses(LAYOUT, press + WITHDRAWAL_DURATION / 2, distance, press)["right_hand"][0]
    assert np.linalg.norm(half - rest) == pytest.approx(distance / 2)
    speeds = np.linalg.norm(np.diff(hand, axis=0), axis=1) / 0.001
    assert speeds.max() == pytest.approx(withdrawal_peak_speed(distance), rel=1e-4)
    assert times[np.argmax(speeds)] == pytest.approx(press + WITHDRAWAL_DURATION / 2, abs=0.002)


def test_without_a_press_the_hand_stays_and_the_other_bodies_rest_where_they_should() -> None:
    for t in np.arange(0.0, 10.0, 0.37):
        poses = body_poses(LAYOUT, float(t), 0.05)  # test 1: no press time
        assert list(poses) == list(BODIES)
        assert poses["right_hand"][0] == pytest.approx(SCENE.hand.top)
        head, left = poses["head"][0], poses["left_hand"][0]
        assert np.linalg.norm(head - SCENE.seat) <= HEAD_SWAY[0] + 1e-12
        assert left[2] == pytest.approx(SCENE.hand.top[2])
        # the hand under the robot is the one nearest the scene hand, by far
        assert np.linalg.norm(left - SCENE.hand.top) > 0.2
        for _, orientation in poses.values():
            assert np.linalg.norm(orientation) == pytest.approx(1.0)
    heads = np.array([body_poses(LAYOUT, t, 0.0)["head"][0] for t in np.linspace(0.0, HEAD_SWAY[1], 200)])
    assert np.ptp(heads, axis=0).max() == pytest.approx(2 * HEAD_SWAY[0], rel=1e-3)  # it sways, slowly
    # the head looks at the hand: its x axis points from the seat to the hand
    x, y, z, w = body_poses(LAYOUT, 0.0)["head"][1]
    forward = np.array([1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)])
    look = SCENE.hand.top - SCENE.seat
    assert forward == pytest.approx(look / np.linalg.norm(look))


def test_the_tracking_jitter_is_sub_millimetre_and_reproducible_from_its_stream() -> None:
    clean = body_poses(LAYOUT, 1.2, 0.03, 1.0)
    first = body_poses(LAYOUT, 1.2, 0.03, 1.0, np.random.default_rng([5, 1, 8]))
    again = body_poses(LAYOUT, 1.2, 0.03, 1.0, np.random.default_rng([5, 1, 8]))
    for body in BODIES:
        assert np.array_equal(first[body][0], again[body][0])
        assert 0.0 < np.abs(first[body][0] - clean[body][0]).max() < min(6 * TRACKING_JITTER, 0.001)
        assert np.array_equal(first[body][1], clean[body][1])
    with pytest.raises(ParticipantError, match="withdrawal must be >= 0 m"):
        body_poses(LAYOUT, 0.0, -0.01, 0.0)
