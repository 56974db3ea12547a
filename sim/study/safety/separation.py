"""Speed and separation monitoring: brake when the robot's separation from the hand would fall under the floor within
the time it takes to stop, not once the floor is crossed. Pure logic, no I/O.

The rule is ISO/TS 15066's protective separation distance (Marvel & Norcross 2017, Robotics and Computer-Integrated
Manufacturing 44), S_p = S_h + S_r + S_s + C + Z_d + Z_r, where

  S_h  the hand's travel towards the robot while the robot reacts and brakes: its closing speed × (T_r + T_s). The
       closing speed is measured from the tracker (a least-squares slope over the last `window` s of stamped places,
       projected on the direction from the hand to the robot's nearest point; a hand moving away counts 0)
  S_r  the robot's travel towards the hand while the stop is prepared: its speed towards the hand × T_r, T_r being
       the lead a stop is stamped ahead (sim.study.run.links.lead: 10-250 ms), the constant-speed form of the rule
  S_s  the robot's braking distance along its path from its current path speed and acceleration, with the braking's
       deceleration and jerk (sim.study.safety.braking.braking_phases, the jerk's build-up included), T_s its duration.
       Along the path, not towards the hand: the tool keeps its orientation, so the separation falls by no more
  C    intrusion: how far the hand's surface may reach beyond where the scene's hand box (moved by the tracked
       displacement) puts it: the hand placed on its mark and shaped as the box to within this
  Z_d  the tracker's position uncertainty (of a displacement)
  Z_r  the robot's position uncertainty: the achieved joint states' forward kinematics, the URDF's geometry and the
       base's placement in the scene against the real arm

S_r + S_s is capped by the path left to the plan's own rest (`remaining`): a braking that would rest beyond the
plan's end is not sent, the plan rests sooner (braking.brake), so the arm never travels farther than that.

The hand's place is as old as its last sample. While tracked, the hand is taken to have gone on at its closing speed
since then; in a gap (no sample for more than `gap_after` s) it may be anywhere within `gap_speed` × the time since
it was last seen of its last place (ISO 13855's 2.0 m/s for a reach), and may be closing at that speed; a gap longer
than `gap_limit` is a reason to stop in itself. Without a tracker the hand is the scene's, at rest (or closing at a
declared `unmonitored_hand_speed`), and the verdict says it was not monitored.

The separation after a stop decided now would be at least

  predicted = separation − unseen − S_p

(`unseen` the hand's travel since its last sample); the arm brakes when that falls under the floor, unless the arm
is at rest with nothing of its plan left to run (braking cannot help; a hand moving onto a resting arm is the
participant's own move).

The live link calls the monitor on each joint state, on one monotonic clock for the hand's stamps and `now`:

    plan = PlannedTravel(path.times, planned.distances, braking.arc_length(path), path.speeds)
    monitor = SeparationMonitor(SeparationParameters(floor=spec.floor), tracked=hand_body != "", plan=plan)
    # on each tracked place of the hand under the robot (stamp on the monitor's clock), from before the motion:
    monitor.hand_seen(stamp, position)
    # on each joint state, t s into the approach (the plan's clock), the stop's lead as it would be stamped now:
    verdict = monitor.check(now, live_distance, lead, plan_time=t, direction=unit(robot_point - hand_point))
    if verdict.brake:
        stop(verdict.reason)
    # for the trial's record: monitor.least_predicted, monitor.least_achieved, monitor.monitored

Without a plan, `check` takes the robot's speed towards the hand, its path speed and acceleration and the path left
instead (ISO's constant-speed form, protective_separation).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, fields

import numpy as np

from sim.study.safety.braking import STOP_DECELERATION, STOP_JERK, braking_phases
from sim.study.safety.errors import SafetyError

__all__ = [
    "STOP_LEAD_CEILING",
    "REACH_SPEED",
    "SeparationParameters",
    "ProtectiveSeparation",
    "braking_travel",
    "protective_separation",
    "HandMotion",
    "Verdict",
    "SeparationMonitor",
    "PlannedTravel",
    "PlannedSeparation",
    "least_planned_separation",
]

STOP_LEAD_CEILING = 0.25  # s: the longest a stop is stamped ahead (sim.study.run.links.lead's CEILING is this)
REACH_SPEED = 2.0  # m/s: ISO 13855's approach speed of a hand or arm reaching (K for distances under 0.5 m)
_AT_REST = 1e-6  # m/s, m: a speed or a path left this small is none


@dataclass(frozen=True)
class SeparationParameters:
    """The rule's declared parameters, SI units. Defaults for a Panda-sized arm and a mocap tracker at 60 Hz or more."""

    floor: float = 0.01  # m: the least separation allowed while the arm moves (the runner's --floor)
    intrusion: float = 0.005  # m, C: the real hand's surface beyond the scene's box (its placement and shape)
    tracker_uncertainty: float = 0.002  # m, Z_d: a mocap's displacement error (a headset's hand tracking: ~0.01)
    robot_uncertainty: float = 0.002  # m, Z_r: FK, the URDF's geometry and the base's placement vs the real arm
    deceleration: float = STOP_DECELERATION  # m/s² along the path: the braking's (braking.py)
    jerk: float = STOP_JERK  # m/s³ along the path: the braking's build-up (braking.py)
    window: float = 0.1  # s of samples for the hand's velocity: 6 at 60 Hz, jitter of 0.3 mm reads ~4 mm/s
    gap_after: float = 0.05  # s without a sample that make a gap: three frames at 60 Hz
    gap_speed: float = REACH_SPEED  # m/s: how fast an unseen hand's possible places grow
    gap_limit: float = 0.2  # s: a gap this long stops the arm whatever the separation
    unmonitored_hand_speed: float = 0.0  # m/s: the hand's closing speed without a tracker (at rest on its mark)

    def __post_init__(self) -> None:
        for field in fields(self):
            value = getattr(self, field.name)
            positive = field.name in ("deceleration", "jerk", "window", "gap_after", "gap_speed", "gap_limit")
            bound = "> 0" if positive else ">= 0"
            usable = isinstance(value, (int, float)) and math.isfinite(value)
            if not (usable and (value > 0 if positive else value >= 0)):
                raise SafetyError(f"the separation's {field.name} must be finite and {bound}, got {value!r}")
        if self.gap_limit < self.gap_after:
            raise SafetyError(
                f"the separation's gap_limit ({self.gap_limit!r} s) must be at least its gap_after "
                f"({self.gap_after!r} s)"
            )

    @property
    def allowances(self) -> float:
        """m: C + Z_d + Z_r."""
        return self.intrusion + self.tracker_uncertainty + self.robot_uncertainty


@dataclass(frozen=True)
class ProtectiveSeparation:
    """S_p's terms (m) and the times they are taken over (s)."""

    hand: float  # S_h
    robot: float  # S_r
    braking: float  # S_s
    intrusion: float  # C
    tracker: float  # Z_d
    robot_uncertainty: float  # Z_r
    reaction: float  # T_r
    stop_time: float  # T_s

    @property
    def total(self) -> float:
        """S_p."""
        return self.hand + self.robot + self.braking + self.intrusion + self.tracker + self.robot_uncertainty

    def describe(self) -> str:
        """One line: 'S_p 0.061 m: hand 0.020, robot 0.010, braking 0.021, C+Z 0.010'."""
        allowances = self.intrusion + self.tracker + self.robot_uncertainty
        return (
            f"S_p {self.total:.3f} m: hand {self.hand:.3f}, robot {self.robot:.3f}, braking {self.braking:.3f}, "
            f"C+Z {allowances:.3f}"
        )


def braking_travel(speed: float, acceleration: float, deceleration: float, jerk: float) -> tuple[float, float]:
    """(m along the path, s): the braking's distance and duration from `speed` and `acceleration`, as braking.py
    brakes (its phases integrated exactly)."""
    v, a, distance, duration = max(speed, 0.0), acceleration, 0.0, 0.0
    for d, j in braking_phases(speed, acceleration, deceleration, jerk):
        distance += v * d + a * d**2 / 2 + j * d**3 / 6
        v, a = v + a * d + j * d**2 / 2, a + j * d
        duration += d
    return max(distance, 0.0), duration


def protective_separation(
    parameters: SeparationParameters,
    hand_speed: float,
    robot_speed: float,
    path_speed: float,
    path_acceleration: float,
    reaction: float,
    remaining: float = math.inf,
) -> ProtectiveSeparation:
    """S_p's terms (module doc) for a hand closing at `hand_speed` and a robot coming towards it at `robot_speed`
    (m/s, only closing counts), on its path at `path_speed` and `path_acceleration`, a stop starting `reaction` s from
    now (T_r), with `remaining` m of path to the plan's own rest."""
    for name, value in (("hand speed", hand_speed), ("robot speed", robot_speed), ("path speed", path_speed),
                        ("path acceleration", path_acceleration)):  # fmt: skip
        if not math.isfinite(value):
            raise SafetyError(f"the separation needs a finite {name}, got {value!r}")
    if not (math.isfinite(reaction) and reaction >= 0):
        raise SafetyError(f"the separation's reaction time must be finite and >= 0 s, got {reaction!r}")
    if not (remaining >= 0):
        raise SafetyError(f"the path left to the plan's rest must be >= 0 m, got {remaining!r}")
    braking, stop_time = braking_travel(path_speed, path_acceleration, parameters.deceleration, parameters.jerk)
    robot = max(robot_speed, 0.0) * reaction
    robot = min(robot, remaining)
    braking = min(braking, remaining - robot)
    return ProtectiveSeparation(
        hand=max(hand_speed, 0.0) * (reaction + stop_time),
        robot=robot,
        braking=braking,
        intrusion=parameters.intrusion,
        tracker=parameters.tracker_uncertainty,
        robot_uncertainty=parameters.robot_uncertainty,
        reaction=reaction,
        stop_time=stop_time,
    )


class HandMotion:
    """The tracked hand's recent places: its velocity (a least-squares slope over the last `window` s of samples),
    its closing speed towards the robot, and how far it may have gone since it was last seen."""

    def __init__(self, window: float, gap_after: float, gap_speed: float) -> None:
        self.window, self.gap_after, self.gap_speed = window, gap_after, gap_speed
        self._samples: deque[tuple[float, np.ndarray]] = deque()

    def add(self, stamp: float, position: np.ndarray) -> None:
        """A tracked place (m, world) at `stamp` (s, the monitor's clock); one not newer than the last is dropped (a
        late delivery says nothing newer)."""
        place = np.asarray(position, dtype=float).reshape(3)
        if not (math.isfinite(stamp) and np.all(np.isfinite(place))):
            raise SafetyError(f"a hand's place needs a finite stamp and position, got {stamp!r}, {place.tolist()}")
        if self._samples and stamp <= self._samples[-1][0]:
            return
        self._samples.append((float(stamp), place))
        while self._samples[0][0] < stamp - self.window:
            self._samples.popleft()

    @property
    def last_seen(self) -> float | None:
        """s: the last sample's stamp; None before any."""
        return self._samples[-1][0] if self._samples else None

    def velocity(self) -> np.ndarray | None:
        """(3,) m/s: the least-squares slope of the window's places over their stamps; None with fewer than two."""
        if len(self._samples) < 2:
            return None
        stamps = np.array([stamp for stamp, _ in self._samples])
        places = np.array([place for _, place in self._samples])
        centred = stamps - stamps.mean()
        return np.asarray(centred @ (places - places.mean(axis=0)) / float(centred @ centred))

    def in_gap(self, now: float) -> bool:
        """Whether the hand has gone unseen longer than `gap_after` (or was never seen, or its speed is unknown)."""
        last = self.last_seen
        return last is None or now - last > self.gap_after or len(self._samples) < 2

    def latest_velocity(self) -> np.ndarray | None:
        """(3,) m/s between the last two places; None with fewer than two."""
        if len(self._samples) < 2:
            return None
        (before, there), (last, here) = self._samples[-2], self._samples[-1]
        return np.asarray((here - there) / (last - before))

    def closing_speed(self, now: float, direction: np.ndarray | None = None) -> float:
        """m/s towards the robot: the velocity along `direction` (unit, from the hand to the robot's nearest point),
        0 when moving away; its whole speed without a direction; `gap_speed` in a gap (unseen, it may close at it).
        The larger of two velocities: the window's slope, steady for a hand that creeps, and the last two places',
        prompt for a hand that sets off (a reach is at speed within a frame or two, which the window's slope lags
        by about half the window: at 1.6 m/s, 8 cm)."""
        velocities = [self.velocity(), self.latest_velocity()]
        if self.in_gap(now) or velocities[0] is None:
            return self.gap_speed
        if direction is None:
            return max(float(np.linalg.norm(v)) for v in velocities if v is not None)
        towards = np.asarray(direction, dtype=float)
        return max(max(float(v @ towards) for v in velocities if v is not None), 0.0)

    def unseen(self, now: float, direction: np.ndarray | None = None) -> float:
        """m: how far the hand may have come towards the robot since its last sample: at its closing speed while
        tracked, at `gap_speed` in a gap; inf never seen."""
        last = self.last_seen
        if last is None:
            return math.inf
        return self.closing_speed(now, direction) * max(now - last, 0.0)


@dataclass(frozen=True)
class Verdict:
    brake: bool
    reason: str  # "" when the arm need not brake
    separation: float  # m, the achieved separation given
    predicted: float  # m, the least separation a stop decided now would leave (separation − unseen − S_p)
    unseen: float  # m, the hand's possible travel since its last sample
    terms: ProtectiveSeparation
    monitored: bool  # whether a tracker followed the hand (False: the scene's hand, taken at rest)


class SeparationMonitor:
    """One approach's speed and separation monitoring (module doc): a verdict on each joint state, and the least
    predicted and achieved separations for the trial's record."""

    def __init__(self, parameters: SeparationParameters, tracked: bool, plan: PlannedTravel | None = None) -> None:
        self.parameters = parameters
        self.monitored = tracked
        self.plan = plan
        self.hand = HandMotion(parameters.window, parameters.gap_after, parameters.gap_speed)
        self.least_predicted = math.inf
        self.least_achieved = math.inf
        self._since: float | None = None  # the first check's time: a tracked hand never seen is unseen since then

    def hand_seen(self, stamp: float, position: np.ndarray) -> None:
        """A tracked place of the hand under the robot (m, world), stamped on the monitor's clock."""
        self.hand.add(stamp, position)

    def check(
        self,
        now: float,
        separation: float,
        lead: float,
        plan_time: float | None = None,
        robot_speed: float = 0.0,
        path_speed: float = 0.0,
        path_acceleration: float = 0.0,
        remaining: float = math.inf,
        direction: np.ndarray | None = None,
    ) -> Verdict:
        """Whether to brake now (module doc): `separation` m achieved to the hand's live place, a stop stamped `lead` s
        ahead (T_r). The robot's part: with the monitor's plan, the plan's own travel from `plan_time` s into it
        (PlannedTravel); else ISO's constant-speed form from the robot's `robot_speed` m/s towards the hand, its
        `path_speed` and `path_acceleration`, `remaining` m of path to the plan's rest. `direction`: the unit vector
        from the hand to the robot's nearest point (None: any motion of the hand closes)."""
        if not math.isfinite(separation):
            raise SafetyError(f"the separation must be finite, got {separation!r}")
        p = self.parameters
        if self._since is None:
            self._since = now
        seen = self.hand.last_seen
        untracked = now - (self._since if seen is None else seen)
        if self.monitored:
            hand_speed = self.hand.closing_speed(now, direction)
            unseen = p.gap_speed * max(untracked, 0.0) if seen is None else self.hand.unseen(now, direction)
        else:
            hand_speed, unseen = p.unmonitored_hand_speed, 0.0
        if self.plan is not None and plan_time is not None:
            terms = self.plan.terms(p, plan_time, lead, hand_speed)
            moving = self.plan.moving(plan_time)
        else:
            terms = protective_separation(p, hand_speed, robot_speed, path_speed, path_acceleration, lead, remaining)
            moving = path_speed > _AT_REST or remaining > _AT_REST
        predicted = separation - unseen - terms.total
        self.least_predicted = min(self.least_predicted, predicted)
        self.least_achieved = min(self.least_achieved, separation)
        reason = ""
        if moving and self.monitored and untracked > p.gap_limit:
            reason = f"the hand untracked for {untracked:.3f} s, over the bound {p.gap_limit:g} s"
        elif moving and predicted < p.floor:
            gap = f", unseen {unseen:.3f}" if unseen > 0.0005 else ""
            said = "" if self.monitored else "; the hand not monitored, taken at rest"
            reason = (
                f"separation {separation:.3f} m would fall under the floor {p.floor:.3f} m within the stop "
                f"({terms.describe()}{gap}){said}"
            )
        return Verdict(bool(reason), reason, separation, predicted, unseen, terms, self.monitored)


class PlannedTravel:
    """A plan's own motion as the robot's part of the rule, ISO's integral form: during the reaction the arm runs its
    plan (the controller follows it until the stop's stamp), so S_r is the separation the plan loses over T_r; the
    stop brakes along the path from the plan's state at the stamp (braking.py), so S_s is what the separation loses
    over the braking's arc. Both read off the planned distances (to the scene's hand, as functions of time and arc),
    the worst point of each stretch, capped at the plan's end (the plan rests there sooner)."""

    def __init__(self, times: np.ndarray, distances: np.ndarray, arc: np.ndarray, speeds: np.ndarray) -> None:
        self.times, self.distances = np.asarray(times, dtype=float), np.asarray(distances, dtype=float)
        self.arc, self.speeds = np.asarray(arc, dtype=float), np.asarray(speeds, dtype=float)
        if not (
            len(self.times) >= 2 and self.distances.shape == self.arc.shape == self.speeds.shape == self.times.shape
        ):
            raise SafetyError(f"a plan's travel needs two samples or more of each, got {len(self.times)} times")
        self.accelerations = np.gradient(self.speeds, self.times)

    def _lowest(self, values: np.ndarray, at: np.ndarray, start: float, end: float) -> float:
        """The least of `values` (sampled at ascending `at`) over [start, end], linear between samples."""
        inside = values[(at > start) & (at < end)]
        ends = np.interp([start, end], at, values)
        return float(min(ends.min(), inside.min())) if inside.size else float(ends.min())

    def terms(
        self, parameters: SeparationParameters, time: float, reaction: float, hand_speed: float = 0.0
    ) -> ProtectiveSeparation:
        """S_p's terms at `time` s into the plan, a stop starting `reaction` s later, the hand closing at
        `hand_speed` m/s over the reaction and the braking."""
        if not (math.isfinite(time) and math.isfinite(reaction) and reaction >= 0 and math.isfinite(hand_speed)):
            raise SafetyError(f"a plan's travel needs a finite time, reaction >= 0 s and hand speed, got "
                              f"{time!r}, {reaction!r}, {hand_speed!r}")  # fmt: skip
        end = float(self.times[-1])
        start, braking_start = min(max(time, 0.0), end), min(max(time + reaction, 0.0), end)
        now = float(np.interp(start, self.times, self.distances))
        reacted = self._lowest(self.distances, self.times, start, braking_start)
        arc = float(np.interp(braking_start, self.times, self.arc))
        speed = float(np.interp(braking_start, self.times, self.speeds))
        acceleration = float(np.interp(braking_start, self.times, self.accelerations))
        travel, stop_time = braking_travel(speed, acceleration, parameters.deceleration, parameters.jerk)
        rested = reacted
        if travel > 0:
            rested = min(reacted, self._lowest(self.distances, self.arc, arc, min(arc + travel, float(self.arc[-1]))))
        return ProtectiveSeparation(
            hand=max(hand_speed, 0.0) * (reaction + stop_time),
            robot=max(now - reacted, 0.0),
            braking=max(reacted - rested, 0.0),
            intrusion=parameters.intrusion,
            tracker=parameters.tracker_uncertainty,
            robot_uncertainty=parameters.robot_uncertainty,
            reaction=reaction,
            stop_time=stop_time,
        )

    def moving(self, time: float) -> bool:
        """Whether the plan still moves at or after `time` (not at rest at its end)."""
        return time < float(self.times[-1]) and (
            float(np.interp(time, self.times, self.speeds)) > _AT_REST
            or float(self.arc[-1] - np.interp(time, self.times, self.arc)) > _AT_REST
        )


@dataclass(frozen=True)
class PlannedSeparation:
    """A plan's least predicted separation (separation − S_p) over the samples at which it still moves."""

    time: float  # s, of the sample
    separation: float  # m, planned
    predicted: float  # m
    terms: ProtectiveSeparation


def least_planned_separation(
    plan: PlannedTravel, parameters: SeparationParameters, reaction: float, hand_speed: float = 0.0
) -> PlannedSeparation:
    """The rule applied to a plan before motion, with the hand resting at the scene's place (or closing at a
    declared `hand_speed` m/s): at each planned sample at which the plan still moves, the sample with the least
    separation − S_p (PlannedTravel's terms, a stop `reaction` s ahead)."""
    worst: PlannedSeparation | None = None
    for time, distance in zip(plan.times, plan.distances):
        if not plan.moving(float(time)):
            continue
        terms = plan.terms(parameters, float(time), reaction, hand_speed)
        predicted = float(distance) - terms.total
        if worst is None or predicted < worst.predicted:
            worst = PlannedSeparation(float(time), float(distance), predicted, terms)
    if worst is None:
        raise SafetyError("a plan that never moves has no separation to check")
    return worst
