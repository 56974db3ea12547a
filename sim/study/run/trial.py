"""One study trial as it runs, without I/O: what to command at each step, what a press changes, and what the trial
measured. The runner node feeds it the clock, the presses and the achieved joint states, and streams its targets.

  before the press   the planned approach, sample by sample
  a press at t_p     the stop (sim.study.run.stop): braking along the path, then holding at rest
  measured           the press time; the robot's distance to the hand at the press and at rest, both of the
                     achieved joint states (the state at the press, linear in time between the two recorded around
                     it, and the last one) by the scene's definition of the distance (the world's, given); and the
                     thesis's estimate, the distance the plan has at the press time (its extrapolation from time)

Every time here is from the motion's start: the instant the arm began to move as the link reports it (the stream's
first step, a trajectory controller's goal stamp), so that the press and the joint states share one timeline.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from sim.robots import RobotSpec
from sim.study.design.feasibility import PlannedApproach
from sim.study.run.errors import RunError
from sim.study.run.links.hand import HandWatch
from sim.study.run.stop import STOP_DECELERATION, StoppedMotion, stop_motion

__all__ = ["TrialMeasures", "TrialRun", "state_at"]


@dataclass(frozen=True)
class TrialMeasures:
    pressed: bool
    press_time: float  # s from the motion's start; NaN without a press
    distance_at_press: float  # m, of the achieved state at the press; NaN without a press
    distance_at_rest: float  # m, of the last achieved state
    distance_extrapolated: float  # m, the plan's distance at the press time (the thesis's method); NaN without
    braking_distance: float  # m along the path, planned; 0 without a press


class TrialRun:
    def __init__(
        self,
        robot: RobotSpec,
        planned: PlannedApproach,
        hand_distance: Callable[[np.ndarray], float],
        deceleration: float = STOP_DECELERATION,
        hand: HandWatch | None = None,
    ) -> None:
        if not planned.feasible:
            raise RunError(
                f"the {planned.path.name} path to {planned.path.standoff} m is not feasible: "
                f"{'; '.join(planned.problems)}"
            )
        self.robot, self.planned, self.deceleration = robot, planned, deceleration
        self.stopped: StoppedMotion | None = None
        self._hand_distance = hand_distance
        self.hand = hand  # the tracked hand, for the link's supervision (None: the scene's hand, unmonitored)
        self._states: list[tuple[float, np.ndarray]] = []

    @property
    def dt(self) -> float:
        return self.planned.path.dt

    @property
    def steps(self) -> int:
        """Samples the motion has, the first being its start (at rest)."""
        return len(self.stopped.times) if self.stopped is not None else len(self.planned.path.times)

    def target(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(positions, velocities) for sample k (at t = k·dt); past the end, the last sample at rest."""
        if k < 0:
            raise RunError(f"sample {k} is before the motion's start")
        if self.stopped is not None:
            joints = self.stopped.joint_positions
            k = min(k, len(joints) - 1)
            velocity = (joints[k] - joints[k - 1]) / self.dt if 0 < k < len(joints) - 1 else np.zeros(self.robot.dof)
            return joints[k].copy(), velocity
        k = min(k, len(self.planned.positions) - 1)
        return self.planned.positions[k].copy(), self.planned.velocities[k].copy()

    def press(self, time_s: float) -> None:
        """The participant pressed at `time_s` (s from the motion's start). Only the first press counts."""
        if self.stopped is None:
            self.stopped = stop_motion(self.planned.path, self.planned.positions, time_s, self.deceleration)

    def record_state(self, time_s: float, positions: np.ndarray) -> None:
        """An achieved joint state, `time_s` from the motion's start."""
        positions = np.asarray(positions, dtype=float)
        if positions.shape != (self.robot.dof,) or not np.all(np.isfinite(positions)):
            raise RunError(f"a joint state needs {self.robot.dof} finite positions, got {positions.tolist()}")
        self._states.append((float(time_s), positions))

    def hand_distance(self, positions: np.ndarray) -> float:
        """The robot's distance to the hand at joint positions `positions`."""
        return self._hand_distance(positions)

    def live_hand_distance(self, positions: np.ndarray) -> float:
        """The robot's distance to the hand where it is now (a tracked hand's live place; the scene's without one), at
        joint positions `positions`: what the distance floor is checked against during the motion. The measures keep
        the scene's hand."""
        return self._hand_distance(positions) if self.hand is None else self.hand.live_hand_distance(positions)

    def positions_at(self, time_s: float) -> np.ndarray:
        """The achieved joint positions at `time_s` (s from the motion's start), interpolated (`state_at`)."""
        if not self._states:
            raise RunError("no joint state was recorded in this trial")
        return state_at(self._states, time_s)

    def measures(self) -> TrialMeasures:
        if not self._states:
            raise RunError("no joint state was recorded in this trial")
        rest = self.hand_distance(self._states[-1][1])
        if self.stopped is None:
            return TrialMeasures(False, math.nan, math.nan, rest, math.nan, 0.0)
        press = self.stopped.press_time
        planned_distance = float(np.interp(press, self.planned.path.times, self.planned.distances))
        return TrialMeasures(
            True,
            press,
            self.hand_distance(self.positions_at(press)),
            rest,
            planned_distance,
            self.stopped.braking_distance,
        )


def state_at(states: Sequence[tuple[float, np.ndarray]], time_s: float) -> np.ndarray:
    """The joint positions at `time_s` from (time, positions) samples: linear in time, per joint, between the last
    sample at or before it and the first after it; before the first sample or after the last, that sample. A joint
    state feed samples the arm at its own rate (franka's at 30 Hz, 6.7 mm apart at 0.2 m/s): the nearest sample would
    be up to half that off, whichever way. The line between two samples is off by at most a·h²/8 for an acceleration
    a over their interval h: 0.14 mm at 1 m/s² between 30 Hz samples."""
    if not states:
        raise RunError("no joint state to interpolate")
    ordered = sorted(states, key=lambda state: state[0])  # stable: of samples at one time, the last recorded wins
    times = [state[0] for state in ordered]
    after = bisect_right(times, time_s)  # samples [0, after) are at or before time_s
    if after == 0:
        return ordered[0][1].copy()
    if after == len(ordered):
        return ordered[-1][1].copy()
    (t0, q0), (t1, q1) = ordered[after - 1], ordered[after]
    return q0 + (time_s - t0) / (t1 - t0) * (q1 - q0)  # t0 <= time_s < t1
