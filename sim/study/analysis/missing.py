"""Missing trials: how much the verdict leans on their being missing at random. Pure logic (sim.study.analysis
.mixed_model).

A trial can lack its measure (no answer, no press, a tracking loss that voided it), and not at random: fast
withdrawals and hands near the arm lose more trials, and those are the trials of some cells more than of others.
The primary analysis, the mixed model fitted to every trial with a measure, with condition × factor × path as fixed
effects, is unbiased when the trials are missing at random given those (MAR): a cell's missing trials are then like
its observed ones. (Each participant's mean of their observed trials is not: it weighs the cells by how many trials
each kept.) That cannot be checked from the data, so the sensitivity analysis asks how far from MAR the missing trials
would have to be to change the verdict: delta-adjusted multiple imputation (a pattern-mixture model, as the US
National Research Council's 2010 report on missing data and the EMA's guideline ask for):

  1. the primary model is fitted to the observed trials;
  2. each missing trial is imputed `imputations` times from it: its cell's fixed effects drawn from their estimate's
     sampling distribution, plus its participant's predicted random effects, plus a residual drawn from the fitted
     residual SD: what MAR predicts for that trial, with its uncertainty;
  3. in each scenario, the imputed trials of one condition are shifted by δ (the other condition's keep MAR): the
     missing trials of that condition are taken to differ by δ from what their observed neighbours predict;
  4. the model is refitted to each completed set of trials, and the contrasts are pooled by Rubin's rules, with
     Barnard and Rubin's (1999) degrees of freedom from the model's own (participants − sequences);
  5. the pooled contrast is judged against the SESOI by the primary analysis's rules (sim.study.analysis
     .equivalence.verdict).
δ = 0 is MAR by imputation (close to the primary estimate, as it should be); δ = ±SESOI shifts every missing trial of
one condition by the whole margin, which is as far as a difference can go while still "not mattering". The same draws
serve every scenario (a fixed seed), so scenarios differ by δ alone and the report is reproducible.

The imputation keeps the variance components and each participant's random effects at their estimates (drawing the
fixed effects only): a common approximation that understates the imputation's spread slightly when participants
are few.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.study.analysis.equivalence import Verdict, verdict
from sim.study.analysis.errors import AnalysisError
from sim.study.analysis.mixed_model import ModelDesign, ModelFit, Predictive, Trials, fit_model, model_design

__all__ = ["IMPUTATIONS", "SEED", "Scenario", "Sensitivity", "delta_adjusted", "pooled", "sesoi_deltas"]

IMPUTATIONS = 10  # per scenario; 5 already keep the pooled interval within a few percent of its limit (Rubin 1987)
SEED = 59  # the draws' seed: the report's figures are reproducible


@dataclass(frozen=True)
class Scenario:
    """One δ: the missing trials of `shifted` imputed as MAR predicts plus `delta` (the measure's units)."""

    shifted: str  # "vr" or "reality"; "" with δ = 0 (MAR)
    delta: float
    verdict: Verdict  # on the pooled VR − reality contrast


@dataclass(frozen=True)
class Sensitivity:
    """The delta-adjusted analysis of one test's missing trials."""

    missing: dict[str, int]  # per condition ("vr", "reality"): trials without a measure
    trials: int  # every trial of the test, with a measure or not
    imputations: int
    primary: Verdict  # the primary analysis's, on the observed trials
    scenarios: tuple[Scenario, ...]

    @property
    def holds(self) -> bool:
        """Every scenario's verdict is the primary's."""
        return all(s.verdict.label == self.primary.label for s in self.scenarios)

    def summary(self, units: str = "") -> str:
        """One line for the report, beside the primary verdict."""
        if not any(self.missing.values()):
            return "no trial missing"
        missing = f"{self.missing['vr']} VR and {self.missing['reality']} reality trial(s) missing"
        if self.holds:
            deltas = ", ".join(f"{delta:+g}{units}" for delta in sorted({s.delta for s in self.scenarios}))
            return f"{missing}: {self.primary.label} under every δ tried ({deltas})"
        changed = [
            f"{s.verdict.label} with {s.shifted or 'neither'}'s shifted by {s.delta:+g}{units}"
            for s in self.scenarios
            if s.verdict.label != self.primary.label
        ]
        return f"{missing}: {'; '.join(changed)}"


def sesoi_deltas(sesoi: float) -> tuple[tuple[str, float], ...]:
    """The scenarios the report shows: MAR, and each condition's missing trials shifted by ∓SESOI and ±SESOI."""
    return (("", 0.0),) + tuple((shifted, sign * sesoi) for shifted in ("vr", "reality") for sign in (-1.0, 1.0))


def pooled(estimates: Sequence[float], errors: Sequence[float], df_complete: float) -> tuple[float, float, float]:
    """Rubin's rules: (the pooled estimate, its standard error, Barnard and Rubin's degrees of freedom) of the
    estimates and standard errors of m ≥ 2 imputed data sets, each analysed with `df_complete` degrees of freedom."""
    q, u = np.asarray(estimates, dtype=float), np.asarray(errors, dtype=float) ** 2
    m = q.size
    if m < 2 or u.shape != q.shape or df_complete <= 0:
        raise AnalysisError(f"pooling needs 2+ estimates with their errors and df > 0, got {m} and df {df_complete}")
    within, between = float(u.mean()), float(q.var(ddof=1))
    total = within + (1.0 + 1.0 / m) * between
    if total <= 0.0:
        return float(q.mean()), 0.0, float(df_complete)
    share = (1.0 + 1.0 / m) * between / total  # λ: the share of the variance the missing trials add
    df_observed = (df_complete + 1.0) / (df_complete + 3.0) * df_complete * (1.0 - share)
    df_rubin = math.inf if share == 0.0 else (m - 1) / share**2
    df = 1.0 / (1.0 / df_rubin + 1.0 / df_observed) if df_observed > 0 else float(m - 1)
    return float(q.mean()), math.sqrt(total), df


def _fixed_columns(observed_names: tuple[str, ...], full_names: tuple[str, ...]) -> list[int]:
    """Where the observed trials' terms are among the whole layout's: AnalysisError when the layout has a term that
    only missing trials inform (a cell that lost every trial), as nothing observed predicts them."""
    unseen = [name for name in full_names if name not in observed_names]
    if unseen:
        raise AnalysisError(f"no observed trial informs {', '.join(unseen)}: its missing trials cannot be imputed")
    absent = [name for name in observed_names if name not in full_names]
    if absent:  # cannot happen with one layout, but a prediction on other columns would be silently wrong
        raise AnalysisError(f"the observed trials' terms {absent} are not in the whole layout's")
    return [full_names.index(name) for name in observed_names]


def delta_adjusted(
    trials: Trials,
    factor_name: str,
    sesoi: float,
    primary: ModelFit | None = None,
    scenarios: Sequence[tuple[str, float]] | None = None,
    imputations: int = IMPUTATIONS,
    seed: int = SEED,
) -> Sensitivity:
    """The sensitivity of the VR − reality verdict to `trials`' missing values (NaN): every trial of a test, with a
    measure or not. `primary`: the primary fit on the observed trials, if already made. `scenarios`: (the condition
    whose missing trials are shifted, δ), by default sesoi_deltas(sesoi). AnalysisError when the observed trials
    cannot be modelled, or a missing trial lies in a cell that no observed trial informs."""
    if imputations < 2:
        raise AnalysisError(f"Rubin's rules need 2+ imputations, got {imputations}")
    missing_rows = ~np.isfinite(trials.value)
    observed = Trials(*(np.asarray(column)[~missing_rows] for column in _columns(trials)))
    observed_design = model_design(observed, factor_name)
    if primary is None:
        primary = fit_model(observed_design, observed.value)
    primary_verdict = verdict(primary.contrast.estimate, primary.contrast.se, primary.df, sesoi)
    missing = {
        "vr": int(np.sum(missing_rows & trials.vr)),
        "reality": int(np.sum(missing_rows & ~trials.vr)),
    }
    chosen = sesoi_deltas(sesoi) if scenarios is None else tuple(scenarios)
    if not missing_rows.any():  # nothing to impute: every scenario is the primary analysis
        return Sensitivity(missing, int(trials.value.size), imputations, primary_verdict, ())
    full_design = model_design(trials, factor_name)
    basis = primary.predictive
    assert basis is not None  # fit_model always gives it
    columns = _fixed_columns(observed_design.names, full_design.names)
    rows = np.flatnonzero(missing_rows)
    unknown = sorted({int(p) for p in trials.participant[rows]} - {int(p) for p in observed.participant})
    if unknown:
        raise AnalysisError(f"participants {unknown} have no observed trial to predict their missing ones from")
    rng = np.random.default_rng(seed)
    draws = [_imputed(full_design, columns, missing_rows, trials.value, basis, rng) for _ in range(imputations)]
    in_vr = trials.vr[rows]
    results = []
    by_shift: dict[bytes, tuple[float, float, float]] = {}  # a condition without missing trials shifts nothing
    for shifted, delta in chosen:
        if shifted not in ("", "vr", "reality"):
            raise AnalysisError(f"a scenario shifts 'vr' or 'reality', got {shifted!r}")
        shift = np.where(in_vr == (shifted == "vr"), delta, 0.0) if shifted else np.zeros(rows.size)
        key = shift.tobytes()
        if key not in by_shift:
            estimates, errors = [], []
            for imputed in draws:
                completed = trials.value.copy()
                completed[rows] = imputed + shift
                fit = fit_model(full_design, completed)
                estimates.append(fit.contrast.estimate)
                errors.append(fit.contrast.se)
            by_shift[key] = pooled(estimates, errors, full_design.df)
        estimate, se, df = by_shift[key]
        results.append(Scenario(shifted, delta, verdict(estimate, se, df, sesoi)))
    return Sensitivity(missing, int(trials.value.size), imputations, primary_verdict, tuple(results))


def _imputed(
    design: ModelDesign,
    columns: list[int],
    missing_rows: np.ndarray,
    values: np.ndarray,
    basis: Predictive,
    rng: np.random.Generator,
) -> np.ndarray:
    """One draw of the missing trials' values under MAR: fixed effects drawn from their sampling distribution; given
    them, each participant's random effects drawn from their distribution given the participant's observed trials;
    then a residual. (Drawing the fixed effects alone around fixed BLUPs would move every imputed trial with the
    intercept's between-participant uncertainty, and inflate the pooled interval.)"""
    fixed = rng.multivariate_normal(basis.fixed, basis.fixed_cov, method="eigh")
    exog = design.exog[:, columns]
    size = basis.random_cov.shape[0]
    g, residual_variance = basis.random_cov, basis.residual_sd**2
    imputed = np.full(values.size, np.nan)
    for participant in np.unique(design.groups):
        mine = design.groups == participant
        seen, unseen = mine & ~missing_rows, mine & missing_rows
        if not unseen.any():
            continue
        z_seen, z_unseen = design.exog_re[seen, :size], design.exog_re[unseen, :size]
        v = z_seen @ g @ z_seen.T + residual_variance * np.eye(int(seen.sum()))
        gain = g @ z_seen.T @ np.linalg.inv(v)
        mean = gain @ (values[seen] - exog[seen] @ fixed)
        spread = g - gain @ z_seen @ g
        random = rng.multivariate_normal(mean, (spread + spread.T) / 2.0, method="eigh")
        residuals = rng.normal(0.0, basis.residual_sd, int(unseen.sum()))
        imputed[unseen] = exog[unseen] @ fixed + z_unseen @ random + residuals
    return imputed[missing_rows]


def _columns(trials: Trials) -> tuple[np.ndarray, ...]:
    return (trials.participant, trials.vr, trials.vr_first, trials.factor, trials.path, trials.value)
