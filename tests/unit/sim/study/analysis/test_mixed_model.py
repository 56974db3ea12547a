"""sim.study.analysis.mixed_model: on complete data the VR − reality contrast is the classic two-period crossover
analysis's (estimate and standard error); a period effect (the second block unlike the first) is found by the period
term and leaves the contrast alone; a random slope that is not there is
kept on its boundary and said; a cell without data leaves its terms out, by name; data that cannot be modelled is one
clear error."""

from __future__ import annotations

import numpy as np
import pytest

from sim.study.analysis.mixed_model import CONTRAST, PERIOD, SEQUENCE, Trials, fit_model, model_design
from sim.study.errors import StudyError


def crossover(
    participants: int = 10,
    vr_first: int = 4,
    slope_sd: float = 0.02,
    period: float = 0.0,
    seed: int = 5,
    noise: float = 0.01,
) -> Trials:
    """Test 2's shape: 2 speed sets × 3 paths per condition; a participant's VR − reality difference drawn around
    −1 cm; VR 1 cm farther on the fast speed set in reality and VR alike; `period` added to the first block's trials,
    whichever condition it was."""
    rng = np.random.default_rng(seed)
    rows = []
    for p in range(1, participants + 1):
        comfort, difference = rng.normal(0.12, 0.03), rng.normal(-0.01, slope_sd)
        first = p <= vr_first
        for vr in (True, False):
            for speed_set in ("slow", "fast"):
                for path in ("a", "b", "c"):
                    value = comfort + 0.01 * (speed_set == "fast") + rng.normal(0.0, noise)
                    if vr:
                        value += difference
                    if vr == first:  # the participant's first block
                        value += period
                    rows.append((p, vr, first, speed_set, path, value))
    columns = list(zip(*rows))
    return Trials(*(np.array(column) for column in columns))


def participant_differences(trials: Trials) -> dict[int, float]:
    return {
        int(p): float(
            trials.value[(trials.participant == p) & trials.vr].mean()
            - trials.value[(trials.participant == p) & ~trials.vr].mean()
        )
        for p in np.unique(trials.participant)
    }


def test_on_complete_data_the_contrast_is_the_crossover_analysis():
    trials = crossover()
    fit = fit_model(model_design(trials, "speed set"), trials.value)
    d = participant_differences(trials)
    first = [d[p] for p in range(1, 5)]
    second = [d[p] for p in range(5, 11)]
    estimate = (np.mean(first) + np.mean(second)) / 2  # each order group weighs the same
    pooled = ((len(first) - 1) * np.var(first, ddof=1) + (len(second) - 1) * np.var(second, ddof=1)) / 8
    se = 0.5 * np.sqrt(pooled * (1 / len(first) + 1 / len(second)))
    assert fit.contrast.name == CONTRAST
    assert fit.contrast.estimate == pytest.approx(estimate, abs=1e-12)
    assert fit.contrast.se == pytest.approx(se, rel=2e-3)  # REML's optimiser tolerance
    assert fit.df == 8 and fit.participants == 10 and fit.trials == 120
    assert fit.random_effects == "an intercept and a condition slope per participant" and fit.notes == ()
    from scipy import stats

    half = stats.t.ppf(0.975, 8) * fit.contrast.se
    assert (fit.contrast.ci_low, fit.contrast.ci_high) == pytest.approx((estimate - half, estimate + half), abs=1e-12)
    speed = {k.name: k for k in fit.coefficients}["speed set[fast]"]  # sum coding: half the fast − slow gap
    assert speed.estimate == pytest.approx(0.005, abs=0.002)


def test_the_period_term_finds_a_period_effect_and_the_contrast_is_left_alone():
    """A 2×2 crossover's period effect is condition × sequence: fitted as the period, within participants."""
    trials = crossover(participants=20, vr_first=10, period=0.03, slope_sd=0.005)
    fit = fit_model(model_design(trials, "speed set"), trials.value)
    terms = {k.name: k for k in fit.coefficients}
    assert terms[PERIOD].ci_low < 0.03 < terms[PERIOD].ci_high and terms[PERIOD].ci_low > 0  # first − second
    alone = crossover(participants=20, vr_first=10, slope_sd=0.005)  # the same participants, no period effect
    without = fit_model(model_design(alone, "speed set"), alone.value)
    assert fit.contrast.estimate == pytest.approx(without.contrast.estimate, abs=1e-9)
    assert fit.contrast.se == pytest.approx(without.contrast.se, rel=2e-3)
    sequence = terms[SEQUENCE]  # between participants: where an unequal carry-over would hide, none put in
    assert sequence.ci_low < 0.0 < sequence.ci_high


def test_a_random_slope_that_is_not_there_is_kept_on_its_boundary_and_said():
    """Kept, not dropped: a model without the slope would judge the contrast against the trials' noise alone."""
    trials = crossover(slope_sd=0.0, noise=0.01)
    fit = fit_model(model_design(trials, "speed set"), trials.value)
    assert fit.random_effects == "an intercept and a condition slope per participant"
    assert fit.variances["participant condition slope"] < 0.1 * fit.variances["residual"]
    assert any("boundary" in note for note in fit.notes), fit.notes
    assert fit.contrast.ci_low < -0.01 < fit.contrast.ci_high


def test_a_cell_without_data_leaves_its_terms_out_by_name():
    trials = crossover()
    keep = ~((trials.factor == "fast") & (trials.path == "c") & trials.vr)  # no participant did it in VR
    sparse = Trials(
        *(getattr(trials, name)[keep] for name in ("participant", "vr", "vr_first", "factor", "path", "value"))
    )
    design = model_design(sparse, "speed set")
    # 11 cells with data cannot fit condition × speed set × path's 12 columns: the last three-way term goes
    assert design.left_out == (f"{CONTRAST} × speed set[fast] × path[b]",)
    fit = fit_model(design, sparse.value)
    assert fit.notes[0].startswith("left out, as no trial informs them: ")


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda t: t.participant < 3, "at least 3 participants, got 2"),
        (lambda t: ~((t.participant == 2) & ~t.vr), "participant 2 has trials in one condition only"),
    ],
)
def test_data_that_cannot_be_modelled_is_one_clear_error(change, message):
    trials = crossover()
    keep = change(trials)
    chosen = Trials(
        *(getattr(trials, name)[keep] for name in ("participant", "vr", "vr_first", "factor", "path", "value"))
    )
    with pytest.raises(StudyError, match=message):
        model_design(chosen, "speed set")


def test_values_must_fit_the_design():
    trials = crossover()
    design = model_design(trials, "speed set")
    with pytest.raises(StudyError, match="needs 120 finite values"):
        fit_model(design, trials.value[:-1])
    with pytest.raises(StudyError, match="needs 120 finite values"):
        fit_model(design, np.where(np.arange(120) == 3, np.nan, trials.value))
