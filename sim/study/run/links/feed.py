"""The arm's joint states as a trajectory-controller link reads them, at whatever rate the driver publishes them.
No ROS: rospy's subscriber calls `callback` on its own thread.

A state that cannot be read (names that do not cover the robot's joints, positions that do not match the names, a
position or velocity that is not finite) is not a state: it is kept as a fault, with when it came, and never
replaces the latest good one. The supervision of a motion stops the arm on a fault that comes during it; at rest,
the next motion begins only on a fresh, good state. A fault is never kept "for good": a driver that recovers is
read again.

Arrivals are on the link's clock (sim.study.run.links.clock): monotonic, so a step of the system's wall clock
neither hides a stale feed nor raises one.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.robots import RobotSpec
from sim.wire.contract import MessageError, positions_by_name

__all__ = ["FedState", "FeedFault", "JointFeed", "KEPT_STATES"]

KEPT_STATES = 10000  # a 500 Hz driver's 20 s, more than a motion takes between looks
OFFSET_HORIZON = 10.0  # s: the longest window least_offset may be asked about


@dataclass(frozen=True)
class FedState:
    stamp: float  # s, the driver's header stamp (the robot PC's clock)
    arrival: float  # s, the link's clock when it came
    positions: np.ndarray
    velocities: np.ndarray  # NaN where the driver gives none


@dataclass(frozen=True)
class FeedFault:
    arrival: float  # s, the link's clock
    reason: str


def read_state(message: Any, robot: RobotSpec, arrival: float) -> FedState:
    """A JointState message as the robot's state; MessageError naming what is wrong with it."""
    positions = positions_by_name(message.name, message.position, robot.joint_names)
    velocities = (
        positions_by_name(message.name, message.velocity, robot.joint_names)
        if len(message.velocity)
        else np.full(robot.dof, math.nan)
    )
    bad = [name for name, p in zip(robot.joint_names, positions) if not math.isfinite(p)]
    if bad:
        raise MessageError(f"JointState with a non-finite position of {', '.join(bad)}")
    if len(message.velocity) and not np.all(np.isfinite(velocities)):
        raise MessageError("JointState with a non-finite velocity")
    stamp = message.header.stamp.to_sec()
    if not math.isfinite(stamp) or stamp <= 0:
        raise MessageError(f"JointState stamped {stamp!r}: a driver stamps each state with its time")
    return FedState(stamp, arrival, positions, velocities)


class JointFeed:
    """The arm's good joint states and its faults as they come, in the robot's joint order; thread-safe."""

    def __init__(self, robot: RobotSpec, clock: Callable[[], float]) -> None:
        self.robot = robot
        self._clock = clock
        self._states: list[FedState] = []
        # (arrival, offset) of the states that may still be a window's least offset: each one's offset under every
        # later one's, so the first within a window is its least (a sliding minimum: the link looks at every state)
        self._least: deque[tuple[float, float]] = deque()
        self._faults: list[FeedFault] = []
        self._changed = threading.Condition()

    def callback(self, message: Any) -> None:
        arrival = self._clock()
        try:
            state = read_state(message, self.robot, arrival)
        except MessageError as error:
            with self._changed:
                self._faults.append(FeedFault(arrival, str(error)))
                del self._faults[:-100]
                self._changed.notify_all()
            return
        with self._changed:
            self._states.append(state)
            del self._states[:-KEPT_STATES]
            offset = state.arrival - state.stamp
            while self._least and self._least[-1][1] >= offset:
                self._least.pop()
            self._least.append((state.arrival, offset))
            while self._least[0][0] < state.arrival - OFFSET_HORIZON:
                self._least.popleft()
            self._changed.notify_all()

    def count(self) -> int:
        with self._changed:
            return len(self._states)

    def latest(self) -> FedState | None:
        with self._changed:
            return self._states[-1] if self._states else None

    def since(self, arrival: float) -> list[FedState]:
        """The good states that came after `arrival` (the link's clock)."""
        with self._changed:
            return [state for state in self._states if state.arrival > arrival]

    def least_offset(self, over: float = 0.5) -> float | None:
        """s: the least arrival minus stamp of the good states that came within `over` s of the latest: the robot's
        clock behind the link's, plus the quickest delivery among them (None before any). A delivery only ever adds
        to a state's offset, so a starved machine or a slow network raises the others, not the least, as long as one
        state in `over` s came promptly; a clock that steps raises them all."""
        if not 0.0 <= over <= OFFSET_HORIZON:
            raise ValueError(f"a window of {over!r} s: least_offset looks back at most {OFFSET_HORIZON:g} s")
        with self._changed:
            if not self._states:
                return None
            since = self._states[-1].arrival - over
            return next(offset for arrival, offset in self._least if arrival >= since)  # the latest is in it

    def faults_since(self, arrival: float) -> list[FeedFault]:
        with self._changed:
            return [fault for fault in self._faults if fault.arrival > arrival]

    def wait(self, after: float, timeout: float, stop: threading.Event | None = None) -> FedState | None:
        """The latest good state once one has come after `after` (the link's clock), or once a fault has; None after
        `timeout` s or when stopped."""
        deadline = self._clock() + timeout
        with self._changed:
            while stop is None or not stop.is_set():
                if self._faults and self._faults[-1].arrival > after:
                    return self._states[-1] if self._states else None
                if self._states and self._states[-1].arrival > after:
                    return self._states[-1]
                remaining = deadline - self._clock()
                if remaining <= 0:
                    return None
                self._changed.wait(min(remaining, 0.1))
        return None
