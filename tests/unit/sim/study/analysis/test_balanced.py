"""sim.study.analysis.balanced: in a balanced study the closed form is the REML estimate statsmodels reaches with a
tight tolerance, and the mixed model's fit, started there, gives that optimum's contrast, where statsmodels' own
start stops short of it (its L-BFGS says converged) with a standard error 23 % off; a study missing a trial or a cell
is not balanced; an estimate on the boundary leaves the start to statsmodels."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from sim.study.analysis.balanced import balance, reml_start
from sim.study.analysis.mixed_model import CONTRAST, Trials, fit_model, model_design

SHORT = 35  # a seed at which L-BFGS from statsmodels' start stops short of the optimum (Python 3.8 and 3.11 alike)


def crossover(seed: int, participants: int = 6, slope_sd: float = 0.005, noise: float = 0.01) -> Trials:
    """Test 2's shape, 3 speed sets × 3 paths per condition, once each; odd participants do VR first."""
    rng = np.random.default_rng(seed)
    rows = []
    for p in range(1, participants + 1):
        comfort, difference = rng.normal(0.12, 0.03), rng.normal(0.0, slope_sd)
        for vr in (True, False):
            for speed_set in ("slow", "medium", "fast"):
                for path in ("a", "b", "c"):
                    value = comfort + difference * vr + rng.normal(0.0, noise)
                    rows.append((p, vr, p % 2 == 1, speed_set, path, value))
    return Trials(*(np.array(column) for column in zip(*rows)))


def tight_optimum(trials: Trials) -> tuple[np.ndarray, float]:
    """(cov_re / scale, the contrast's SE) of statsmodels' BFGS run to a gradient of 1e-10 from its own start."""
    from statsmodels.regression.mixed_linear_model import MixedLM

    design = model_design(trials, "speed set")
    unit = float(np.std(trials.value))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = MixedLM(trials.value / unit, design.exog, design.groups, exog_re=design.exog_re)
        result = model.fit(reml=True, method=["bfgs"], gtol=1e-10)
    return np.asarray(result.cov_re) / result.scale, float(result.bse_fe[design.names.index(CONTRAST)]) * unit


@pytest.mark.parametrize("seed, slope_sd", [(SHORT, 0.005), (1, 0.02), (2, 0.02)])
def test_in_a_balanced_study_the_start_is_the_reml_estimate_and_the_fit_its_contrast(seed, slope_sd):
    trials = crossover(seed, slope_sd=slope_sd)
    design = model_design(trials, "speed set")
    assert design.balance is not None
    start = reml_start(design.balance, trials.value / np.std(trials.value))
    ratio, se = tight_optimum(trials)
    assert start is not None and np.allclose(start, ratio, rtol=1e-5, atol=1e-7), (start, ratio)
    assert fit_model(design, trials.value).contrast.se == pytest.approx(se, rel=1e-6)


def test_from_statsmodels_own_start_the_fit_stops_short_of_the_optimum():
    """Why the start matters beyond speed: the fit without it, on the seed where L-BFGS stops short."""
    trials = crossover(SHORT)
    design = model_design(trials, "speed set")
    _, se = tight_optimum(trials)
    without = fit_model(dataclasses.replace(design, balance=None), trials.value).contrast.se
    assert abs(without / se - 1.0) > 0.1, (without, se)


def test_a_study_missing_a_trial_or_a_cell_is_not_balanced():
    trials = crossover(1)
    cells = np.array([f"{f}|{p}" for f, p in zip(trials.factor, trials.path)])

    def balance_of(kept: np.ndarray):
        return balance(trials.participant[kept], trials.vr[kept], trials.vr_first[kept], list(cells[kept]))

    assert balance_of(np.full(len(cells), True)) is not None
    assert balance_of(np.arange(len(cells)) != 4) is None  # a trial missing
    assert balance_of(~(np.char.startswith(cells, "slow") & (trials.participant == 2))) is None  # a cell missing


def test_an_estimate_on_the_boundary_leaves_the_start_to_statsmodels():
    """No slope in the data: for some studies the slope's variance estimated in closed form is negative."""
    for seed in range(20):
        trials = crossover(seed, slope_sd=0.0)
        design = model_design(trials, "speed set")
        assert design.balance is not None
        if reml_start(design.balance, trials.value / np.std(trials.value)) is None:
            assert fit_model(design, trials.value).contrast.se > 0.0  # fitted from statsmodels' start
            return
    pytest.fail("no study put the estimate outside the parameter space")
