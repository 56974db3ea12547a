"""sim.study.participants.model: traits are reproducible and spread as the population says; judgements and presses
carry the known VR − reality differences; a whole study drawn at once has the same truths; the press lands where
the participant means it to; the preference follows the ranking."""

from __future__ import annotations

import numpy as np
import pytest

from sim.study.design.paths import PATH_NAMES
from sim.study.errors import StudyError
from sim.study.participants.model import (
    MIN_COMFORT,
    Population,
    arrival_time,
    comfort_at_press,
    draw_traits,
    perceived_distance,
    preferred_path,
    study_measures,
)

POPULATION = Population()


def test_traits_are_reproducible_per_participant_and_seed_and_spread_as_the_population_says():
    assert draw_traits(POPULATION, 3, 7) == draw_traits(POPULATION, 3, 7)
    traits = [draw_traits(POPULATION, p, 7) for p in range(1, 401)]
    comfort = np.array([t.comfort_distance["reality"] for t in traits])
    comfort_shift = np.array([t.comfort_distance["vr"] for t in traits]) - comfort
    ratio_shift = np.array([t.distance_ratio["vr"] - t.distance_ratio["reality"] for t in traits])
    assert np.mean(comfort) == pytest.approx(POPULATION.comfort_mean, abs=0.005)
    assert np.std(comfort) == pytest.approx(POPULATION.comfort_sd, rel=0.15)
    assert np.mean(comfort_shift) == pytest.approx(POPULATION.vr_comfort_shift, abs=0.004)
    assert np.std(comfort_shift) == pytest.approx(POPULATION.comfort_shift_sd, rel=0.15)
    assert np.mean(ratio_shift) == pytest.approx(POPULATION.vr_distance_shift, abs=0.01)
    assert np.std(ratio_shift) == pytest.approx(POPULATION.distance_shift_sd, rel=0.15)
    assert len({t.ranking for t in traits[:20]}) > 10
    assert sorted(traits[0].ranking) == sorted(PATH_NAMES)


def test_judgements_and_presses_scatter_around_the_participants_own_means():
    traits = draw_traits(POPULATION, 1, 0)
    rng = np.random.default_rng(0)
    for condition in ("vr", "reality"):
        ratios = np.array([perceived_distance(traits, condition, 0.2, rng) for _ in range(4000)]) / 0.2
        assert np.mean(ratios) == pytest.approx(traits.distance_ratio[condition], rel=0.005)
        assert np.std(np.log(ratios)) == pytest.approx(POPULATION.perception_noise, rel=0.05)
        presses = np.array([comfort_at_press(traits, condition, rng) for _ in range(4000)])
        assert np.mean(presses) == pytest.approx(traits.comfort_distance[condition], abs=0.001)
        assert np.std(presses) == pytest.approx(POPULATION.comfort_noise, rel=0.05)
        assert presses.min() >= MIN_COMFORT


def test_a_whole_study_drawn_at_once_has_the_populations_vr_minus_reality_differences():
    participants, per_condition = 4000, 3
    participant = np.repeat(np.arange(participants), 2 * per_condition)
    vr = np.tile(np.repeat([True, False], per_condition), participants)
    rng = np.random.default_rng(3)
    for test, shift, spread in (
        (1, POPULATION.vr_distance_shift, POPULATION.distance_shift_sd),
        (2, POPULATION.vr_comfort_shift, POPULATION.comfort_shift_sd),
    ):
        values = study_measures(POPULATION, test, participant, vr, rng).reshape(participants, 2, per_condition)
        differences = values[:, 0].mean(axis=1) - values[:, 1].mean(axis=1)
        assert np.mean(differences) == pytest.approx(shift, abs=3 * spread / np.sqrt(participants) + 0.001)
        assert np.std(differences) > spread  # the trials' own noise on top of the participants' differences
    with pytest.raises(StudyError, match="test must be 1 or 2"):
        study_measures(POPULATION, 3, participant, vr, rng)


def test_the_arrival_time_is_interpolated_where_the_approach_first_comes_within_the_distance():
    times = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    distances = np.array([0.30, 0.20, 0.10, 0.15, 0.05])  # in, out again, in
    assert arrival_time(times, distances, 0.15) == pytest.approx(0.15)
    assert arrival_time(times, distances, 0.5) == 0.0
    with pytest.raises(StudyError, match="never comes within 0.010 m"):
        arrival_time(times, distances, 0.01)


def test_the_preference_follows_the_ranking():
    traits = draw_traits(POPULATION, 2, 0)
    group = ["straight", "lateral_arc", "over_the_top"]
    assert preferred_path(traits, group) == next(path for path in traits.ranking if path in group)


def test_bad_inputs_are_named():
    traits = draw_traits(POPULATION, 1, 0)
    with pytest.raises(StudyError, match="unknown condition 'ar'"):
        perceived_distance(traits, "ar", 0.1, np.random.default_rng(0))
    with pytest.raises(StudyError, match="unknown condition 'ar'"):
        comfort_at_press(traits, "ar", np.random.default_rng(0))
    with pytest.raises(StudyError, match="cannot rank paths"):
        preferred_path(traits, ["zigzag"])
    with pytest.raises(StudyError, match="participant must be >= 1"):
        draw_traits(POPULATION, 0, 0)
    with pytest.raises(StudyError, match="spreads must be >= 0: comfort_noise -0.01"):
        Population(comfort_noise=-0.01)
    with pytest.raises(StudyError, match="VR comfort shift must be within"):
        Population(vr_comfort_shift=0.5)
