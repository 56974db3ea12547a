"""The study's mixed model (statsmodels MixedLM), one per test. Pure logic.

A trial's measure is explained by:
  fixed effects   condition (VR or reality) × the test's two design factors (test 2: speed set and path; test 1:
                  stand-off and path), with every interaction; the period (the participant's first block of trials
                  or second) and the sequence (VR first or reality first);
  random effects  an intercept and a condition slope per participant, by the first of lbfgs, bfgs and powell to
                  converge, started at the REML estimate in closed form in a balanced study (balanced.py); a
                  slope variance on its boundary (near 0) is kept and said. Only when no optimiser
                  converges is the slope left out, and the fit says why: without it, the contrast would be judged
                  against the trials' noise rather than the participants' own differences.

The crossover's terms (CROSSOVER_TERMS): with two conditions in two periods, the period is condition × sequence,
so a period effect (practice, fatigue, growing used to the robot) is estimated within participants beside the
VR − reality contrast and does not bias it. Carry-over cannot be estimated: an unequal carry-over (VR changing the
reality block after it more than reality changes a VR block) is aliased with the sequence term and with
condition × period, and the sequence term is estimated between participants only. Such a carry-over would bias the
contrast, and no model of these trials can take it out: only the design can (a break between the blocks).

Coding, so that the condition's coefficient is the VR − reality contrast averaged over the design's cells:
  condition   +1/2 in VR, −1/2 in reality;
  period      +1/2 in the first block, −1/2 in the second: its coefficient is first − second;
  sequence    +1/2 for participants who did VR first, −1/2 for the others;
  factors     sum-to-zero: a level's column is +1 on its trials, −1 on the last level's, 0 elsewhere.

Intervals use Student's t with (participants − sequences) degrees of freedom, as in the classic two-period
crossover analysis: the contrast is judged against how much the participants' own VR − reality differences vary,
and statsmodels' normal (Wald) intervals are too narrow with a dozen participants. The measure is scaled to unit
variance for the fit (the optimiser reports false boundary solutions on values of a few centimetres) and the
estimates are scaled back.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from sim.study.analysis.balanced import Balance, balance, reml_start
from sim.study.analysis.errors import AnalysisError

__all__ = [
    "CONTRAST",
    "CROSSOVER_TERMS",
    "PERIOD",
    "SEQUENCE",
    "Coefficient",
    "ModelDesign",
    "ModelFit",
    "Predictive",
    "Trials",
    "fit_model",
    "formula",
    "model_design",
]

CONTRAST = "VR − reality"
PERIOD = "period: first − second"
SEQUENCE = "sequence: VR first"
# What the two-period crossover can and cannot tell, for the report and the pre-registration
CROSSOVER_TERMS = (
    "Period (first block − second) is condition × sequence in a two-condition crossover: practice or fatigue is "
    "estimated within participants, beside the VR − reality contrast, and does not bias it.",
    "Carry-over cannot be estimated: an unequal carry-over between the conditions is aliased with the sequence "
    "term (estimated between participants only) and with condition × period. It would bias the contrast, and only "
    "the design guards against it (a break between the blocks).",
)
_INTERCEPT_ONLY = "an intercept per participant"
_WITH_SLOPE = "an intercept and a condition slope per participant"
_OPTIMISERS = ("lbfgs", "bfgs", "powell")
# statsmodels' words for an attempt that failed, which the next optimiser may mend: not about the fit kept
_ATTEMPT_WARNINGS = {
    "Maximum Likelihood optimization failed to converge. Check mle_retvals",
    "MixedLM optimization failed, trying a different optimizer may help.",
}


@dataclass(frozen=True)
class Trials:
    """One row per trial: the model's data. Arrays of one length."""

    participant: np.ndarray  # int
    vr: np.ndarray  # bool: the trial was in VR
    vr_first: np.ndarray  # bool: its participant did VR first
    factor: np.ndarray  # str: test 2's speed set, test 1's stand-off
    path: np.ndarray  # str
    value: np.ndarray  # float: the measure (NaN in a layout the model is built on before any data)


@dataclass(frozen=True)
class ModelDesign:
    """The fixed and random effects' matrices of a set of trials; refitted with other values of the same layout
    (sim.study.power.sample_size)."""

    names: tuple[str, ...]  # the fixed effects', in exog's column order
    exog: np.ndarray
    exog_re: np.ndarray  # intercept and condition
    groups: np.ndarray
    participants: int
    sequences: int  # with participants in them: 1 or 2
    left_out: tuple[str, ...]  # terms the data cannot estimate (an empty cell), left out of exog
    balance: Balance | None = field(default=None, compare=False, repr=False)  # where the fit starts (balanced.py)

    @property
    def df(self) -> int:
        return self.participants - self.sequences


@dataclass(frozen=True)
class Coefficient:
    name: str
    estimate: float
    se: float
    ci_low: float  # 95 %
    ci_high: float


@dataclass(frozen=True)
class Predictive:
    """What imputing a missing trial needs of a fit (sim.study.analysis.missing), in the measure's units: the fixed
    effects (in the design's column order) with their covariance, the random effects' covariance (the intercept's
    and, with the slope, the condition slope's) and the residual SD."""

    fixed: np.ndarray
    fixed_cov: np.ndarray
    random_cov: np.ndarray  # 1×1 or 2×2, as exog_re's first columns
    residual_sd: float


@dataclass(frozen=True)
class ModelFit:
    coefficients: tuple[Coefficient, ...]
    contrast: Coefficient  # the condition's coefficient: VR − reality, averaged over the cells
    df: int
    random_effects: str  # what was fitted
    variances: dict[str, float]  # the random effects' and the residual's, in the measure's units squared
    participants: int
    trials: int
    notes: tuple[str, ...]  # a random slope that did not converge, terms left out
    predictive: Predictive | None = field(default=None, compare=False, repr=False)

    @property
    def with_slope(self) -> bool:
        """The random condition slope was fitted (not left out for want of convergence)."""
        return self.random_effects == _WITH_SLOPE


def formula(measure: str, factor_name: str) -> str:
    """The model of a test's measure, as the report and the pre-registration write it."""
    return f"{measure} ~ condition × {factor_name} × path + period + sequence"


def _sum_coded(labels: np.ndarray, name: str) -> list[tuple[str, np.ndarray]]:
    levels = sorted(set(labels.tolist()))
    last = labels == levels[-1]
    return [(f"{name}[{level}]", (labels == level).astype(float) - last) for level in levels[:-1]]


def _products(a: Sequence[tuple[str, np.ndarray]], b: Sequence[tuple[str, np.ndarray]]) -> list[tuple[str, np.ndarray]]:
    return [(f"{name_a} × {name_b}", col_a * col_b) for name_a, col_a in a for name_b, col_b in b]


def _check(trials: Trials) -> None:
    size = trials.value.shape[0]
    arrays = (trials.participant, trials.vr, trials.vr_first, trials.factor, trials.path, trials.value)
    if any(np.asarray(array).shape != (size,) for array in arrays):
        raise AnalysisError("the model's columns must be 1-D arrays of one length")
    for participant in np.unique(trials.participant):
        mine = trials.participant == participant
        if len(set(trials.vr[mine].tolist())) < 2:
            raise AnalysisError(f"participant {participant} has trials in one condition only")
        if len(set(trials.vr_first[mine].tolist())) > 1:
            raise AnalysisError(f"participant {participant} is marked both VR first and VR second")


def model_design(trials: Trials, factor_name: str) -> ModelDesign:
    """The fixed effects (see the module's doc) and random effects of `trials`; AnalysisError if they cannot be
    fitted."""
    _check(trials)
    participants = len(np.unique(trials.participant))
    if participants < 3:
        raise AnalysisError(f"a mixed model needs at least 3 participants, got {participants}")
    condition = [(CONTRAST, np.where(trials.vr, 0.5, -0.5))]
    factor = _sum_coded(np.asarray(trials.factor), factor_name)
    path = _sum_coded(np.asarray(trials.path), "path")
    columns = [("intercept", np.ones(trials.value.shape[0]))] + condition + factor + path
    columns += _products(condition, factor) + _products(condition, path)
    factor_path = _products(factor, path)
    columns += factor_path + _products(condition, factor_path)
    sequences = len(set(trials.vr_first.tolist()))
    if sequences == 2:  # with one sequence only, the sequence is the intercept and the period the condition
        first_block = trials.vr == trials.vr_first
        columns += [(PERIOD, np.where(first_block, 0.5, -0.5)), (SEQUENCE, np.where(trials.vr_first, 0.5, -0.5))]
    if participants - sequences < 2:
        raise AnalysisError(f"{participants} participants in {sequences} sequences leave too few to compare")
    kept: list[tuple[str, np.ndarray]] = []
    left_out = []
    for name, column in columns:  # terms of cells without data add nothing the others do not
        candidate = np.column_stack([c for _, c in kept] + [column])
        if np.linalg.matrix_rank(candidate) == len(kept) + 1:
            kept.append((name, column))
        else:
            left_out.append(name)
    if CONTRAST in left_out:
        raise AnalysisError("the condition cannot be estimated from these trials")
    return ModelDesign(
        names=tuple(name for name, _ in kept),
        exog=np.column_stack([column for _, column in kept]),
        exog_re=np.column_stack([np.ones(trials.value.shape[0]), condition[0][1]]),
        groups=np.asarray(trials.participant),
        participants=participants,
        sequences=sequences,
        left_out=tuple(left_out),
        balance=balance(
            trials.participant, trials.vr, trials.vr_first, [f"{f}|{p}" for f, p in zip(trials.factor, trials.path)]
        ),
    )


def _mixedlm(design: ModelDesign, values: np.ndarray, slope: bool) -> tuple[Any, bool, list[str]]:
    """(fit, converged, what was said): the first of the optimisers to converge, with the warnings about its fit;
    else the last attempt (None if every one raised) and why none converged. lbfgs is fastest and fails on a few
    percent of small studies, where bfgs or powell converge: dropping the slope there instead makes the contrast's
    interval too narrow (42 % of such studies came out "different" with no difference put in)."""
    from statsmodels.regression.mixed_linear_model import MixedLM, MixedLMParams

    exog_re = design.exog_re if slope else design.exog_re[:, :1]
    at = reml_start(design.balance, values) if slope and design.balance is not None else None
    start = None if at is None else MixedLMParams.from_components(np.zeros(design.exog.shape[1]), cov_re=at)
    result, failures = None, []
    for method in _OPTIMISERS:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                model = MixedLM(values, design.exog, design.groups, exog_re=exog_re)
                attempt = model.fit(start_params=start, reml=True, method=[method])
            except (np.linalg.LinAlgError, ValueError) as error:  # a random effect with no variance at all
                failures.append(f"{method}: {type(error).__name__}: {error}")
                continue
        result = attempt
        if attempt.converged and np.all(np.isfinite(attempt.bse_fe)):
            about_the_fit = {str(w.message).split("\n")[0] for w in caught} - _ATTEMPT_WARNINGS
            return attempt, True, sorted(about_the_fit)
        failures.append(f"{method} did not converge")
    return result, False, failures


def fit_model(design: ModelDesign, values: np.ndarray) -> ModelFit:
    """REML fit of `values` (one per row of `design`)."""
    values = np.asarray(values, dtype=float)
    if values.shape != (design.exog.shape[0],) or not np.all(np.isfinite(values)):
        raise AnalysisError(f"the model needs {design.exog.shape[0]} finite values, got shape {values.shape}")
    unit = float(np.std(values)) or 1.0
    notes = [f"left out, as no trial informs them: {', '.join(design.left_out)}"] if design.left_out else []
    result, converged, said = _mixedlm(design, values / unit, slope=True)
    random_effects = _WITH_SLOPE
    if not converged:
        simpler, simpler_converged, simpler_said = _mixedlm(design, values / unit, slope=False)
        if simpler_converged:
            notes.append(
                f"the random condition slope did not converge ({'; '.join(said)}): fitted without it, so the "
                f"{CONTRAST} interval may be too narrow"
            )
            result, random_effects, said = simpler, _INTERCEPT_ONLY, simpler_said
        elif result is None and simpler is None:
            raise AnalysisError(f"the mixed model cannot be fitted: {'; '.join(said + simpler_said)}")
        else:  # neither converged: the last attempt is what can be had
            if result is None:
                result, random_effects = simpler, _INTERCEPT_ONLY
            notes.append(f"no fit converged, with or without the random slope ({'; '.join(said + simpler_said)})")
            said = []
    if said:
        notes.append(f"the fit with {random_effects}: {'; '.join(said)}")
    estimates = np.asarray(result.fe_params) * unit
    errors = np.asarray(result.bse_fe) * unit
    half = float(stats.t.ppf(0.975, design.df)) * errors
    coefficients = tuple(
        Coefficient(name, float(e), float(s), float(e - h), float(e + h))
        for name, e, s, h in zip(design.names, estimates, errors, half)
    )
    cov_re = np.atleast_2d(np.asarray(result.cov_re)) * unit**2
    variances = {"participant intercept": float(cov_re[0, 0])}
    if random_effects == _WITH_SLOPE:
        variances["participant condition slope"] = float(cov_re[1, 1])
    variances["residual"] = float(result.scale) * unit**2
    predictive = Predictive(
        fixed=estimates,
        fixed_cov=np.asarray(result.cov_params())[: len(design.names), : len(design.names)] * unit**2,
        random_cov=cov_re,
        residual_sd=float(np.sqrt(result.scale)) * unit,
    )
    return ModelFit(
        coefficients=coefficients,
        contrast=coefficients[design.names.index(CONTRAST)],
        df=design.df,
        random_effects=random_effects,
        variances=variances,
        participants=design.participants,
        trials=int(values.shape[0]),
        notes=tuple(notes),
        predictive=predictive,
    )
