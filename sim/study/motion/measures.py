"""Per approach, what the participant's tracked body did (pure logic: tracks in, numbers out).

  the hand under the robot  of the two hands, the one nearest the scene's hand when the approach starts (at its first
                            tracked place in the approach if it was not tracked then), within HAND_RADIUS; none
                            beyond it (a tracker that is not where the scene says the hand is measures no withdrawal)
  withdrawal distance       how far that hand got away from the robot (m), from where it was at the approach's start,
                            over the withdrawal's window: of each displacement, only what is not towards the robot
                            counts (its component towards the end effector's point, at the press or, without one, at
                            rest, is taken out; a move across that direction counts whole, as a hand slid out from
                            under a robot coming from above does): an implicit comfort measure beside the press
  withdrawal peak speed     that hand's highest speed away from the robot in that window (m/s, the velocity's part
                            not towards the end effector), each speed taken over SPEED_SPAN so that a tracker's jitter
                            between frames does not pass for motion
  withdrawal's window       from the approach's start until the hand is at rest again after it moved: the first time,
                            from the robot's rest on, at which the hand has stayed within REST_SPEED x REST_DURATION
                            for REST_DURATION, having moved farther than that from its place at the press (at the
                            start without one); at most WITHDRAWAL_LIMIT after the robot rests. A gap in the hand's
                            tracking inside the window leaves both withdrawal measures missing (NaN), never 0: the
                            hand may have moved while it was not seen
  head distance at press    the head to the end effector at the press (m)
  untracked time            per body, the time of the approach inside gaps: stretches longer than the protocol's
                            tracking gap between consecutive poses of that body, its edges included (a body lost at
                            the approach's start is lost from the start)

An approach is its window of ROS time, from the motion's start to its end (at rest); a body that sent no pose around
it has no measures (NaN), which is not the same as a body lost for the whole window (its untracked time is the
window's length). The untracked time is the approach's (start to rest), the same for every body; the withdrawal's own
window may run on after it, and any gap there makes the withdrawal missing.
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
    "REST_SPEED",
    "REST_DURATION",
    "WITHDRAWAL_LIMIT",
    "Track",
    "Window",
    "MotionMeasures",
    "UNMEASURED",
    "untracked_time",
    "position_at",
    "hand_under_robot",
    "nearest_hand",
    "withdrawal_end",
    "withdrawal",
    "motion_measures",
]

HANDS = ("left_hand", "right_hand")
HAND_RADIUS = 0.25  # m: about a forearm's width around the scene's hand, well inside a seated person's reach
# s: a tracker's jitter of 0.3 mm reads as up to some 0.1 m/s between consecutive frames at 90 Hz, and as some
# 0.03 m/s over 50 ms; a withdrawal's peak (0.2 m/s and more) reads 1-2 % low over 50 ms
SPEED_SPAN = 0.05
# The hand at rest: over REST_DURATION it stays within REST_SPEED x REST_DURATION (5 mm) of where it is, some ten
# times a tracker's jitter at rest (0.3 mm), and less than a tenth of a withdrawal's usual few centimetres
REST_SPEED = 0.01  # m/s
REST_DURATION = 0.5  # s
# s after the robot rests: the longest the withdrawal is followed (a late, slow pull back of a second or more, after
# a reaction time, fits); the runner holds the robot at rest until the hand rests again, or this long
WITHDRAWAL_LIMIT = 3.0


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

    @property
    def limit(self) -> float:
        """The latest the withdrawal's window may end: WITHDRAWAL_LIMIT after the robot rests."""
        return self.end + WITHDRAWAL_LIMIT


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
    places = {}
    for name in HANDS:
        track = tracks.get(name)
        place = _first_place(track, window, gap) if track is not None and len(track) else None
        if place is not None:
            places[name] = place
    return nearest_hand(places, hand_point)


def nearest_hand(places: Mapping[str, np.ndarray], hand_point: np.ndarray, radius: float = HAND_RADIUS) -> str:
    """Of the hands (HANDS) in `places` (world), the one nearest `hand_point` within `radius`; "" when none is."""
    found = [
        (float(np.linalg.norm(np.asarray(places[name], dtype=float) - hand_point)), name)
        for name in HANDS
        if name in places
    ]
    found = [(distance, name) for distance, name in found if distance <= radius]
    return min(found)[1] if found else ""


def withdrawal_end(track: Track, window: Window, gap: float) -> float | None:
    """When the withdrawal's window ends: the first pose's stamp, from the robot's rest (window.end) up to
    window.limit, at which the hand has been at rest for REST_DURATION (its poses since then, without a gap between,
    all within REST_SPEED x REST_DURATION of it) after it moved farther than that from its place at the press (at the
    window's start without one); window.limit when the track reaches it without such a rest; None while the track
    reaches neither (the runner holds the robot on)."""
    radius = REST_SPEED * REST_DURATION
    since = window.press if math.isfinite(window.press) else window.start
    stamps, positions = track.stamps, track.positions
    origin = position_at(track, since, gap)
    after = np.flatnonzero(stamps >= since)
    if origin is None and after.size:
        origin = positions[after[0]]
    if origin is not None:
        # for each pose, whether the hand had moved away from its origin at or before it
        far = (stamps >= since) & (np.linalg.norm(positions - origin, axis=1) > radius)
        moved = np.maximum.accumulate(far)
        for j in np.flatnonzero((stamps >= window.end) & (stamps <= window.limit)):
            first = int(np.searchsorted(stamps, stamps[j] - REST_DURATION, side="right")) - 1  # at or before
            if first < 0 or not moved[j]:
                continue
            span = slice(first, j + 1)
            if np.any(np.diff(stamps[span]) > gap):
                continue
            if np.max(np.linalg.norm(positions[span] - positions[j], axis=1)) <= radius:
                return float(stamps[j])
    return window.limit if stamps.size and stamps[-1] >= window.limit else None


def _not_towards(vectors: np.ndarray, away: np.ndarray | None) -> np.ndarray:
    """Each vector less its component towards the robot (along -away), when it has one: what of it is not towards
    the robot."""
    if away is None:
        return vectors
    along = vectors @ away
    return vectors - np.minimum(along, 0.0)[:, None] * away


def withdrawal(track: Track, window: Window, gap: float, robot_point: np.ndarray | None = None) -> tuple[float, float]:
    """(how far the body got away from the robot, from where it was at the window's start (m); its peak speed away
    from it (m/s)) over the withdrawal's window (withdrawal_end; to window.limit when the track stops short of its
    end). `robot_point`: the end effector's point (world) at the press, or at rest without one; the part of a move
    towards it is not counted (None: every move counts). Both NaN when they cannot be told: no place at the start, a
    gap in the tracking inside the window, no pose inside it at all (the hand may have moved unseen: missing, never
    0); the speed also without two poses SPEED_SPAN apart."""
    reference = position_at(track, window.start, gap)
    end = withdrawal_end(track, window, gap)
    end = window.limit if end is None else end
    if reference is None or untracked_time(track, Window(window.start, end), gap) > 0.0:
        return math.nan, math.nan
    away = None
    if robot_point is not None:
        out = reference - np.asarray(robot_point, dtype=float)
        norm = float(np.linalg.norm(out))
        away = out / norm if norm > 1e-9 else None
    inside = (track.stamps >= window.start) & (track.stamps <= end)
    stamps, positions = track.stamps[inside], track.positions[inside]
    if stamps.size == 0:
        # no pose inside the window: the hand was never seen in it, however close the poses around it, so its
        # withdrawal is missing, never 0
        return math.nan, math.nan
    speed = _peak_speed(stamps, positions, gap, away)
    moved = _not_towards(positions - reference, away)
    return float(np.max(np.linalg.norm(moved, axis=1))), speed


def _peak_speed(stamps: np.ndarray, positions: np.ndarray, gap: float, away: np.ndarray | None) -> float:
    """The highest speed (not towards the robot) from each pose to the first one at least SPEED_SPAN after it, over
    stretches without gaps."""
    later = np.searchsorted(stamps, stamps + SPEED_SPAN)  # for each pose, the first at least SPEED_SPAN after it
    gaps_before = np.concatenate([[0], np.cumsum(np.diff(stamps) > gap)])  # gaps before each pose
    usable = np.flatnonzero(later < len(stamps))
    usable = usable[gaps_before[later[usable]] == gaps_before[usable]]
    if usable.size == 0:
        return math.nan
    ends = later[usable]
    velocities = (positions[ends] - positions[usable]) / (stamps[ends] - stamps[usable])[:, None]
    return float(np.max(np.linalg.norm(_not_towards(velocities, away), axis=1)))


def motion_measures(
    tracks: Mapping[str, Track],
    window: Window,
    hand_point: np.ndarray,
    end_effector_at_press: np.ndarray | None,
    gap: float,
    end_effector_at_rest: np.ndarray | None = None,
) -> MotionMeasures:
    """The approach's measures from the bodies' tracks (by name: head and HANDS; a body absent or empty sent
    nothing); `hand_point` is the scene's hand, `end_effector_at_press` the end effector's point at the press
    (None without a press), `end_effector_at_rest` at the robot's rest, all in the world. The withdrawal is taken
    away from the end effector at the press, or at rest without one (and in any direction without either)."""
    head = tracks.get("head", Track(np.zeros(0), np.zeros((0, 3))))
    hand = hand_under_robot(tracks, window, np.asarray(hand_point, dtype=float), gap)
    distance = speed = hand_untracked = math.nan
    if hand:
        robot_point = end_effector_at_press if end_effector_at_press is not None else end_effector_at_rest
        distance, speed = withdrawal(tracks[hand], window, gap, robot_point)
        hand_untracked = untracked_time(tracks[hand], window, gap)
    head_at_press = math.nan
    if end_effector_at_press is not None and math.isfinite(window.press):
        place = position_at(head, window.press, gap)
        if place is not None:
            head_at_press = float(np.linalg.norm(place - np.asarray(end_effector_at_press, dtype=float)))
    return MotionMeasures(hand, distance, speed, head_at_press, hand_untracked, untracked_time(head, window, gap))
