"""sim.study.motion.measures: an approach's withdrawal, head distance and tracking gaps, against motions whose
answers are known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.study.errors import StudyError
from sim.study.motion.measures import (
    HAND_RADIUS,
    SPEED_SPAN,
    Track,
    Window,
    hand_under_robot,
    motion_measures,
    position_at,
    untracked_time,
    withdrawal,
)

GAP = 0.1
RATE = 72.0
HAND = np.array([0.55, 0.0, 0.02])
WINDOW = Window(10.0, 14.0, press=12.0)


def stamps(start: float = 9.0, end: float = 15.0, rate: float = RATE) -> np.ndarray:
    return start + np.arange(int(round((end - start) * rate)) + 1) / rate


def still(at: np.ndarray, times: np.ndarray) -> Track:
    return Track(times, np.tile(at, (len(times), 1)))


def min_jerk(times: np.ndarray, start: float, duration: float, distance: float, direction: np.ndarray) -> np.ndarray:
    """Positions of a minimum-jerk move of `distance` along `direction` from HAND, starting at `start`."""
    s = np.clip((times - start) / duration, 0.0, 1.0)
    travelled = distance * (10 * s**3 - 15 * s**4 + 6 * s**5)
    return HAND + travelled[:, None] * direction


def test_a_track_is_sorted_by_stamp_and_keeps_a_repeated_stamp_once() -> None:
    track = Track.of([(2.0, (1, 1, 1)), (1.0, (0, 0, 0)), (2.0, (1, 1, 1)), (1.5, (0.5, 0.5, 0.5))])
    assert track.stamps.tolist() == [1.0, 1.5, 2.0] and track.positions[1].tolist() == [0.5, 0.5, 0.5]
    with pytest.raises(StudyError, match="finite"):
        Track.of([(1.0, (0, math.nan, 0))])


def test_a_window_must_run_forwards() -> None:
    with pytest.raises(StudyError, match="forwards"):
        Window(3.0, 2.0)


def test_a_withdrawal_gives_its_distance_and_peak_speed() -> None:
    """A minimum-jerk move of d over T peaks at 1.875 d / T; averaged over SPEED_SPAN, it reads within 2 %."""
    times = stamps()
    direction = np.array([0.0, -1.0, 0.0])
    track = Track(times, min_jerk(times, 12.0, 0.4, 0.05, direction))
    distance, speed = withdrawal(track, WINDOW, GAP)
    assert distance == pytest.approx(0.05, abs=1e-9)
    assert 0.98 * 1.875 * 0.05 / 0.4 <= speed <= 1.875 * 0.05 / 0.4


def test_a_still_hand_with_a_trackers_jitter_has_next_to_no_withdrawal() -> None:
    times = stamps()
    jitter = np.random.default_rng(3).normal(0.0, 0.0003, (len(times), 3))
    distance, speed = withdrawal(Track(times, HAND + jitter), WINDOW, GAP)
    assert distance < 0.003 and speed < 0.04


def test_the_hand_under_the_robot_is_the_one_at_the_scenes_hand() -> None:
    times = stamps()
    tracks = {"left_hand": still(np.array([0.3, -0.4, 0.05]), times), "right_hand": still(HAND + 0.01, times)}
    assert hand_under_robot(tracks, WINDOW, HAND, GAP) == "right_hand"
    far = {"left_hand": still(HAND + np.array([0.0, -HAND_RADIUS - 0.01, 0.0]), times)}
    assert hand_under_robot(far, WINDOW, HAND, GAP) == ""
    # lost at the start, it is taken where it was first tracked in the approach
    late = {"left_hand": still(HAND, stamps(10.5, 15.0))}
    assert hand_under_robot(late, WINDOW, HAND, GAP) == "left_hand"


def test_untracked_time_counts_the_gaps_longer_than_the_limit_inside_the_window() -> None:
    times = stamps()
    assert untracked_time(still(HAND, times), WINDOW, GAP) == 0.0
    # a 0.5 s hole, and a 0.08 s one (under the limit)
    holes = times[((times < 11.0) | (times > 11.5)) & ((times < 13.0) | (times > 13.08))]
    lost = untracked_time(still(HAND, holes), WINDOW, GAP)
    assert lost == pytest.approx(0.5 + 2 / RATE, abs=1e-9)  # from the pose before the hole to the one after
    # tracking that starts late is lost from the window's start; one that ends early, to its end
    middle = still(HAND, stamps(10.6, 13.0))
    lost = untracked_time(middle, WINDOW, GAP)
    assert lost == pytest.approx(0.6 + (WINDOW.end - middle.stamps[-1]), abs=1e-9)
    # a body tracked only before the approach is lost for all of it; a body that sent nothing has no figure
    assert untracked_time(still(HAND, stamps(5.0, 9.0)), WINDOW, GAP) == pytest.approx(4.0)
    assert math.isnan(untracked_time(Track.of([]), WINDOW, GAP))


def test_a_position_is_interpolated_between_poses_and_not_across_a_gap() -> None:
    track = Track(np.array([1.0, 1.05, 2.0]), np.array([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0]]))
    assert position_at(track, 1.02, GAP).tolist() == pytest.approx([0.4, 0, 0])
    assert position_at(track, 1.05, GAP).tolist() == [1.0, 0, 0]
    assert position_at(track, 1.09, GAP).tolist() == [1.0, 0, 0]  # nearest, within half the limit
    assert position_at(track, 1.5, GAP) is None  # inside the gap
    assert position_at(track, 0.5, GAP) is None


def test_the_measures_of_an_approach_together() -> None:
    times = stamps()
    direction = np.array([0.0, -0.6, 0.8])
    head = np.array([0.55, -0.65, 0.45])
    tracks = {
        "head": still(head, times),
        "right_hand": Track(times, min_jerk(times, 12.0, 0.5, 0.04, direction)),
        "left_hand": still(np.array([0.4, -0.5, 0.02]), times[times < 11.0]),  # lost at 11 s, and far from the hand
    }
    end_effector = np.array([0.55, 0.0, 0.12])
    measures = motion_measures(tracks, WINDOW, HAND, end_effector, GAP)
    assert measures.tracked_hand == "right_hand"
    assert measures.withdrawal_distance == pytest.approx(0.04, abs=1e-9)
    assert 0.98 * 1.875 * 0.04 / 0.5 <= measures.withdrawal_peak_speed <= 1.875 * 0.04 / 0.5
    assert measures.head_distance_at_press == pytest.approx(float(np.linalg.norm(head - end_effector)))
    assert measures.hand_untracked == 0.0 and measures.head_untracked == 0.0
    # without a press, no head distance; without any pose, nothing
    unpressed = motion_measures(tracks, Window(10.0, 14.0), HAND, None, GAP)
    assert math.isnan(unpressed.head_distance_at_press) and unpressed.tracked_hand == "right_hand"
    nothing = motion_measures({}, WINDOW, HAND, end_effector, GAP)
    assert nothing.tracked_hand == "" and all(
        math.isnan(value) for value in vars(nothing).values() if isinstance(value, float)
    )


def test_speed_needs_two_poses_a_span_apart_without_a_gap() -> None:
    times = np.array([10.0, 10.02, 10.2, 10.22])  # no two within one stretch are SPEED_SPAN apart
    assert SPEED_SPAN > 0.02
    distance, speed = withdrawal(still(HAND, times), WINDOW, GAP)
    assert distance == 0.0 and math.isnan(speed)
