"""Missing trials (sim.study.analysis.missing, contrasts, report): in a simulated study whose participants lose trials
more often where they withdraw fast (fast approaches, more so in reality), missing at random given the cell, the
trial-level mixed model recovers the true VR − reality contrast while the per-participant means are biased; the
delta-adjusted sensitivity analysis moves the contrast the way δ says; the report carries both."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from sim.study.analysis.errors import AnalysisError
from sim.study.analysis.missing import delta_adjusted, pooled
from sim.study.analysis.mixed_model import Trials, fit_model, model_design
from sim.study.analysis.report import write_report
from sim.study.analysis.statistics import paired_comparison
from sim.study.design.spec import load_design
from sim.study.participants.model import Population, study_measures
from sim.study.power.sample_size import study_layout
from tests.unit.sim.study.analysis.test_summary import study

TRUE_CONTRAST = -0.02  # m: the population's VR − reality distance at the press
POPULATION = Population(vr_comfort_shift=TRUE_CONTRAST, comfort_shift_sd=0.005)
# People stop a faster robot further away (m, on top of their comfort distance), and a fast approach brings a fast
# withdrawal, which loses the trial more often: in reality (hands near the real arm) far more than in VR
SPEED_EFFECT = {"slow": 0.0, "medium": 0.04, "fast": 0.08}
LOSS_IN_REALITY = {"slow": 0.05, "medium": 0.3, "fast": 0.7}
LOSS_IN_VR = 0.1
SESOI = 0.02


def simulated_study(seed: int = 0) -> Trials:
    """Test 2 of 12 participants, as their plans lay it out, measures from the participant model, the lost trials
    NaN."""
    layout = study_layout(load_design(None), 2, 12, 1)
    rng = np.random.default_rng(seed)
    index = np.unique(layout.participant, return_inverse=True)[1]
    values = study_measures(POPULATION, 2, index, layout.vr, rng)
    values += np.array([SPEED_EFFECT[level] for level in layout.factor])
    loss = np.where(layout.vr, LOSS_IN_VR, np.array([LOSS_IN_REALITY[level] for level in layout.factor]))
    values[rng.random(values.size) < loss] = math.nan
    return dataclasses.replace(layout, value=values)


def observed(trials: Trials) -> Trials:
    kept = np.isfinite(trials.value)
    columns = (trials.participant, trials.vr, trials.vr_first, trials.factor, trials.path, trials.value)
    return Trials(*(np.asarray(column)[kept] for column in columns))


def test_the_trial_level_model_recovers_the_contrast_where_participant_means_are_biased() -> None:
    every = simulated_study()
    lost = ~np.isfinite(every.value)
    assert 0.3 < lost[~every.vr].mean() < 0.6 and lost[every.vr].mean() < 0.2  # reality's trials lost far more
    trials = observed(every)
    fit = fit_model(model_design(trials, "speed set"), trials.value)
    assert fit.contrast.ci_low <= TRUE_CONTRAST <= fit.contrast.ci_high
    assert abs(fit.contrast.estimate - TRUE_CONTRAST) < 0.005
    # the per-participant means weigh reality's slow trials (stopped closer) more: VR − reality comes out too high
    people = np.unique(trials.participant)
    means = {
        in_vr: [float(np.mean(trials.value[(trials.participant == p) & (trials.vr == in_vr)])) for p in people]
        for in_vr in (True, False)
    }
    naive = paired_comparison(means[True], means[False])
    assert naive.mean_difference - TRUE_CONTRAST > 0.015
    assert not naive.ci_low <= TRUE_CONTRAST <= naive.ci_high


def test_the_sensitivity_analysis_moves_with_delta_the_way_it_should() -> None:
    trials = simulated_study()
    scenarios = [("", 0.0), ("vr", -SESOI), ("vr", SESOI), ("reality", -SESOI), ("reality", SESOI)]
    result = delta_adjusted(trials, "speed set", SESOI, scenarios=scenarios, imputations=2)
    assert result.missing["reality"] > 3 * result.missing["vr"] > 0
    assert result.trials == trials.value.size and result.imputations == 2
    mar, vr_down, vr_up, reality_down, reality_up = (s.verdict.estimate for s in result.scenarios)
    assert mar == pytest.approx(result.primary.estimate, abs=0.003)  # imputing under MAR is the primary analysis
    assert vr_down < mar < vr_up  # VR's missing trials further away: VR − reality grows
    assert reality_up < mar < reality_down  # reality's: it shrinks
    assert reality_down - reality_up > vr_up - vr_down  # more of reality's trials are missing
    # the pooled interval is about as wide as the primary's (the imputation neither invents nor loses information)
    mar_verdict, primary = result.scenarios[0].verdict, result.primary
    assert 0.7 < (mar_verdict.ci95[1] - mar_verdict.ci95[0]) / (primary.ci95[1] - primary.ci95[0]) < 2.0
    assert result.summary(" m").startswith(f"{result.missing['vr']} VR and {result.missing['reality']} reality")


def test_without_missing_trials_there_is_nothing_to_impute() -> None:
    complete = simulated_study()
    complete = dataclasses.replace(complete, value=np.nan_to_num(complete.value, nan=0.12))
    result = delta_adjusted(complete, "speed set", SESOI)
    assert result.scenarios == () and result.holds and result.summary() == "no trial missing"


def test_a_cell_that_lost_every_trial_cannot_be_imputed() -> None:
    trials = simulated_study()
    values = trials.value.copy()
    values[(trials.factor == "fast") & (trials.path == "straight") & ~trials.vr] = math.nan
    with pytest.raises(AnalysisError, match="no observed trial informs VR − reality × speed set.*cannot be imputed"):
        delta_adjusted(dataclasses.replace(trials, value=values), "speed set", SESOI, imputations=2)


def test_rubins_rules_pool_within_and_between_imputation_variance() -> None:
    estimate, se, df = pooled([1.0, 2.0, 3.0], [1.0, 1.0, 1.0], 1e9)
    assert estimate == 2.0 and se == pytest.approx(math.sqrt(1.0 + 4.0 / 3.0))
    share = (4.0 / 3.0) / (7.0 / 3.0)
    assert df == pytest.approx(2 / share**2, rel=1e-6)  # Rubin's own with a huge complete-data df
    assert pooled([1.0, 1.0], [0.5, 0.5], 10)[2] == pytest.approx(11 / 13 * 10)  # no between: the observed df


def test_the_report_states_the_sensitivity_beside_the_verdict(tmp_path: Path) -> None:
    records = study()
    lost = 0
    for k, record in enumerate(records):  # every third reality trial of test 2 loses its press
        if record.test == 2 and record.condition == "reality" and k % 3 == 0:
            records[k] = dataclasses.replace(record, pressed=False, distance_at_press=math.nan)
            lost += 1
    assert lost > 10
    report = write_report(records, tmp_path, "A study", {1: 0.05, 2: 0.02}, imputations=2).read_text()
    beside = next(line for line in report.splitlines() if line.startswith("- Test 2: "))
    assert f". Missing trials' sensitivity: 0 VR and {lost} reality trial(s) missing: " in beside
    assert "- Test 1: different: " in report and "Missing trials' sensitivity: no trial missing." in report
    section = report.split("### Missing trials: the sensitivity analysis")[1].split("###")[0]
    scenario_rows = [line for line in section.splitlines() if line.startswith("| 2 |")]
    assert len(scenario_rows) == 5 and f"| 0 / {lost} of " in scenario_rows[0]
    assert "δ = 0: missing at random" in scenario_rows[0] and "reality's missing trials +0.02 m" in section
    assert "2 times" in section and "Rubin's rules" in section
    assert "biased; the verdicts above are the trial-level model's" in report
