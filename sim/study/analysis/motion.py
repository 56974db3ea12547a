"""The participant's motion, compared between the conditions, from the records' motion columns (filled by the runner
from the tracked head and hands, sim.study.motion). Pure: records in, numbers and lines out.

Test 2's robot comes onto the hand: how far and how fast the hand moves away during the approach is an implicit
comfort measure beside the press, and the head's distance to the end effector at the press says how far the
participant kept their head. Per measure (MOTION_MEASURES): each participant's mean per condition over their trials
with a value, the mean across participants with its t interval, and the paired VR − reality comparison, as for the
stop distance; test 1's withdrawal too. With `model`, the test 2 withdrawal distance's VR − reality contrast also
comes from the stop distance's crossover mixed model. The measures are secondary and exploratory: no SESOI, no
verdict.

Tracking: per condition, the trials with a gap (a body's poses further apart than the protocol's tracking gap), and
each body's untracked time in all and in the worst trial. A trial without a value of a measure is left out of it,
and counted per condition beside its contrast, by why (LEFT_OUT): nothing tracked in the trial; no tracked hand at
the scene's hand (the hands sent no pose, or none was near it); the head sent no pose; a gap in the hand's tracking
inside the withdrawal's window (missing, never 0); no press. The trials without a hand at the scene's hand, or
without the head, are also named by participant. A pilot (one participant) gets that
participant's mean per condition, without an interval. Records without any motion (files written
before the motion's columns, sessions without a tracker) give a summary that says so, not an error.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

from sim.study.analysis.contrasts import FACTOR_NAMES, trials_for
from sim.study.analysis.errors import AnalysisError
from sim.study.analysis.mixed_model import ModelFit, fit_model, formula, model_design
from sim.study.analysis.statistics import Estimate, PairedComparison, mean_estimate, one_value, paired_comparison
from sim.study.analysis.summary import cell, per_participant
from sim.study.design.spec import CONDITIONS
from sim.study.errors import StudyError
from sim.study.motion.measures import REST_DURATION, REST_SPEED, SPEED_SPAN, WITHDRAWAL_LIMIT
from sim.study.run.protocol import TRACKING_GAP
from sim.study.run.records import TrialRecord

__all__ = [
    "MotionMeasure",
    "MOTION_MEASURES",
    "MODELLED",
    "DEFINED",
    "TRACKED_BODIES",
    "LEFT_OUT",
    "left_out_why",
    "MotionComparison",
    "BodyTracking",
    "ConditionTracking",
    "MotionSummary",
    "motion_recorded",
    "summarise_motion",
    "motion_lines",
]


@dataclass(frozen=True)
class MotionMeasure:
    column: str  # the record's column
    test: int
    body: str  # the tracked body it comes from (TRACKED_BODIES): without that body's poses, a trial has no value
    label: str
    unit: str  # the report's
    scale: float  # from the record's unit (m, m/s) to the report's
    digits: int
    definition: str  # for the report, the pre-registration and the docs

    def value(self, record: TrialRecord) -> float:
        """The record's value; NaN when the measure's body sent no pose in the trial, whatever the column says."""
        return float(getattr(record, self.column)) if _tracked(record, self.body) else math.nan


_WITHDRAWAL = (
    "how far the hand under the robot got away from the robot, from where it was at the approach's start: only "
    "motion not towards the robot counts (each displacement less its component towards the end effector's point at "
    "the press, or at rest without one), taken from the approach's start until the hand is at rest again (within "
    f"{REST_SPEED * REST_DURATION * 1000:.0f} mm for {REST_DURATION:g} s after it moved), at most "
    f"{WITHDRAWAL_LIMIT:g} s after the robot rests; a tracking gap in that window leaves it missing"
)
MOTION_MEASURES = (
    MotionMeasure("withdrawal_distance", 2, "hand", "withdrawal distance", "cm", 100.0, 1, _WITHDRAWAL),
    MotionMeasure(
        "withdrawal_peak_speed",
        2,
        "hand",
        "withdrawal peak speed",
        "m/s",
        1.0,
        2,
        f"the highest speed of the hand under the robot away from the robot (its velocity less any part towards the "
        f"end effector) in the withdrawal's window, each speed taken over at least {SPEED_SPAN * 1000:.0f} ms",
    ),
    MotionMeasure(
        "head_distance_at_press",
        2,
        "head",
        "head to the end effector at the press",
        "cm",
        100.0,
        1,
        "the head's distance to the robot's end effector when the stop press landed; none without a press",
    ),
    MotionMeasure("withdrawal_distance", 1, "hand", "withdrawal distance", "cm", 100.0, 1, _WITHDRAWAL),
)
# The measure whose VR − reality contrast also comes from the crossover mixed model, as the stop distance's does:
# the withdrawal is the comfort measure beside the press, so it gets the press's analysis
MODELLED = MOTION_MEASURES[0]
# Each column once, its first measure (test 1 and test 2 share the withdrawal's): where the measures are defined
DEFINED = tuple(
    measure
    for k, measure in enumerate(MOTION_MEASURES)
    if measure.column not in {earlier.column for earlier in MOTION_MEASURES[:k]}
)
# The bodies whose tracking is summarised, with the record's column of their untracked time
TRACKED_BODIES = {"hand": "hand_untracked", "head": "head_untracked"}
# Why a trial has no value of a measure, in the report's words
LEFT_OUT = {
    "nothing": "nothing tracked",
    "hand": "no tracked hand at the scene's hand",
    "head": "the head sent no pose",
    "gap": "a tracking gap in the withdrawal's window",
    "press": "no press",
}
# What a body missing from a trial means, for the trials named by participant
_MISSING = {
    "hand": "no tracked hand was at the scene's hand as the approach started (neither hand sent a pose, or neither "
    "was within 25 cm of it)",
    "head": "the head sent no pose",
}


@dataclass(frozen=True)
class MotionComparison:
    measure: MotionMeasure
    conditions: dict[str, Estimate]  # the conditions with at least 2 participants with a value (a pilot's: 1)
    vr_vs_reality: PairedComparison | None  # None with fewer than 2 participants with a value in both
    model: ModelFit | None  # the crossover mixed model's fit (MODELLED only, when asked and it could be fitted)
    left_out: dict[str, dict[str, int]]  # condition -> why (LEFT_OUT's keys) -> the measure's test's trials


@dataclass(frozen=True)
class BodyTracking:
    tracked: int  # trials in which the body sent any pose
    with_gap: int  # of those, the trials with untracked time
    untracked_total: float  # s over those trials
    untracked_most: float  # s, the most in one trial (the records keep a trial's sum, not its single gaps); NaN
    # when the body was tracked in no trial


@dataclass(frozen=True)
class ConditionTracking:
    trials: int
    bodies: dict[str, BodyTracking]  # by TRACKED_BODIES' names
    hands: dict[str, int]  # the hand taken for the one under the robot (tracked_hand): trials each


@dataclass(frozen=True)
class MotionSummary:
    recorded: bool  # any trial has a tracked body; else nothing else is filled
    comparisons: tuple[MotionComparison, ...]  # in MOTION_MEASURES' order, those with any value
    tracking: dict[str, ConditionTracking]  # per condition with trials
    # body -> participant -> condition -> trials without it: the head sent no pose; no tracked hand at the scene's hand
    untracked: dict[str, dict[int, dict[str, int]]]
    gap: float  # s: the protocol's tracking gap
    notes: tuple[str, ...]


def _tracked(record: TrialRecord, body: str) -> bool:
    """Whether `body` sent any pose in the trial: its untracked time is a number (NaN when it sent nothing); the
    hand also needs to have been taken for the one under the robot."""
    if body == "hand" and not record.tracked_hand:
        return False
    return math.isfinite(getattr(record, TRACKED_BODIES[body]))


def left_out_why(record: TrialRecord, measure: MotionMeasure) -> str:
    """Why the record has no value of `measure` (a key of LEFT_OUT), or "" when it has one."""
    if math.isfinite(measure.value(record)):
        return ""
    if not any(_tracked(record, body) for body in TRACKED_BODIES) and not record.tracked_hand:
        return "nothing"
    if not _tracked(record, measure.body):
        return measure.body
    if measure.body == "head" and not record.pressed:
        return "press"
    return "gap"


def motion_recorded(records: Sequence[TrialRecord]) -> bool:
    """Whether any trial has a tracked body: not so in files written before the motion's columns, nor in sessions
    without a tracker."""
    return any(_tracked(record, body) for record in records for body in TRACKED_BODIES)


def _compare(records: Sequence[TrialRecord], measure: MotionMeasure, model: bool, notes: list[str]) -> MotionComparison:
    where = f"test {measure.test}'s {measure.label}"
    pilot = len({r.participant for r in records}) == 1
    conditions = {}
    for condition in CONDITIONS:
        means = per_participant(records, cell(measure.test, condition), measure.value)
        if len(means) >= 2:
            conditions[condition] = mean_estimate(list(means.values()))
        elif pilot and means:
            conditions[condition] = one_value(*means.values())
        else:
            notes.append(f"{where} in {condition}: {len(means)} participant(s) with a value, too few for a mean")
    vr = per_participant(records, cell(measure.test, "vr"), measure.value)
    reality = per_participant(records, cell(measure.test, "reality"), measure.value)
    both = sorted(set(vr) & set(reality))
    paired = None
    if len(both) >= 2:
        paired = paired_comparison([vr[p] for p in both], [reality[p] for p in both])
    else:
        notes.append(f"{where}: {len(both)} participant(s) with a value in both conditions, too few to compare")
    fit = None
    if model and measure == MODELLED:
        try:
            # a participant with values in one condition only says nothing about VR − reality, and the model
            # refuses them: they are left out of it, as they are of the pairs
            paired_records = [r for r in records if r.participant in both]
            trials = trials_for(paired_records, measure.test, measure.value)
            fit = fit_model(model_design(trials, FACTOR_NAMES[measure.test]), trials.value)
        except StudyError as error:
            notes.append(f"{where}: no mixed model: {error}")
    return MotionComparison(measure, conditions, paired, fit, _left_out(records, measure))


def _left_out(records: Sequence[TrialRecord], measure: MotionMeasure) -> dict[str, dict[str, int]]:
    """Per condition (reality, then vr: the table's order), the measure's test's trials without a value, by why."""
    left_out: dict[str, dict[str, int]] = {}
    for condition in sorted(CONDITIONS):
        why = Counter(left_out_why(r, measure) for r in records if r.test == measure.test and r.condition == condition)
        del why[""]
        left_out[condition] = {reason: why[reason] for reason in LEFT_OUT if why[reason]}
    return left_out


def _left_out_words(left_out: dict[str, dict[str, int]]) -> str:
    """'reality 2 (2 no tracked hand at the scene's hand); vr 1 (...)', the conditions with any left out."""
    return "; ".join(
        f"{condition} {sum(reasons.values())} ("
        + ", ".join(f"{n} {LEFT_OUT[reason]}" for reason, n in reasons.items())
        + ")"
        for condition, reasons in left_out.items()
        if reasons
    )


def _body(records: Sequence[TrialRecord], body: str) -> BodyTracking:
    untracked = [getattr(r, TRACKED_BODIES[body]) for r in records if _tracked(r, body)]
    return BodyTracking(
        tracked=len(untracked),
        with_gap=sum(1 for seconds in untracked if seconds > 0.0),
        untracked_total=float(sum(untracked)),
        untracked_most=max(untracked, default=math.nan),
    )


def summarise_motion(records: Sequence[TrialRecord], model: bool = False) -> MotionSummary:
    """The motion's comparisons and the tracking, per condition; with `model`, the test 2 withdrawal distance's
    mixed model too (a few seconds' fit). AnalysisError only when there are no records at all."""
    if not records:
        raise AnalysisError("no trial records to analyse")
    if not motion_recorded(records):
        return MotionSummary(False, (), {}, {}, TRACKING_GAP, ())
    notes: list[str] = []
    comparisons = []
    for measure in MOTION_MEASURES:
        if any(r.test == measure.test and math.isfinite(measure.value(r)) for r in records):
            comparisons.append(_compare(records, measure, model, notes))
        elif any(r.test == measure.test for r in records):
            why = _left_out_words(_left_out(records, measure))
            notes.append(f"no test {measure.test} trial has a {measure.label}: all left out, {why}")
    tracking = {}
    for condition in CONDITIONS:
        mine = [r for r in records if r.condition == condition]
        if mine:
            tracking[condition] = ConditionTracking(
                trials=len(mine),
                bodies={body: _body(mine, body) for body in TRACKED_BODIES},
                hands=dict(sorted(Counter(r.tracked_hand for r in mine if r.tracked_hand).items())),
            )
    untracked: dict[str, dict[int, dict[str, int]]] = {}
    for body in TRACKED_BODIES:
        missing: dict[int, dict[str, int]] = {}
        for r in records:
            if not _tracked(r, body):
                by_condition = missing.setdefault(r.participant, {})
                by_condition[r.condition] = by_condition.get(r.condition, 0) + 1
        untracked[body] = dict(sorted(missing.items()))
    return MotionSummary(True, tuple(comparisons), tracking, untracked, TRACKING_GAP, tuple(notes))


def _estimate(estimate: Estimate | None, measure: MotionMeasure) -> str:
    if estimate is None:
        return "–"
    s, d = measure.scale, measure.digits
    if math.isnan(estimate.ci_low):  # a pilot's one participant
        return f"{estimate.mean * s:.{d}f} (n {estimate.n})"
    return f"{estimate.mean * s:.{d}f} [{estimate.ci_low * s:.{d}f}, {estimate.ci_high * s:.{d}f}] (n {estimate.n})"


def _difference(c: PairedComparison | None, measure: MotionMeasure) -> str:
    if c is None:
        return "– | – | – | –"
    s, d = measure.scale, measure.digits
    p = "< 0.001" if c.t_p < 0.001 else f"{c.t_p:.3f}"
    return (
        f"{c.n} | {c.mean_difference * s:+.{d}f} [{c.ci_low * s:+.{d}f}, {c.ci_high * s:+.{d}f}] | {p} | "
        f"{c.cohen_dz:.2f}"
    )


def _seconds(value: float) -> str:
    return "–" if math.isnan(value) else f"{value:.2f}"


def _counts(by_condition: dict[str, int]) -> str:
    return ", ".join(f"{n} in {condition}" for condition, n in by_condition.items())


def _model_line(c: MotionComparison) -> str:
    fit, m = c.model, c.measure
    assert fit is not None
    k, s, d = fit.contrast, m.scale, m.digits
    said = f" ({'; '.join(fit.notes)})" if fit.notes else ""
    return (
        f"Test {m.test}'s {m.label} in the stop distance's crossover mixed model, "
        f"{formula(f'{m.label} ({m.unit})', FACTOR_NAMES[m.test])}, random effects: {fit.random_effects}: "
        f"VR − reality {k.estimate * s:+.{d}f} {m.unit} [{k.ci_low * s:+.{d}f}, {k.ci_high * s:+.{d}f}] "
        f"({fit.participants} participants with both conditions, {fit.trials} trials, t with {fit.df} df){said}."
    )


def motion_lines(summary: MotionSummary, caveat: str = "", trackers: Sequence[str] = ()) -> list[str]:
    """The report's section on the participant's motion; when nothing was tracked, one line that says so. `caveat`
    (sim.study.analysis.trackers): what every VR − reality contrast carries when the conditions' trackers differ;
    `trackers`: the lines on them, after the tracking's."""
    lines = ["## The participant's motion", ""]
    if not summary.recorded:
        return lines + [
            "No motion was recorded: no trial has a tracked head or hand (records written before the motion's "
            "columns, or sessions without a tracker).",
            "",
        ]
    lines += [
        "How the participant moved while the robot approached, from their tracked head and hands. Secondary and "
        "exploratory: compared VR − reality without an equivalence margin, and no verdict is drawn. Each "
        "participant's trials with a value are averaged per condition, then VR and reality are compared in pairs "
        "(paired t-test with Cohen's d_z); 95 % t intervals across participants. n: the participants with a value "
        "(for the difference, in both conditions).",
        "",
    ]
    lines += [f"- **{measure.label}**: {measure.definition}." for measure in DEFINED]
    lines += [
        "",
        "| test | measure | reality [95 % CI] | VR [95 % CI] | n | VR − reality [95 % CI] | p (t) | d_z | "
        "trials left out (reality; VR) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for c in summary.comparisons:
        m = c.measure
        counts = "; ".join(str(sum(c.left_out.get(condition, {}).values())) for condition in ("reality", "vr"))
        lines.append(
            f"| {m.test} | {m.label} ({m.unit}) | {_estimate(c.conditions.get('reality'), m)} | "
            f"{_estimate(c.conditions.get('vr'), m)} | {_difference(c.vr_vs_reality, m)} | {counts} |"
        )
    lines.append("")
    left = [
        f"- test {c.measure.test}'s {c.measure.label}: {_left_out_words(c.left_out)}"
        for c in summary.comparisons
        if any(c.left_out.values())
    ]
    if left:
        lines += ["Trials left out of a measure, which have no value of it, and why:", "", *left, ""]
    if caveat:
        measures = ", ".join(f"test {c.measure.test}'s {c.measure.label}" for c in summary.comparisons)
        modelled = ", and the model below" if any(c.model is not None for c in summary.comparisons) else ""
        lines += [f"**Caveat on every VR − reality contrast here** ({measures}{modelled}): {caveat}.", ""]
    lines += [_model_line(c) for c in summary.comparisons if c.model is not None]
    if any(c.model is not None for c in summary.comparisons):
        lines.append("")
    lines += [
        "Tracking: a body's poses further apart than "
        f"{summary.gap:g} s (the protocol's tracking gap) leave a gap, and the approach's time in such gaps is "
        "untracked. Per condition, the trials in which each body sent any pose, those of them with a gap, the "
        "untracked time in all and the most in one trial, s:",
        "",
        "| condition | trials | hand tracked | with a gap | untracked | most in a trial | head tracked | with a gap | "
        "untracked | most in a trial |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for condition, t in summary.tracking.items():
        cells = " | ".join(
            f"{b.tracked} | {b.with_gap} | {_seconds(b.untracked_total)} | {_seconds(b.untracked_most)}"
            for b in (t.bodies["hand"], t.bodies["head"])
        )
        lines.append(f"| {condition} | {t.trials} | {cells} |")
    lines.append("")
    taken = "; ".join(
        f"{condition}: " + ", ".join(f"{hand} in {n}" for hand, n in t.hands.items())
        for condition, t in summary.tracking.items()
        if t.hands
    )
    lines.append(f"The hand taken for the one under the robot: {taken}.")
    for body, participants in summary.untracked.items():
        if participants:
            named = "; ".join(f"participant {p} ({_counts(counts)})" for p, counts in participants.items())
            lines.append(f"Trials in which {_MISSING[body]}, left out of its measures: {named}.")
    lines.append("")
    lines += trackers
    if summary.notes:
        lines += [f"- {note}" for note in summary.notes] + [""]
    return lines
