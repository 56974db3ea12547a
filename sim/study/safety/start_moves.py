"""The check of the moves to each path's start, before any motion: the joint-space quintic a trajectory link sends
(sim.control.scenarios.approach, as TrajectoryLink.move_to sends it) against the robot's limits, as an approach's
samples are checked. Pure logic.

Where the moves come from: the runner goes to each trial's start from wherever the arm rests (Runner.run_trial; it
never goes home between trials). Before the first trial that is the robot's home, where the check assumes the arm
waits; after a trial it is somewhere on that trial's planned joint path: its end when it rested at the stand-off, a
point short of it when a press braked it (braking follows the path), its start when it was held before it began.
A session's order is drawn per participant, so any combination may follow any other. So every start is checked from
home and from every planned sample of every combination (each a possible rest). The quintic's peaks are known in
closed form (a rest-to-rest quintic over T peaks at 1.875·Δ/T, 5.7735·Δ/T², 60·Δ/T³), which finds each limit's worst
rest on a path without sampling every move; that move is then sampled at the plan's dt, as the link sends it, and
checked like any motion. Not covered: an arm left elsewhere than home before the session.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from sim.control.scenarios import approach
from sim.control.scenarios.defaults import APPROACH_MIN_S, APPROACH_SPEED_FRACTION
from sim.robots import RobotSpec
from sim.study.design.feasibility import PlannedApproach
from sim.study.safety.limits import DEFAULT_MARGIN, Exceedance, MotionLimits, motion_exceedances

__all__ = ["QUINTIC_PEAKS", "quintic_ratios", "start_move_refusals"]

QUINTIC_PEAKS = (1.875, 10.0 / np.sqrt(3.0), 60.0)  # peak |velocity|·T/Δ, |acceleration|·T²/Δ, |jerk|·T³/Δ


def quintic_ratios(
    robot: RobotSpec, limits: MotionLimits, here: np.ndarray, there: np.ndarray, margin: float
) -> np.ndarray:
    """For moves from each row of `here` to `there`, each joint's peak velocity, acceleration and jerk over what the
    margin allows (the closed form of sim.control.scenarios.approach's timing): (rows, 3, joints), NaN for a kind
    without a limit."""
    delta = np.abs(np.atleast_2d(here) - there)
    needed = np.max(QUINTIC_PEAKS[0] * delta / (APPROACH_SPEED_FRACTION * robot.max_velocity), axis=1)
    duration = np.maximum(APPROACH_MIN_S, needed)[:, None]
    ratios = np.full((len(delta), 3, robot.dof), np.nan)
    for order, bound in enumerate((limits.velocity, limits.acceleration, limits.jerk)):
        if bound is not None:
            ratios[:, order] = QUINTIC_PEAKS[order] * delta / duration ** (order + 1) / (margin * np.asarray(bound))
    return ratios


def _move(
    robot: RobotSpec, limits: MotionLimits, what: str, here: np.ndarray, there: np.ndarray, dt: float, margin: float
) -> list[Exceedance]:
    """The move as the link sends it, sampled, against the limits."""
    positions, _ = approach(robot, here, there, dt)
    return motion_exceedances(what, np.arange(len(positions)) * dt, positions, limits, margin)


def start_move_refusals(
    robot: RobotSpec,
    limits: MotionLimits,
    approaches: Mapping[tuple[str, float, float], PlannedApproach],
    margin: float = DEFAULT_MARGIN,
) -> list[str]:
    """The limits the moves to each feasible combination's start exceed (see the module's doc): from home, each
    limit the move exceeds; from a rest on a combination's path, each limit once per start, at its worst rest."""
    feasible = {key: planned for key, planned in approaches.items() if planned.feasible}
    lines = []
    for (path, standoff, speed), planned in feasible.items():
        start, dt = np.asarray(planned.positions[0], dtype=float), planned.path.dt
        target = f"{path} to {standoff:g} m at {speed:g} m/s"
        from_home = _move(robot, limits, f"the move from home to the start of {target}", robot.home, start, dt, margin)
        lines += [found.line for found in from_home]
        worst: dict[tuple[str, str], Exceedance] = {}
        for (other, other_standoff, other_speed), before in feasible.items():
            rests = np.asarray(before.positions, dtype=float)
            ratios = quintic_ratios(robot, limits, rests, start, margin)
            candidates = {int(k) for k in np.argmax(np.nan_to_num(ratios, nan=-1.0), axis=0).ravel()}
            for k in sorted(candidates):
                what = (
                    f"the move to the start of {target} from a rest at t = {before.path.times[k]:.2f} s of "
                    f"{other} to {other_standoff:g} m at {other_speed:g} m/s"
                )
                for found in _move(robot, limits, what, rests[k], start, dt, margin):
                    key = (found.subject, found.kind)
                    if key not in worst or found.ratio > worst[key].ratio:
                        worst[key] = found
        lines += [found.line for found in worst.values()]
    return lines
