"""Per approach, what the participant's tracked body did (pure logic: tracks in, numbers out).

  the hand under the robot  of the two hands, the one nearest the scene's hand when the approach starts (at its first
                            tracked place in the approach if it was not tracked then), within HAND_RADIUS; none
                            beyond it (a tracker that is not where the scene says the hand is measures no withdrawal)
  withdrawal distance       that hand's farthest from where it was at the approach's start, during the approach (m):
                            an implicit comfort measure beside the press, how far the hand moved away
  withdrawal peak speed     that hand's highest speed during the approach (m/s), each speed taken over SPEED_SPAN so
                            that a tracker's jitter between frames does not pass for motion
  head distance at press    the head to the end effector at the press (m)
  untracked time            per body, the time of the approach inside gaps: stretches longer than the protocol's
                            tracking gap between consecutive poses of that body, its edges included (a body lost at
                            the approach's start is lost from the start)

An approach is its window of ROS time, from the motion's start to its end (at rest); a body that sent no pose around
it has no measures (NaN), which is not the same as a body lost for the whole window (its untracked time is the
window's length).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from sim.study.motion.errors import MotionError

__all__ = [
    "HANDS",
    "HAND_RADIUS",
    "SPEED_SPAN",
    "Track",
    "Window",
    "MotionMeasures",
    "UNMEASURED",
    "untracked_time",
    "position_at",
    "hand_under_robot",
    "withdrawal",
    "motion_measures",
]

HANDS = ("left_hand", "right_hand")
HAND_RADIUS = 0.25  # m: about a forearm's width around the scene's hand, well inside a seated person's reach
# s: a tracker's jitter of 0.3 mm reads as up to some 0.1 m/s between consecutive frames at 90 Hz, and as some
# 0.03 m/s over 50 ms; a withdrawal's peak (0.2 m/s and more) reads 1-2 % low over 50 ms
SPEED_SPAN = 0.05


@dataclass(frozen=True)
class Track:
    """One body's poses: stamps (s of ROS time, ascending, distinct) and positions (n, 3) in the world."""

    stamps: np.ndarray
    positions: np.ndarray

    @staticmethod
    def of(samples: Sequence[tuple[float, Sequence[float]]]) -> Track:
        """From (stamp, xyz) samples in any order (as they arrived): sorted by stamp, a repeated stamp kept once."""
        stamps = np.array([stamp for stamp, _ in samples], dtype=float).reshape(-1)
        positions = np.array([position for _, position in samples], dtype=float).reshape(-1, 3)
        if not (np.all(np.isfinite(stamps)) and np.all(np.isfinite(positions))):
            raise MotionError("a pose's stamp and position must be finite")
        stamps, first = np.unique(stamps, return_index=True)  # sorted
        return Track(stamps, positions[first])

    def __len__(self) -> int:
        return len(self.stamps)


@dataclass(frozen=True)
class Window:
    """An approach in ROS time (s): from the motion's start to its end; the press's time, NaN without one."""

    start: float
    end: float
    press: float = math.nan

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start) and math.isfinite(self.end) and self.start <= self.end):
            raise MotionError(f"an approach's window must run forwards, got {self.start!r} to {self.end!r}")


@dataclass(frozen=True)
class MotionMeasures:
    tracked_hand: str  # one of HANDS, or "" when no hand was under the robot
    withdrawal_distance: float  # m
    withdrawal_peak_speed: float  # m/s
    head_distance_at_press: float  # m
    hand_untracked: float  # s
    head_untracked: float  # s


UNMEASURED = MotionMeasures("", math.nan, math.nan, math.nan, math.nan, math.nan)


def untracked_time(track: Track, window: Window, gap: float) -> float:
    """s of the window inside gaps longer than `gap` between consecutive poses; NaN for a body with no pose at all."""
    if len(track) == 0:
        return math.nan
    stamps = track.stamps
    before, after = stamps[stamps <= window.start], stamps[stamps >= window.end]
    # the window's edges are poses when none came before (or after) it: tracking that starts late is lost until then
    left = before[-1] if before.size else window.start
    right = after[0] if after.size else window.end
    inside = stamps[(stamps > window.start) & (stamps < window.end)]
    points = np.concatenate([[left], inside, [right]])
    lost = 0.0
    for a, b in zip(points[:-1], points[1:]):
        if b - a > gap:
            lost += max(0.0, min(b, window.end) - max(a, window.start))
    return float(lost)


def position_at(track: Track, time_s: float, gap: float) -> np.ndarray | None:
    """The body's position at `time_s`: between the two poses around it when they are no more than `gap` apart, else
    the nearest pose within half of `gap`; None when it was not tracked then."""
    stamps = track.stamps
    k = int(np.searchsorted(stamps, time_s))  # the first pose at or after time_s
    if k < len(stamps) and stamps[k] == time_s:
        return track.positions[k]
    if 0 < k < len(stamps) and stamps[k] - stamps[k - 1] <= gap:
        fraction = (time_s - stamps[k - 1]) / (stamps[k] - stamps[k - 1])
        return track.positions[k - 1] + fraction * (track.positions[k] - track.positions[k - 1])
    nearest = [j for j in (k - 1, k) if 0 <= j < len(stamps) and abs(stamps[j] - time_s) <= gap / 2.0]
    if not nearest:
        return None
    return track.positions[min(nearest, key=lambda j: abs(stamps[j] - time_s))]


def _first_place(track: Track, window: Window, gap: float) -> np.ndarray | None:
    """Where the body was at the window's start, or at its first pose inside the window."""
    at_start = position_at(track, window.start, gap)
    if at_start is not None:
        return at_start
    inside = np.flatnonzero((track.stamps >= window.start) & (track.stamps <= window.end))
    return track.positions[inside[0]] if inside.size else None


def hand_under_robot(tracks: Mapping[str, Track], window: Window, hand_point: np.ndarray, gap: float) -> str:
    """The hand (of HANDS) nearest `hand_point` (the scene's hand, world) as the approach starts, within
    HAND_RADIUS; "" when none is."""
    found = []
    for name in HANDS:
        track = tracks.get(name)
        place = _first_place(track, window, gap) if track is not None and len(track) else None
        if place is not None:
            distance = float(np.linalg.norm(place - hand_point))
            if distance <= HAND_RADIUS:
                found.append((distance, name))
    return min(found)[1] if found else ""


def withdrawal(track: Track, window: Window, gap: float) -> tuple[float, float]:
    """(the farthest the body got from where it was at the window's start (m), its peak speed (m/s)) during the
    window; NaN where it cannot be told (no place at the start; no two poses SPEED_SPAN apart without a gap between)."""
    reference = position_at(track, window.start, gap)
    inside = (track.stamps >= window.start) & (track.stamps <= window.end)
    stamps, positions = track.stamps[inside], track.positions[inside]
    speed = _peak_speed(stamps, positions, gap)
    if reference is None or stamps.size == 0:
        return math.nan, speed
    return float(np.max(np.linalg.norm(positions - reference, axis=1))), speed


def _peak_speed(stamps: np.ndarray, positions: np.ndarray, gap: float) -> float:
    """The highest speed from each pose to the first one at least SPEED_SPAN after it, over stretches without gaps."""
    later = np.searchsorted(stamps, stamps + SPEED_SPAN)  # for each pose, the first at least SPEED_SPAN after it
    gaps_before = np.concatenate([[0], np.cumsum(np.diff(stamps) > gap)])  # gaps before each pose
    usable = np.flatnonzero(later < len(stamps))
    usable = usable[gaps_before[later[usable]] == gaps_before[usable]]
    if usable.size == 0:
        return math.nan
    ends = later[usable]
    travelled = np.linalg.norm(positions[ends] - positions[usable], axis=1)
    return float(np.max(travelled / (stamps[ends] - stamps[usable])))


def motion_measures(
    tracks: Mapping[str, Track],
    window: Window,
    hand_point: np.ndarray,
    end_effector_at_press: np.ndarray | None,
    gap: float,
) -> MotionMeasures:
    """The approach's measures from the bodies' tracks (by name: head and HANDS; a body absent or empty sent
    nothing); `hand_point` is the scene's hand, `end_effector_at_press` the end effector's point at the press
    (None without a press), both in the world."""
    head = tracks.get("head", Track(np.zeros(0), np.zeros((0, 3))))
    hand = hand_under_robot(tracks, window, np.asarray(hand_point, dtype=float), gap)
    distance = speed = hand_untracked = math.nan
    if hand:
        distance, speed = withdrawal(tracks[hand], window, gap)
        hand_untracked = untracked_time(tracks[hand], window, gap)
    head_at_press = math.nan
    if end_effector_at_press is not None and math.isfinite(window.press):
        place = position_at(head, window.press, gap)
        if place is not None:
            head_at_press = float(np.linalg.norm(place - np.asarray(end_effector_at_press, dtype=float)))
    return MotionMeasures(hand, distance, speed, head_at_press, hand_untracked, untracked_time(head, window, gap))
