"""The hand as the floor check sees it during a motion (the move to a path's start, the approach): the scene's hand
moved by the tracked hand's displacement. Pure.

The distance floor is checked on the achieved joint states against the hand. A participant's hand is not bolted
to its rest: reaching out towards the robot brings it closer than any plan. Where a tracker follows the hands (the
protocol's pose topics), the hand under the robot is taken as sim.study.motion does (of the two, the one nearest
the scene's hand, within HAND_RADIUS, when it is first seen in the motion), and the scene's hand box is moved by
that hand's displacement since then: relative, so that a tracker worn a few centimetres off the hand's centre moves
the box by what the hand moved, not by where the tracker sits. While it is not seen (a tracking gap), the box keeps
its last place; without a tracker, it is the scene's. (The speed and separation monitor, sim.study.safety.separation,
lets the hand's possible places grow during a gap: HandWatch gives it the tracked places as they come.)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from sim.study.motion.measures import HAND_RADIUS, HANDS, Track, nearest_hand

__all__ = ["LiveHand", "HandWatch", "tracks_hands"]


class LiveHand:
    """One approach's hand under the robot, from the latest tracked place of each body."""

    def __init__(self, hand_point: np.ndarray, radius: float = HAND_RADIUS) -> None:
        self.hand_point = np.asarray(hand_point, dtype=float)
        self.radius = radius
        self.body = ""  # the hand taken (one of HANDS), "" until one is near the scene's hand
        self._origin = np.zeros(3)
        self._shift = np.zeros(3)

    def shift(self, latest: Mapping[str, np.ndarray]) -> np.ndarray:
        """(3,) m, world: how far the hand under the robot has moved since it was first seen; `latest` holds each
        tracked body's latest place (bodies not seen are left out)."""
        if not self.body:
            self.body = nearest_hand(latest, self.hand_point, self.radius)
            if not self.body:
                return self._shift.copy()
            self._origin = np.asarray(latest[self.body], dtype=float).copy()
        if self.body in latest:
            self._shift = np.asarray(latest[self.body], dtype=float) - self._origin
        return self._shift.copy()


class HandWatch:
    """The hand under the robot during one motion of a trial (the move to the path's start, or the approach), for a
    link's supervision: the robot's distance to the hand's live place, and the tracked places of the hand under the
    robot as they come. `tracks` gives each tracked body's poses of the trial so far; `distance(positions, shift)` the
    scene world's distance to the hand moved by `shift`; `tracked()`: a tracker follows the hands in this trial (else
    the hand is the scene's, at rest, and unmonitored), asked when `tracked` is read: a trial's first poses come after
    it began, so a link reads it once its motion starts."""

    def __init__(
        self,
        hand_point: np.ndarray,
        tracks: Callable[[], Mapping[str, Track]],
        distance: Callable[[np.ndarray, np.ndarray], float],
        tracked: Callable[[], bool],
    ) -> None:
        self.live = LiveHand(hand_point)
        self._tracks, self._distance, self._tracked = tracks, distance, tracked

    @property
    def tracked(self) -> bool:
        return self._tracked()

    def hand_distance(self, positions: np.ndarray) -> float:
        """m: the robot at joint `positions` to the scene's hand, where the plans put it."""
        return self._distance(positions, np.zeros(3))

    def live_hand_distance(self, positions: np.ndarray) -> float:
        """m: the robot at joint `positions` to the hand where it is now (its last tracked place)."""
        places = {body: track.positions[-1] for body, track in self._tracks().items() if len(track.stamps)}
        return self._distance(positions, self.live.shift(places))

    def places_after(self, stamp: float) -> list[tuple[float, np.ndarray]]:
        """The hand under the robot's tracked places stamped after `stamp` (none until it has been taken)."""
        if not self.tracked or not self.live.body:
            return []
        track = self._tracks().get(self.live.body)
        if track is None:
            return []
        later = track.stamps > stamp
        return list(zip(track.stamps[later].tolist(), track.positions[later]))


def tracks_hands(bodies: list[str]) -> bool:
    """A tracker follows the hands: one of HANDS is among the bodies sending."""
    return any(body in HANDS for body in bodies)
