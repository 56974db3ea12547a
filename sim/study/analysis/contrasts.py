"""VR against reality, per test, the way a reviewer accepts it: the mixed model's VR − reality contrast, fitted to
every trial with a measure (unbiased when trials are missing at random given condition, factor and path), judged
against the design's SESOI (different, equivalent or inconclusive); the sensitivity analysis of the missing trials
(sim.study.analysis.missing) beside it; and, descriptive only, the paired TOST on per-participant means and their
Bland–Altman agreement. Pure logic; `analyse` and `power` both judge through `judge`, so a simulated study is
analysed exactly as a real one.

The measures: test 1, perceived / actual distance (actual: the robot at rest); test 2, the distance at the press.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from sim.study.analysis.equivalence import Agreement, PairedTost, Verdict, agreement, paired_tost, verdict
from sim.study.analysis.errors import AnalysisError
from sim.study.analysis.missing import IMPUTATIONS, Sensitivity, delta_adjusted
from sim.study.analysis.mixed_model import ModelDesign, ModelFit, Trials, fit_model, model_design
from sim.study.run.records import TrialRecord

__all__ = [
    "FACTOR_NAMES",
    "MEASURES",
    "TestContrast",
    "perceived_ratio",
    "measure",
    "factor_level",
    "trials_for",
    "every_trial",
    "judge",
    "contrast",
]

FACTOR_NAMES = {1: "stand-off", 2: "speed set"}
MEASURES = {1: "perceived / actual distance", 2: "distance at the press (m)"}


@dataclass(frozen=True)
class TestContrast:
    test: int
    fit: ModelFit
    verdict: Verdict
    tost: PairedTost  # the cross-check on per-participant means (descriptive: biased where trials are missing)
    agreement: Agreement
    vr_means: dict[int, float]  # per participant
    reality_means: dict[int, float]
    sensitivity: Sensitivity | None  # the verdict under missing trials not at random (sim.study.analysis.missing)
    sensitivity_problem: str = ""  # why there is none


def perceived_ratio(record: TrialRecord) -> float:
    """Test 1: perceived / actual distance (actual: the robot at rest); NaN where it is undefined."""
    if record.distance_at_rest <= 0.0:
        return math.nan
    return record.perceived_distance / record.distance_at_rest


def measure(record: TrialRecord) -> float:
    """The record's value in its test's model; NaN where it has none (no answer, no press)."""
    if record.test == 1:
        return perceived_ratio(record)
    return record.distance_at_press if record.pressed else math.nan


def factor_level(test: int, standoff: float, speed_set: str) -> str:
    """A trial's level of its test's factor (FACTOR_NAMES): test 1 its stand-off, test 2 its speed set."""
    return f"{standoff:g} m" if test == 1 else speed_set


def trials_for(records: Sequence[TrialRecord], test: int, value: Callable[[TrialRecord], float] = measure) -> Trials:
    """The test's trials with a finite `value` (by default the test's measure), as the model's rows. Another value
    (the participant's motion, sim.study.analysis.motion) gets the same crossover model as the test's measure."""
    rows = [r for r in records if r.test == test and math.isfinite(value(r))]
    if not rows:
        raise AnalysisError(f"test {test} has no trial with a measure")
    return _trials(rows, value)


def every_trial(records: Sequence[TrialRecord], test: int, value: Callable[[TrialRecord], float] = measure) -> Trials:
    """Every trial of `test`, its value NaN where it has none: the missing trials' places, for the sensitivity
    analysis (sim.study.analysis.missing)."""
    rows = [r for r in records if r.test == test]
    if not rows:
        raise AnalysisError(f"test {test} has no trial")
    return _trials(rows, value)


def _trials(rows: Sequence[TrialRecord], value: Callable[[TrialRecord], float]) -> Trials:
    return Trials(
        participant=np.array([r.participant for r in rows]),
        vr=np.array([r.condition == "vr" for r in rows]),
        vr_first=np.array([(r.condition == "vr") == (r.condition_position == 1) for r in rows]),
        factor=np.array([factor_level(r.test, r.standoff, r.speed_set) for r in rows]),
        path=np.array([r.path for r in rows]),
        value=np.array([value(r) if math.isfinite(value(r)) else math.nan for r in rows], dtype=float),
    )


def judge(design: ModelDesign, values: np.ndarray, sesoi: float) -> tuple[ModelFit, Verdict]:
    """The mixed model fitted to `values` and the verdict on its VR − reality contrast."""
    fit = fit_model(design, values)
    return fit, verdict(fit.contrast.estimate, fit.contrast.se, fit.df, sesoi)


def _means(trials: Trials, in_vr: bool) -> dict[int, float]:
    chosen = trials.vr == in_vr
    return {
        int(p): float(np.mean(trials.value[chosen & (trials.participant == p)]))
        for p in np.unique(trials.participant[chosen])
    }


def contrast(records: Sequence[TrialRecord], test: int, sesoi: float, imputations: int = IMPUTATIONS) -> TestContrast:
    """VR against reality in `test`: the mixed model on every trial with a measure, and the sensitivity analysis of
    the trials without one (`imputations` per scenario); AnalysisError when its trials cannot be modelled (e.g. fewer
    than 3 participants with both conditions)."""
    trials = trials_for(records, test)
    fit, judged = judge(model_design(trials, FACTOR_NAMES[test]), trials.value, sesoi)
    sensitivity, problem = None, ""
    try:  # the primary verdict stands without it; the report says why it is missing
        sensitivity = delta_adjusted(
            every_trial(records, test), FACTOR_NAMES[test], sesoi, primary=fit, imputations=imputations
        )
    except AnalysisError as error:
        problem = str(error)
    vr, reality = _means(trials, True), _means(trials, False)
    both = sorted(set(vr) & set(reality))
    vr_list, reality_list = [vr[p] for p in both], [reality[p] for p in both]
    return TestContrast(
        test=test,
        fit=fit,
        verdict=judged,
        tost=paired_tost(vr_list, reality_list, sesoi),
        agreement=agreement(vr_list, reality_list),
        vr_means={p: vr[p] for p in both},
        reality_means={p: reality[p] for p in both},
        sensitivity=sensitivity,
        sensitivity_problem=problem,
    )
