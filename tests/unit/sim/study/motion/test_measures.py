"""sim.study.motion.measures: an approach's withdrawal, head distance and tracking gaps, against motions whose
answers are known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.study.errors import StudyError
from sim.study.motion.measures import (
    HAND_RADIUS,
    REST_DURATION,
    REST_SPEED,
    SPEED_SPAN,
    WITHDRAWAL_LIMIT,
    Track,
    Window,
    hand_under_robot,
    motion_measures,
    position_at,
    untracked_time,
    withdrawal,
    withdrawal_end,
)

GAP = 0.1
RATE = 72.0
HAND = np.array([0.55, 0.0, 0.02])
WINDOW = Window(10.0, 14.0, press=12.0)
ROBOT = HAND + np.array([-0.2, 0.0, 0.0])  # the end effector's point at the press: on the robot's side of the hand


def stamps(start: float = 9.0, end: float = 18.0, rate: float = RATE) -> np.ndarray:
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
    distance, speed = withdrawal(track, WINDOW, GAP, ROBOT)
    assert distance == pytest.approx(0.05, abs=1e-9)
    assert 0.98 * 1.875 * 0.05 / 0.4 <= speed <= 1.875 * 0.05 / 0.4


def test_a_still_hand_with_a_trackers_jitter_has_next_to_no_withdrawal() -> None:
    times = stamps()
    jitter = np.random.default_rng(3).normal(0.0, 0.0003, (len(times), 3))
    distance, speed = withdrawal(Track(times, HAND + jitter), WINDOW, GAP, ROBOT)
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
    # the end effector is right above the hand: the move's rise is towards it, and only its part across counts
    assert measures.withdrawal_distance == pytest.approx(0.6 * 0.04, abs=1e-9)
    assert 0.98 * 1.875 * 0.024 / 0.5 <= measures.withdrawal_peak_speed <= 1.875 * 0.024 / 0.5 + 1e-9
    assert measures.head_distance_at_press == pytest.approx(float(np.linalg.norm(head - end_effector)))
    assert measures.hand_untracked == 0.0 and measures.head_untracked == 0.0
    # without a press, no head distance; without any pose, nothing
    unpressed = motion_measures(tracks, Window(10.0, 14.0), HAND, None, GAP, end_effector_at_rest=HAND - direction)
    assert math.isnan(unpressed.head_distance_at_press) and unpressed.tracked_hand == "right_hand"
    assert unpressed.withdrawal_distance == pytest.approx(0.04, abs=1e-9)  # straight away from the robot at rest
    nothing = motion_measures({}, WINDOW, HAND, end_effector, GAP)
    assert nothing.tracked_hand == "" and all(
        math.isnan(value) for value in vars(nothing).values() if isinstance(value, float)
    )


def test_a_gap_inside_the_withdrawals_window_makes_it_missing_never_zero() -> None:
    """The hand unseen for 2 s of the approach, around its move: missing, not "no withdrawal"; a gap before the
    approach, or after the hand is at rest again, does not count."""
    times = stamps()
    track = Track(times, min_jerk(times, 12.0, 0.4, 0.05, np.array([0.0, -1.0, 0.0])))
    holed = times[(times < 11.5) | (times > 13.5)]
    distance, speed = withdrawal(Track(holed, track.positions[np.isin(times, holed)]), WINDOW, GAP, ROBOT)
    assert math.isnan(distance) and math.isnan(speed)
    before = (times < 9.3) | (times > 9.8)
    distance, _ = withdrawal(Track(times[before], track.positions[before]), WINDOW, GAP, ROBOT)
    assert distance == pytest.approx(0.05, abs=1e-9)
    # a track that stops before the hand is seen at rest again: the window runs to the limit, and the end is unseen
    short = times < 12.3
    distance, speed = withdrawal(Track(times[short], track.positions[short]), WINDOW, GAP, ROBOT)
    assert math.isnan(distance) and math.isnan(speed)


def test_a_window_without_a_pose_inside_is_missing_never_zero() -> None:
    """Poses only before and after the withdrawal's window, closer than a (long) gap: nothing is counted as a gap,
    yet the hand was never seen in the window, so its withdrawal is missing, not "it did not move"."""
    long_gap = 2 * WITHDRAWAL_LIMIT + 1.0
    track = Track(np.array([9.0, 14.5]), np.array([HAND, HAND + np.array([0.0, -0.3, 0.0])]))
    window = Window(10.0, 10.5)
    assert untracked_time(track, Window(window.start, window.limit), long_gap) == 0.0
    distance, speed = withdrawal(track, window, long_gap, ROBOT)
    assert math.isnan(distance) and math.isnan(speed)


def test_speed_needs_two_poses_a_span_apart() -> None:
    times = WINDOW.start + np.arange(0, 8.0, 0.04)  # every pose 40 ms from the next: none SPEED_SPAN after another
    times = np.sort(np.concatenate([times, times + 0.045]))
    assert SPEED_SPAN > 0.045
    distance, speed = withdrawal(still(HAND, times), WINDOW, GAP, ROBOT)
    assert distance == 0.0 and speed == 0.0
    distance, speed = withdrawal(still(HAND, np.array([10.0, 10.02])), Window(10.0, 10.02), GAP, ROBOT)
    assert math.isnan(speed)


def test_the_window_ends_when_the_hand_is_at_rest_again_after_moving() -> None:
    """A withdrawal over by the robot's rest: the window ends at the rest (the hand has been still REST_DURATION);
    a move after that (the hand put back on the table) is no part of it."""
    times = stamps()
    direction = np.array([0.0, -1.0, 0.0])
    positions = min_jerk(times, 12.0, 0.4, 0.05, direction) + min_jerk(times, 15.0, 0.4, 0.08, direction) - HAND
    track = Track(times, positions)
    end = withdrawal_end(track, WINDOW, GAP)
    assert end == times[np.searchsorted(times, WINDOW.end)]
    assert withdrawal(track, WINDOW, GAP, ROBOT)[0] == pytest.approx(0.05, abs=1e-9)
    # still all along: no rest "again", followed to the limit; a track short of the limit has no end yet
    assert withdrawal_end(still(HAND, times), WINDOW, GAP) == WINDOW.limit == WINDOW.end + WITHDRAWAL_LIMIT
    assert withdrawal_end(still(HAND, times[times < 16.0]), WINDOW, GAP) is None


def test_a_late_slow_withdrawal_is_measured_whole() -> None:
    """A pull back that starts after the robot rests and takes 1.5 s: followed until the hand rests again (REST_SPEED
    x REST_DURATION), within 1 mm of its whole length; the old window (0.5 s after the rest) held none of it."""
    times = stamps(end=20.0)
    start, duration, distance = WINDOW.end + 0.6, 1.5, 0.06
    track = Track(times, min_jerk(times, start, duration, distance, np.array([0.0, -0.6, 0.8])))
    end = withdrawal_end(track, WINDOW, GAP)
    assert end is not None and start + duration - REST_DURATION < end <= WINDOW.limit
    measured, speed = withdrawal(track, WINDOW, GAP, ROBOT)
    assert distance - REST_SPEED * REST_DURATION / 5 <= measured <= distance
    assert 0.98 * 1.875 * distance / duration <= speed <= 1.875 * distance / duration
    assert withdrawal(track, Window(WINDOW.start, WINDOW.end - WITHDRAWAL_LIMIT + 0.5, WINDOW.press), GAP)[0] < 1e-3


@pytest.mark.parametrize(
    ("direction", "counted"),
    [
        ((1.0, 0.0, 0.0), 1.0),  # straight away from the end effector
        ((-1.0, 0.0, 0.0), 0.0),  # towards it
        ((0.0, -1.0, 0.0), 1.0),  # across: out from under it, towards the seat
        ((-0.6, -0.8, 0.0), 0.8),  # partly towards it: the rest counts
    ],
)
def test_only_what_is_not_towards_the_robot_counts(direction: tuple[float, float, float], counted: float) -> None:
    times = stamps()
    track = Track(times, min_jerk(times, 12.0, 0.4, 0.05, np.array(direction)))
    distance, speed = withdrawal(track, WINDOW, GAP, ROBOT)
    assert distance == pytest.approx(0.05 * counted, abs=1e-9)
    peak = 1.875 * 0.05 / 0.4
    assert (0.98 * peak * counted - 1e-9) <= speed <= peak * counted + 1e-9
