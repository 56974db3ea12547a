"""A 1-D approach for the separation monitor's tests: the robot's nearest point comes straight down towards a hand on
the table along a minimum-jerk plan, the hand rises towards it, a tracker samples the hand at 60 Hz and delivers each
sample a latency later; when the monitor says brake, the arm runs its plan for the lead, then brakes as braking.py
does (its phases from the plan's state then), and rests."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.study.safety.braking import braking_phases
from sim.study.safety.separation import PlannedTravel, SeparationMonitor, SeparationParameters

UP = np.array([0.0, 0.0, 1.0])  # from the hand towards the robot
FRAME = 1.0 / 60.0  # s between tracked samples
LATENCY = 0.02  # s from a sample's capture to the monitor
STEP = 0.002  # s between joint states


@dataclass(frozen=True)
class Outcome:
    braked_at: float  # s, inf when the monitor never braked
    separation_at_brake: float  # m, achieved (to the hand's true place) when the monitor braked
    stopping_travel: float  # m the arm travelled from the brake's decision to its rest
    least_moving: float  # m, the least achieved separation while the arm moved
    rest: float  # s, when the arm came to rest


def minimum_jerk_plan(start: float, end: float, peak: float, dt: float = 0.02) -> PlannedTravel:
    """The robot from `start` m to `end` m from the hand, peaking at `peak` m/s."""
    length = start - end
    duration = math.ceil(1.875 * length / peak / dt) * dt
    times = np.arange(round(duration / dt) + 1) * dt
    tau = times / duration
    arc = length * (10 * tau**3 - 15 * tau**4 + 6 * tau**5)
    speeds = length * (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / duration
    return PlannedTravel(times, start - arc, arc, speeds)


def simulate(
    plan: PlannedTravel,
    hand_speed: float,
    rise_at: float,
    tracked: bool,
    lead: float,
    parameters: SeparationParameters | None = None,
) -> Outcome:
    """The approach with the hand rising at `hand_speed` m/s from `rise_at` s on (and for ever)."""
    monitor = SeparationMonitor(parameters or SeparationParameters(), tracked, plan)
    start = float(plan.distances[0])

    def height(t: float) -> float:
        return hand_speed * max(t - rise_at, 0.0)

    def planned_arc(t: float) -> float:
        return float(np.interp(t, plan.times, plan.arc))

    captured, seen, t = 0, 0.0, 0.0
    braked_at = math.inf
    end = float(plan.times[-1])
    while t <= end:
        while captured * FRAME + LATENCY <= t + 1e-12:
            stamp = captured * FRAME
            monitor.hand_seen(stamp, UP * height(stamp))
            seen, captured = stamp, captured + 1
        separation = start - planned_arc(t) - height(seen)  # to the hand's last tracked place, as the live link sees
        if monitor.check(t, separation, lead, plan_time=t, direction=UP).brake:
            braked_at = t
            break
        t += STEP
    times = np.arange(0.0, end + 2.0, STEP)
    arc = np.array([planned_arc(t) for t in times])
    rest = end
    if math.isfinite(braked_at):
        begins = braked_at + lead
        if begins < end:
            s = planned_arc(begins)
            v = float(np.interp(begins, plan.times, plan.speeds))
            a = float(np.interp(begins, plan.times, plan.accelerations))
            after = times >= begins
            span, phases_end = times[after] - begins, 0.0
            arc_after = np.full(span.shape, s)
            moving = np.ones(span.shape, dtype=bool)
            for duration, jerk in braking_phases(v, a, 1.0, 20.0):
                inside = (span >= phases_end) & (span < phases_end + duration) & moving
                tau = span[inside] - phases_end
                arc_after[inside] = s + v * tau + a * tau**2 / 2 + jerk * tau**3 / 6
                moving &= ~inside
                s, v, a = (
                    s + v * duration + a * duration**2 / 2 + jerk * duration**3 / 6,
                    v + a * duration + jerk * duration**2 / 2,
                    a + jerk * duration,
                )
                phases_end += duration
            arc_after[moving] = s
            arc[after] = np.minimum(arc_after, plan.arc[-1])
            rest = begins + phases_end
    separations = start - arc - np.array([height(t) for t in times])
    moving = times <= rest
    at_brake = start - planned_arc(braked_at) - height(braked_at) if math.isfinite(braked_at) else math.nan
    travel = float(arc[-1] - planned_arc(braked_at)) if math.isfinite(braked_at) else 0.0
    return Outcome(braked_at, at_brake, travel, float(separations[moving].min()), rest)
