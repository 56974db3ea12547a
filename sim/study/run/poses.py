"""The tracked bodies' poses as the runner receives them (the trial protocol's pose topics), kept until the approach
they belong to has been measured (sim.study.motion); thread-safe, for rospy's callback threads. No I/O.

A pose in another frame than the protocol's, or not a finite point, is refused: a tracker that is not calibrated to
the scene's world would measure distances to nothing. The runner says so once per body.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence

from sim.study.motion.measures import Track
from sim.study.run.protocol import BODIES, POSE_FRAME

__all__ = ["COVERED_WITHIN", "ReceivedPoses"]

# s: a body's poses cover a time when one is stamped this close to it or later (a lockstep's stamps are its steps',
# rounded to the nanosecond on the way)
COVERED_WITHIN = 1e-3


class ReceivedPoses:
    def __init__(self, frame: str = POSE_FRAME) -> None:
        self.frame = frame
        self._changed = threading.Condition()
        self._samples: dict[str, list[tuple[float, tuple[float, float, float]]]] = {body: [] for body in BODIES}
        self._latest = dict.fromkeys(BODIES, -math.inf)  # each body's latest stamp
        self._refused: dict[str, str] = {}  # by body: why its first refused pose was refused

    def add(self, body: str, stamp: float, frame_id: str, position: Sequence[float]) -> None:
        """A pose of `body` (one of BODIES) as it came: its stamp (s of ROS time), frame and position."""
        point = tuple(float(value) for value in position)
        if frame_id != self.frame:
            why = f"its frame is {frame_id!r}, not the scene's {self.frame!r}"
        elif len(point) != 3 or not all(math.isfinite(value) for value in (stamp, *point)):
            why = f"it is not a finite point at a finite stamp: {stamp!r}, {point!r}"
        else:
            with self._changed:
                self._samples[body].append((float(stamp), (point[0], point[1], point[2])))
                self._latest[body] = max(self._latest[body], float(stamp))
                self._changed.notify_all()
            return
        with self._changed:
            self._refused.setdefault(body, why)

    def refused(self) -> dict[str, str]:
        """By body, why its first refused pose was refused (a copy: rospy's threads add to it meanwhile)."""
        with self._changed:
            return dict(self._refused)

    def sending(self, since: float) -> list[str]:
        """The bodies with a pose stamped at or after `since`."""
        with self._changed:
            return [body for body, latest in self._latest.items() if latest >= since]

    def uncovered(self, since: float, until: float) -> list[str]:
        """The bodies sending since `since` whose latest pose is still before `until` (within COVERED_WITHIN)."""
        with self._changed:
            return self._uncovered(since, until)

    def _uncovered(self, since: float, until: float) -> list[str]:
        return [body for body, latest in self._latest.items() if since <= latest < until - COVERED_WITHIN]

    def wait_covered(self, since: float, until: float, timeout: float, stop: threading.Event) -> list[str]:
        """Wait (at most `timeout` s, or until stopped) until every body sending since `since` has a pose at or
        after `until`; the bodies still short of it."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                late = self._uncovered(since, until)
                remaining = deadline - time.monotonic()
                if not late or remaining <= 0 or stop.is_set():
                    return late
                self._changed.wait(min(remaining, 0.1))

    def tracks(self, since: float) -> dict[str, Track]:
        """Each body's poses stamped at or after `since`, as tracks (sorted by stamp)."""
        with self._changed:
            kept = {body: [s for s in samples if s[0] >= since] for body, samples in self._samples.items()}
        return {body: Track.of(samples) for body, samples in kept.items()}

    def forget(self, before: float) -> None:
        """Drop the poses stamped before `before`: a session's hours of poses are the bag's to keep, not memory's."""
        with self._changed:
            for body, samples in self._samples.items():
                self._samples[body] = [s for s in samples if s[0] >= before]
