"""The study's results across participants, from their trial records. Pure logic (sim.study.analysis.statistics).

The verdicts are the trial-level mixed model's (sim.study.analysis.contrasts), with the sensitivity analysis of the
missing trials. The figures here are descriptive: each participant's trials are first averaged per cell (condition,
and speed set or path), then the per-participant means are compared in pairs, VR against reality. A mean of the
trials a participant kept weighs the design's cells by how many each kept, so where trials are missing unevenly (fast
withdrawals lose more) these figures are biased, and the model's are not (when trials are missing at random given
their cell).
  test 1   the ratio perceived / actual distance (actual: FK of the robot at rest) per condition, with its interval
           across participants, and the paired VR − reality difference of the ratio;
  test 2   the end effector's distance to the hand at the press (FK of the achieved state) per condition, and the
           paired VR − reality difference overall, per speed set and per path; how often each path was preferred;
           and how far the thesis's estimate from the press time lies from the measured distance.
Given the design's SESOI, each test's mixed model and its verdicts (sim.study.analysis.contrasts) come with it.

A pilot (one participant) has no spread across participants: its summary keeps that participant's mean per condition
(without an interval; a condition without a value is left out), and no paired comparison, model or verdict.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from sim.study.analysis.contrasts import TestContrast, contrast, perceived_ratio
from sim.study.analysis.errors import AnalysisError
from sim.study.analysis.missing import IMPUTATIONS
from sim.study.analysis.statistics import Estimate, PairedComparison, mean_estimate, one_value, paired_comparison
from sim.study.design.spec import CONDITIONS, TESTS
from sim.study.errors import StudyError
from sim.study.run.records import TrialRecord

__all__ = ["StudySummary", "cell", "per_participant", "perceived_ratio", "summarise"]


@dataclass(frozen=True)
class StudySummary:
    """The results; in a pilot (`pilot`: one participant) the estimates are the participant's means without an
    interval, a condition without a value is missing, and the comparisons are None (by speed set and path: empty)."""

    participants: tuple[int, ...]
    trials: int
    distance_ratio: dict[str, Estimate]  # test 1, per condition: perceived / actual
    distance_ratio_vr_vs_reality: PairedComparison | None
    stop_distance: dict[str, Estimate]  # test 2, per condition: m at the press
    stop_distance_vr_vs_reality: PairedComparison | None
    stop_distance_by_speed_set: dict[str, PairedComparison]
    stop_distance_by_path: dict[str, PairedComparison]
    preferences: dict[str, Counter[str]]  # per condition: groups in which each path was preferred (0 too)
    extrapolation_error: Estimate | None  # test 2: |the plan's distance at the press time − the measured one|, m
    notes: list[str] = field(default_factory=list)  # missing answers, trials without a press
    contrasts: dict[int, TestContrast] = field(default_factory=dict)  # per test, given its SESOI and enough data

    @property
    def pilot(self) -> bool:
        return len(self.participants) == 1


def per_participant(
    records: Sequence[TrialRecord], keep: Callable[[TrialRecord], bool], value: Callable[[TrialRecord], float]
) -> dict[int, float]:
    """Each participant's mean of `value` over their records that `keep` selects and that have a finite value
    (descriptive: biased where the cells lost trials unevenly; see the module's doc)."""
    sums: dict[int, list[float]] = {}
    for record in records:
        if keep(record):
            number = value(record)
            if math.isfinite(number):
                sums.setdefault(record.participant, []).append(number)
    return {participant: float(np.mean(values)) for participant, values in sums.items()}


def _paired(
    records: Sequence[TrialRecord],
    keep: Callable[[TrialRecord], bool],
    value: Callable[[TrialRecord], float],
    what: str,
) -> PairedComparison:
    vr = per_participant(records, lambda record: keep(record) and record.condition == "vr", value)
    reality = per_participant(records, lambda record: keep(record) and record.condition == "reality", value)
    both = sorted(set(vr) & set(reality))
    if len(both) < 2:
        raise AnalysisError(
            f"{what}: a paired comparison needs at least 2 participants with both conditions, got {len(both)}"
        )
    return paired_comparison([vr[p] for p in both], [reality[p] for p in both])


def _estimate(
    records: Sequence[TrialRecord],
    keep: Callable[[TrialRecord], bool],
    value: Callable[[TrialRecord], float],
    what: str,
) -> Estimate:
    means = per_participant(records, keep, value)
    if len(means) < 2:
        raise AnalysisError(f"{what}: needs at least 2 participants, got {len(means)}")
    return mean_estimate(list(means.values()))


def _at_press(record: TrialRecord) -> float:
    return record.distance_at_press


def _pilot_estimates(
    records: Sequence[TrialRecord], test: int, value: Callable[[TrialRecord], float]
) -> dict[str, Estimate]:
    """The pilot's participant's mean per condition with a value."""
    found = {}
    for condition in CONDITIONS:
        means = per_participant(records, cell(test, condition), value)
        if means:
            found[condition] = one_value(*means.values())
    return found


def _pilot(records: Sequence[TrialRecord], notes: list[str], preferences: dict[str, Counter[str]]) -> StudySummary:
    """One participant's summary: their means per condition, and nothing that needs a spread across participants."""
    ratio, at_press = _pilot_estimates(records, 1, perceived_ratio), _pilot_estimates(records, 2, _at_press)
    for test, found in ((1, ratio), (2, at_press)):
        notes += [f"test {test} in {c}: no trial with a value" for c in CONDITIONS if c not in found]
    errors = per_participant(records, cell(2), lambda r: abs(r.distance_extrapolated - r.distance_at_press))
    return StudySummary(
        participants=tuple(sorted({r.participant for r in records})),
        trials=len(records),
        distance_ratio=ratio,
        distance_ratio_vr_vs_reality=None,
        stop_distance=at_press,
        stop_distance_vr_vs_reality=None,
        stop_distance_by_speed_set={},
        stop_distance_by_path={},
        preferences=preferences,
        extrapolation_error=one_value(*errors.values()) if errors else None,
        notes=notes,
    )


def cell(test: int, condition: str = "", speed_set: str = "", path: str = "") -> Callable[[TrialRecord], bool]:
    """Selects the records of `test` and, where given, of one condition, speed set or path."""

    def keep(record: TrialRecord) -> bool:
        return (
            record.test == test
            and condition in ("", record.condition)
            and speed_set in ("", record.speed_set)
            and path in ("", record.path)
        )

    return keep


def _contrasts(
    records: Sequence[TrialRecord], sesoi: Mapping[int, float], notes: list[str], imputations: int
) -> dict[int, TestContrast]:
    found = {}
    for test in TESTS:
        try:
            found[test] = contrast(records, test, sesoi[test], imputations)
        except StudyError as error:
            notes.append(f"test {test}: no mixed model or verdict: {error}")
    return found


def summarise(
    records: Sequence[TrialRecord], sesoi: Mapping[int, float] | None = None, imputations: int = IMPUTATIONS
) -> StudySummary:
    """The study's results; with `sesoi` (per test, the design's), each test's mixed model and verdicts too, and the
    sensitivity analysis of its missing trials (`imputations` per scenario, sim.study.analysis.missing). One
    participant's records make a pilot's summary (StudySummary.pilot), without comparisons, models or verdicts."""
    if not records:
        raise AnalysisError("no trial records to analyse")
    test1, test2 = cell(1), cell(2)
    notes = []
    unanswered = sum(1 for r in records if r.test == 1 and not math.isfinite(r.perceived_distance))
    if unanswered:
        notes.append(f"{unanswered} test 1 trial(s) without a perceived distance, left out")
    unpressed = sum(1 for r in records if r.test == 2 and not r.pressed)
    if unpressed:
        notes.append(f"{unpressed} test 2 trial(s) ended on the hand without a press, left out of the stop distances")
    late = [r.press_late for r in records if r.pressed and r.press_late > 0]
    if late:
        notes.append(
            f"{len(late)} press(es) arrived after their stamp and were applied late (at most {max(late) * 1000:.0f} ms)"
        )
    speed_sets = [name for _, name in sorted({(r.peak_speed, r.speed_set) for r in records if r.test == 2})]
    paths = sorted({r.path for r in records if r.test == 2})
    preferences = {condition: Counter(dict.fromkeys(paths, 0)) for condition in CONDITIONS}
    seen_groups = set()
    for record in records:
        key = (record.participant, record.condition, record.group)
        if record.test == 2 and record.preferred_path and key not in seen_groups:
            seen_groups.add(key)
            preferences[record.condition][record.preferred_path] += 1
    if len({r.participant for r in records}) == 1:
        return _pilot(records, notes, preferences)
    contrasts = {} if sesoi is None else _contrasts(records, sesoi, notes, imputations)
    return StudySummary(
        participants=tuple(sorted({r.participant for r in records})),
        trials=len(records),
        distance_ratio={
            condition: _estimate(records, cell(1, condition), perceived_ratio, f"test 1 in {condition}")
            for condition in CONDITIONS
        },
        distance_ratio_vr_vs_reality=_paired(records, test1, perceived_ratio, "test 1"),
        stop_distance={
            condition: _estimate(records, cell(2, condition), _at_press, f"test 2 in {condition}")
            for condition in CONDITIONS
        },
        stop_distance_vr_vs_reality=_paired(records, test2, _at_press, "test 2"),
        stop_distance_by_speed_set={
            name: _paired(records, cell(2, speed_set=name), _at_press, f"test 2 at {name}") for name in speed_sets
        },
        stop_distance_by_path={
            name: _paired(records, cell(2, path=name), _at_press, f"test 2 on {name}") for name in paths
        },
        preferences=preferences,
        extrapolation_error=_estimate(
            records, test2, lambda r: abs(r.distance_extrapolated - r.distance_at_press), "test 2's extrapolation"
        ),
        notes=notes,
        contrasts=contrasts,
    )
