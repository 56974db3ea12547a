"""The hand as the floor check sees it during an approach: the scene's hand moved by the tracked hand's displacement.
Pure.

The distance floor is checked on the achieved joint states against the hand. A participant's hand is not bolted
to its rest: reaching out towards the robot brings it closer than any plan. Where a tracker follows the hands (the
protocol's pose topics), the hand under the robot is taken as sim.study.motion does (of the two, the one nearest
the scene's hand, within HAND_RADIUS, when it is first seen in the approach), and the scene's hand box is moved by
that hand's displacement since then: relative, so that a tracker worn a few centimetres off the hand's centre moves
the box by what the hand moved, not by where the tracker sits. While it is not seen (a tracking gap), the box keeps
its last place; without a tracker, it is the scene's.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from sim.study.motion.measures import HAND_RADIUS, nearest_hand

__all__ = ["LiveHand"]


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
