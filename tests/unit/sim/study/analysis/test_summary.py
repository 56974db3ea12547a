"""sim.study.analysis.summary on records whose truth is known: the biases put in come out, within their intervals."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from sim.study.analysis.summary import summarise
from sim.study.errors import StudyError
from sim.study.participants.model import Population, comfort_at_press, draw_traits, perceived_distance
from sim.study.run.records import TrialRecord

STANDOFFS = (0.05, 0.10, 0.15, 0.20, 0.25)
SPEED_SETS = (("slow", 0.1), ("medium", 0.2), ("fast", 0.3))
PATHS = ("straight", "lateral_arc", "over_the_top")


def session(participant: int, population: Population, seed: int = 5) -> list[TrialRecord]:
    """What a participant of `population` would give, straight from the model (no robot): test 1 at every
    stand-off, test 2 pressed at the trial's comfort distance (the robot then brakes 1 cm). Odd participants start
    with VR."""
    traits = draw_traits(population, participant, seed)
    rng = np.random.default_rng([seed, participant])
    rows = []
    order = ("vr", "reality") if participant % 2 else ("reality", "vr")
    for position, condition in enumerate(order, start=1):
        for standoff in STANDOFFS:
            rows.append(
                TrialRecord(
                    participant,
                    len(rows) + 1,
                    condition,
                    position,
                    1,
                    "straight",
                    standoff,
                    0.15,
                    "",
                    0,
                    0.0,
                    False,
                    math.nan,
                    "",
                    0.0,
                    math.nan,
                    standoff,
                    math.nan,
                    0.0,
                    perceived_distance(traits, condition, standoff, rng),
                    "",
                )
            )
        for group, (name, speed) in enumerate(SPEED_SETS, start=1):
            preferred = min(PATHS, key=traits.ranking.index)
            for path in PATHS:
                at_press = comfort_at_press(traits, condition, rng)
                rows.append(
                    TrialRecord(
                        participant,
                        len(rows) + 1,
                        condition,
                        position,
                        2,
                        path,
                        0.02,
                        speed,
                        name,
                        group,
                        0.0,
                        True,
                        2.0,
                        "button",
                        0.0,
                        at_press,
                        at_press - 0.01,
                        at_press + 0.0005,
                        0.01,
                        math.nan,
                        preferred,
                    )
                )
    return rows


def study(participants: int = 12, population: Population | None = None) -> list[TrialRecord]:
    population = population if population is not None else Population()
    return [row for number in range(1, participants + 1) for row in session(number, population)]


def test_a_15_percent_underestimate_in_vr_is_recovered_within_its_interval() -> None:
    summary = summarise(study())
    vr, reality = summary.distance_ratio["vr"], summary.distance_ratio["reality"]
    assert vr.ci_low <= 0.85 <= vr.ci_high and vr.ci_high < 1.0
    assert reality.ci_low <= 1.0 <= reality.ci_high
    paired = summary.distance_ratio_vr_vs_reality
    assert paired.n == 12 and paired.ci_low <= -0.15 <= paired.ci_high and paired.ci_high < 0
    assert paired.t_p < 0.001 and paired.wilcoxon_p < 0.01 and paired.rank_biserial == -1.0


SAME = Population(vr_distance_shift=0.0, distance_shift_sd=0.02, vr_comfort_shift=0.0, comfort_shift_sd=0.005)


def test_no_bias_put_in_gives_an_interval_around_zero() -> None:
    summary = summarise(study(population=SAME))
    paired = summary.distance_ratio_vr_vs_reality
    assert paired.ci_low <= 0.0 <= paired.ci_high


def test_comfort_distances_are_closer_in_vr_by_the_shift_put_in() -> None:
    summary = summarise(study())
    shift, spread = Population().vr_comfort_shift, Population().comfort_shift_sd / math.sqrt(12)
    assert summary.stop_distance_vr_vs_reality.mean_difference == pytest.approx(shift, abs=2.5 * spread)
    assert list(summary.stop_distance_by_speed_set) == ["slow", "medium", "fast"]  # in the order of their speed
    for comparison in [*summary.stop_distance_by_speed_set.values(), *summary.stop_distance_by_path.values()]:
        assert comparison.mean_difference == pytest.approx(shift, abs=3 * spread)
    assert summary.extrapolation_error.mean == pytest.approx(0.0005)


def test_with_the_designs_sesoi_each_test_gets_its_mixed_model_and_verdict() -> None:
    sesoi = {1: 0.05, 2: 0.02}
    biased = summarise(study(), sesoi)
    ratio, press = biased.contrasts[1], biased.contrasts[2]
    assert ratio.verdict.label == "different" and ratio.verdict.ci95[0] <= -0.15 <= ratio.verdict.ci95[1]
    assert ratio.fit.participants == 12 and ratio.fit.trials == 12 * 10 and ratio.fit.df == 10
    assert press.verdict.ci95[0] <= Population().vr_comfort_shift <= press.verdict.ci95[1]
    assert press.verdict.different and not press.verdict.equivalent  # a shift of one whole SESOI
    assert press.tost.n == 12 and not press.tost.equivalent
    assert press.agreement.bias == pytest.approx(press.tost.mean_difference)
    same = summarise(study(population=SAME), sesoi)
    for test in (1, 2):
        assert same.contrasts[test].verdict.label == "equivalent", same.contrasts[test].verdict
        assert same.contrasts[test].tost.equivalent
    assert summarise(study()).contrasts == {}  # without a SESOI, no verdict


def test_too_few_participants_for_a_model_is_said_not_raised() -> None:
    summary = summarise(study(participants=2), {1: 0.05, 2: 0.02})
    assert summary.contrasts == {}
    assert [note for note in summary.notes if "no mixed model or verdict" in note] == [
        "test 1: no mixed model or verdict: a mixed model needs at least 3 participants, got 2",
        "test 2: no mixed model or verdict: a mixed model needs at least 3 participants, got 2",
    ]


def test_preferences_count_one_answer_per_group() -> None:
    records = study(participants=4)
    summary = summarise(records)
    for condition in ("vr", "reality"):
        assert sum(summary.preferences[condition].values()) == 4 * len(SPEED_SETS)
        assert set(summary.preferences[condition]) == set(PATHS)  # paths never preferred are counted as 0


def test_missing_answers_and_unpressed_trials_are_left_out_and_said() -> None:
    records = study(participants=3)
    records[0] = replace(records[0], perceived_distance=math.nan)
    records[7] = replace(records[7], pressed=False, distance_at_press=math.nan)
    summary = summarise(records)
    assert any("1 test 1 trial(s) without a perceived distance" in note for note in summary.notes)
    assert any("1 test 2 trial(s) ended on the hand without a press" in note for note in summary.notes)
    assert math.isfinite(summary.distance_ratio["vr"].mean)


def test_one_participant_is_a_pilot_with_their_means_and_no_comparison() -> None:
    records = study(participants=1)
    pilot = summarise(records, {1: 0.05, 2: 0.02})
    assert pilot.pilot and pilot.participants == (1,) and pilot.trials == len(records)
    for condition in ("vr", "reality"):
        ratios = [
            r.perceived_distance / r.distance_at_rest for r in records if r.test == 1 and r.condition == condition
        ]
        ratio = pilot.distance_ratio[condition]
        assert ratio.n == 1 and ratio.mean == pytest.approx(np.mean(ratios))
        assert math.isnan(ratio.ci_low) and math.isnan(ratio.ci_high)  # no spread across participants
        at_press = [r.distance_at_press for r in records if r.test == 2 and r.condition == condition]
        assert pilot.stop_distance[condition].mean == pytest.approx(np.mean(at_press))
    assert pilot.distance_ratio_vr_vs_reality is None and pilot.stop_distance_vr_vs_reality is None
    assert pilot.stop_distance_by_speed_set == {} and pilot.stop_distance_by_path == {} and pilot.contrasts == {}
    assert pilot.extrapolation_error is not None and pilot.extrapolation_error.mean == pytest.approx(0.0005)
    assert sum(pilot.preferences["vr"].values()) == len(SPEED_SETS)
    # a condition without a value is left out and said
    vr_only = summarise([r for r in records if r.test == 2 or r.condition == "vr"])
    assert set(vr_only.distance_ratio) == {"vr"} and set(vr_only.stop_distance) == {"vr", "reality"}
    assert "test 1 in reality: no trial with a value" in vr_only.notes
    assert not summarise(study(participants=2)).pilot
    with pytest.raises(StudyError, match="no trial records"):
        summarise([])
