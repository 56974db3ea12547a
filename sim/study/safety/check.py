"""The check before any motion: a planned approach's samples, and its braking from a press at any of them, against
the robot's limits with the declared safety margin; and the speed and separation rule the live monitor brakes by
(sim.study.safety.separation), which must let the plan reach its stand-off with the hand resting. One line per
refusal, naming the limit. Pure logic."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from sim.study.design.feasibility import PlannedApproach
from sim.study.design.paths import ApproachPath
from sim.study.safety.braking import STOP_DECELERATION, STOP_JERK, PathGeometry, PathState, arc_length, brake
from sim.study.safety.limits import DEFAULT_MARGIN, Exceedance, MotionLimits, motion_exceedances
from sim.study.safety.separation import (
    STOP_LEAD_CEILING,
    PlannedTravel,
    SeparationParameters,
    least_planned_separation,
)

__all__ = ["BRAKING_STEP", "plan_refusals", "separation_refusal", "design_refusals"]

BRAKING_STEP = 0.004  # s between the braking's samples: fine enough to see its jerk


def plan_refusals(
    what: str,
    path: ApproachPath,
    joint_positions: np.ndarray,
    limits: MotionLimits,
    margin: float = DEFAULT_MARGIN,
    deceleration: float = STOP_DECELERATION,
    jerk: float = STOP_JERK,
) -> list[str]:
    """The limits the plan's samples exceed, then those its braking exceeds from a press at any sample (each limit
    once, at its worst press); [] when the plan may run."""
    joints = np.asarray(joint_positions, dtype=float)
    lines = [e.line for e in motion_exceedances(what, path.times, joints, limits, margin, path.positions)]
    geometry = PathGeometry(path, joints)
    arc, accelerations = arc_length(path), np.gradient(path.speeds, path.dt)
    worst: dict[tuple[str, str], Exceedance] = {}
    for k in range(1, len(path.times) - 1):
        desired = geometry.joint_state(PathState(float(arc[k]), float(path.speeds[k]), float(accelerations[k])))
        stop = brake(geometry, *desired, BRAKING_STEP, deceleration, jerk)
        if stop is None:
            continue  # the plan rests sooner than braking would: its own samples are checked above
        exact = (stop.velocities, stop.accelerations, stop.jerks)
        press = f"{what}, braking from a press at t = {path.times[k]:.2f} s"
        for found in motion_exceedances(
            press, stop.times, stop.positions, limits, margin, stop.world_positions, derivatives=exact
        ):
            key = (found.subject, found.kind)
            if key not in worst or found.ratio > worst[key].ratio:
                worst[key] = found
    return lines + [found.line for found in worst.values()]


def separation_refusal(
    what: str, planned: PlannedApproach, parameters: SeparationParameters, lead: float, hand_speed: float = 0.0
) -> str:
    """Empty when the speed and separation rule (sim.study.safety.separation) lets the plan reach its stand-off with the
    hand resting at the scene's place (or closing at `hand_speed` m/s), a stop stamped `lead` s ahead; else the line
    naming the planned sample where the separation less S_p falls under the floor (the live monitor would brake
    there)."""
    travel = PlannedTravel(planned.path.times, planned.distances, arc_length(planned.path), planned.path.speeds)
    worst = least_planned_separation(travel, parameters, lead, hand_speed)
    if worst.predicted >= parameters.floor:
        return ""
    return (
        f"{what}: at t = {worst.time:.2f} s the separation {worst.separation:.4f} m less {worst.terms.describe()} "
        f"(lead {lead:g} s, hand {hand_speed:g} m/s) leaves {worst.predicted:.4f} m, under the floor "
        f"{parameters.floor:g} m: the monitor would brake before the stand-off"
    )


def design_refusals(
    limits: MotionLimits,
    approaches: Mapping[tuple[str, float, float], PlannedApproach],
    margin: float = DEFAULT_MARGIN,
    floor: float = 0.0,
    deceleration: float = STOP_DECELERATION,
    separation: SeparationParameters | None = None,
    lead: float = STOP_LEAD_CEILING,
    hand_speed: float = 0.0,
) -> list[str]:
    """Every feasible combination's refusals (plan_refusals), then, given the `separation` rule's parameters, its
    separation_refusal (a stop `lead` s ahead, the hand closing at `hand_speed`), then each whose planned points come
    closer to the hand than `floor` m (a braked rest stops short of the plan's end, so the plan's closest point bounds
    it); [] when every one may run."""
    lines = []
    for (path, standoff, speed), planned in approaches.items():
        if not planned.feasible:
            continue
        what = f"{path} to {standoff:g} m at {speed:g} m/s"
        lines += plan_refusals(what, planned.path, planned.positions, limits, margin, deceleration)
        if separation is not None:
            lines += [line for line in [separation_refusal(what, planned, separation, lead, hand_speed)] if line]
        closest = float(np.min(planned.distances))
        if closest < floor:
            lines.append(f"{what}: comes {closest:.4f} m from the hand, under the floor of {floor:g} m")
    return lines
