"""sim.study.participant_model: traits are reproducible and spread as the population says; judgements carry the
known bias; the press threshold and the preference follow the traits."""

from __future__ import annotations

import numpy as np
import pytest

from sim.study.errors import StudyError
from sim.study.participant_model import (
    Population,
    comfort_threshold,
    draw_traits,
    perceived_distance,
    preferred_path,
)
from sim.study.paths import PATH_NAMES

POPULATION = Population()


def test_traits_are_reproducible_per_participant_and_seed_and_differ_between_participants():
    assert draw_traits(POPULATION, 3, 7) == draw_traits(POPULATION, 3, 7)
    comforts = [draw_traits(POPULATION, p, 7).comfort_distance for p in range(1, 201)]
    assert np.mean(comforts) == pytest.approx(POPULATION.comfort_mean, abs=0.01)
    assert np.std(comforts) == pytest.approx(POPULATION.comfort_sd, rel=0.25)
    assert len({draw_traits(POPULATION, p, 7).ranking for p in range(1, 21)}) > 10
    assert sorted(draw_traits(POPULATION, 1, 0).ranking) == sorted(PATH_NAMES)


def test_judgements_carry_the_conditions_bias():
    traits = draw_traits(POPULATION, 1, 0)
    rng = np.random.default_rng(0)
    vr = [perceived_distance(traits, "vr", 0.2, rng) for _ in range(2000)]
    reality = [perceived_distance(traits, "reality", 0.2, rng) for _ in range(2000)]
    assert np.median(vr) / 0.2 == pytest.approx(0.85, abs=0.01)
    assert np.median(reality) / 0.2 == pytest.approx(1.0, abs=0.01)


def test_the_press_threshold_is_closer_in_vr_and_the_preference_follows_the_ranking():
    traits = draw_traits(POPULATION, 2, 0)
    assert comfort_threshold(traits, "vr") == pytest.approx(max(traits.comfort_distance - 0.02, 0.03))
    assert comfort_threshold(traits, "reality") == traits.comfort_distance
    group = ["straight", "lateral_arc", "over_the_top"]
    assert preferred_path(traits, group) == next(path for path in traits.ranking if path in group)


def test_bad_inputs_are_named():
    traits = draw_traits(POPULATION, 1, 0)
    with pytest.raises(StudyError, match="unknown condition 'ar'"):
        perceived_distance(traits, "ar", 0.1, np.random.default_rng(0))
    with pytest.raises(StudyError, match="cannot rank paths"):
        preferred_path(traits, ["zigzag"])
    with pytest.raises(StudyError, match="participant must be >= 1"):
        draw_traits(POPULATION, 0, 0)
