"""sim.study.participants.model: traits are reproducible and spread as the population says; judgements and presses
carry the known VR − reality differences; a whole study drawn at once has the same truths; the press lands where
the participant means it to; the preference follows the ranking; the questionnaires' answers have the levels put
in; the withdrawals' truths come out as put in, and a late one is measured whole (the tracked body's own tests are
test_body's)."""

from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np
import pytest

from sim.study.design.paths import PATH_NAMES
from sim.study.design.scene import load_scene
from sim.study.errors import StudyError
from sim.study.motion.measures import Track, Window, motion_measures
from sim.study.participants.body import (
    TRACKING_JITTER,
    body_layout,
    body_poses,
    withdrawal_peak_speed,
)
from sim.study.participants.cli import add_population_options, population_from_args
from sim.study.participants.errors import ParticipantError
from sim.study.participants.model import (
    INPUT_DELAY_MAX_S,
    KNOWN_TRUTHS,
    LATE_WITHDRAWAL_DELAY,
    MIN_COMFORT,
    SLOW_WITHDRAWAL_DURATION,
    WITHDRAWAL_DURATION,
    Population,
    WithdrawalTiming,
    arrival_time,
    comfort_at_press,
    draw_traits,
    input_delay,
    perceived_distance,
    preferred_path,
    questionnaire_answer,
    study_measures,
    trial_withdrawal,
    trial_withdrawal_timing,
)
from sim.study.questionnaires.instruments import standard_instrument
from sim.study.questionnaires.scoring import scores

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


# --- questionnaires ------------------------------------------------------------------------------------------------

SSQ, IPQ = standard_instrument("ssq"), standard_instrument("ipq")


def answered(traits, instrument, been_in_vr: bool, rng) -> dict:
    return {
        item.id: questionnaire_answer(traits, instrument.name, item.low, item.high, item.reversed, been_in_vr, rng)
        for item in instrument.items
    }


def test_the_questionnaires_answers_have_the_levels_put_in():
    """Over many simulated participants the scores come out as declared: the SSQ total's mean before VR is
    3.74 x 21 x ssq_level, its rise 3.74 x 21 x vr_ssq_rise; every IPQ subscale's mean is ipq_level; a lab item's
    mean answer lies item_level of the way up its scale."""
    population = Population(ssq_level=0.3, vr_ssq_rise=0.4, ipq_level=4.2, item_level=0.25)
    rng = np.random.default_rng(5)
    before, after, presence, safety = [], [], [], []
    for participant in range(1, 2001):
        traits = draw_traits(population, participant, 9)
        before.append(scores(SSQ, answered(traits, SSQ, False, rng))["total"])
        after.append(scores(SSQ, answered(traits, SSQ, True, rng))["total"])
        presence.append(list(scores(IPQ, answered(traits, IPQ, True, rng)).values()))
        safety.append(questionnaire_answer(traits, "perceived_safety", 1, 7, False, True, rng))
    assert np.mean(before) == pytest.approx(3.74 * 21 * 0.3, rel=0.04)
    assert np.mean(np.array(after) - before) == pytest.approx(3.74 * 21 * 0.4, rel=0.04)
    assert np.mean(presence, axis=0) == pytest.approx([4.2] * 4, abs=0.06)
    assert np.mean(safety) == pytest.approx(1 + 0.25 * 6, abs=0.05)
    assert np.std(after) > 10  # participants differ in their susceptibility, not only their answers' noise


def test_a_reversed_item_is_answered_mirrored_and_every_answer_is_on_its_scale():
    traits = draw_traits(Population(ipq_level=5.5), 2, 3)
    straight = [questionnaire_answer(traits, "ipq", 0, 6, False, True, np.random.default_rng(k)) for k in range(50)]
    mirrored = [questionnaire_answer(traits, "ipq", 0, 6, True, True, np.random.default_rng(k)) for k in range(50)]
    assert [6 - answer for answer in straight] == mirrored and np.mean(straight) > 4
    for been_in_vr in (False, True):
        answers = answered(traits, SSQ, been_in_vr, np.random.default_rng(1))
        assert all(0 <= answer <= 3 and isinstance(answer, int) for answer in answers.values())
    with pytest.raises(ParticipantError, match="lowest < highest, got 3..3"):
        questionnaire_answer(traits, "ssq", 3, 3, False, True, np.random.default_rng(1))


def test_the_questionnaire_truths_leave_the_trials_traits_as_they_were():
    plain = draw_traits(POPULATION, 4, 2)
    other = draw_traits(Population(ssq_level=1.0, vr_ssq_rise=1.5, ipq_level=1.0, item_level=0.9), 4, 2)
    assert replace(other, symptoms=plain.symptoms, presence=plain.presence, item_level=plain.item_level) == plain
    assert other.symptoms["after_vr"] > plain.symptoms["after_vr"] and other.presence < plain.presence
    assert {"ssq_level", "vr_ssq_rise", "ipq_level", "item_level"} <= set(KNOWN_TRUTHS)


@pytest.mark.parametrize(
    "truths, said",
    [
        ({"ssq_level": -0.1}, "SSQ level before VR"),
        ({"ssq_level": 2.0, "vr_ssq_rise": 1.5}, "must be within 0..3"),
        ({"ipq_level": 6.0}, "IPQ level must be inside 0..6, got 6.0"),
        ({"item_level": 0.0}, "items' level must be inside 0..1"),
        ({"symptom_spread": 0.0}, "symptom spread"),
    ],
)
def test_impossible_questionnaire_truths_are_named(truths, said):
    with pytest.raises(ParticipantError, match=said):
        Population(**truths)


def test_a_modelled_input_delay_spans_what_the_conditions_page_reports() -> None:
    rng = np.random.default_rng(3)
    for condition, frame in INPUT_DELAY_MAX_S.items():
        delays = np.array([input_delay(condition, rng) for _ in range(2000)])
        assert delays.min() >= 0 and delays.max() <= frame and delays.mean() == pytest.approx(frame / 2, rel=0.05)
    with pytest.raises(StudyError, match="'lab'"):
        input_delay("lab", rng)


SCENE = load_scene()
LAYOUT = body_layout(SCENE)


def test_the_withdrawal_truths_come_out_as_put_in_per_participant_and_per_trial() -> None:
    population = Population(withdrawal_mean=0.04, vr_withdrawal_shift=-0.015, withdrawal_shift_sd=0.006)
    traits = [draw_traits(population, p, 11) for p in range(1, 1601)]
    reality = np.array([t.withdrawal["reality"] for t in traits])
    shift = np.array([t.withdrawal["vr"] for t in traits]) - reality
    assert np.mean(reality) == pytest.approx(0.04, abs=0.0006)
    assert np.std(reality) == pytest.approx(population.withdrawal_sd, rel=0.1)
    assert np.mean(shift) == pytest.approx(-0.015, abs=0.0005)
    assert np.std(shift) == pytest.approx(0.006, rel=0.1)
    rng = np.random.default_rng(2)
    one = traits[0]
    for condition in ("vr", "reality"):
        trials = np.array([trial_withdrawal(one, condition, rng) for _ in range(4000)])
        assert np.mean(trials) == pytest.approx(one.withdrawal[condition], abs=0.0003)
        assert np.std(trials) == pytest.approx(population.withdrawal_noise, rel=0.05) and trials.min() >= 0.0
    with pytest.raises(StudyError, match="unknown condition 'ar'"):
        trial_withdrawal(one, "ar", rng)


def test_the_withdrawal_truths_leave_every_other_draw_as_it_was() -> None:
    plain = draw_traits(POPULATION, 4, 2)
    other = draw_traits(Population(withdrawal_mean=0.08, withdrawal_sd=0.02, vr_withdrawal_shift=0.01), 4, 2)
    assert replace(other, withdrawal=plain.withdrawal) == plain
    assert other.withdrawal["reality"] > plain.withdrawal["reality"]
    # the trials' traits are still the first draws of the traits' stream, as before the withdrawal
    drawn = POPULATION.draws(np.random.default_rng([2, 4, 1]), 1)
    assert plain.comfort_distance == {"vr": drawn["comfort_vr"][0], "reality": drawn["comfort_reality"][0]}
    assert plain.distance_ratio == {"vr": drawn["ratio_vr"][0], "reality": drawn["ratio_reality"][0]}


def test_the_withdrawal_truths_are_command_line_options() -> None:
    assert {"withdrawal_mean", "vr_withdrawal_shift", "withdrawal_shift_sd"} <= set(KNOWN_TRUTHS)
    parser = argparse.ArgumentParser()
    add_population_options(parser)
    args = parser.parse_args(["--withdrawal-mean", "0.05", "--vr-withdrawal-shift=-0.02", "--withdrawal-shift-sd", "0"])
    population = population_from_args(args)
    assert (population.withdrawal_mean, population.vr_withdrawal_shift, population.withdrawal_shift_sd) == (
        0.05,
        -0.02,
        0.0,
    )
    assert population_from_args(parser.parse_args([])) == POPULATION


@pytest.mark.parametrize(
    "truths, said",
    [
        ({"withdrawal_sd": -0.001}, "spreads must be >= 0: withdrawal_sd -0.001"),
        ({"withdrawal_noise": math.nan}, "spreads must be >= 0: withdrawal_noise nan"),
        ({"withdrawal_mean": 0.01, "vr_withdrawal_shift": -0.02}, "withdrawal in reality .* must be within 0..0.3 m"),
        ({"withdrawal_mean": 0.5}, "withdrawal in reality"),
        ({"vr_withdrawal_shift": math.inf}, "withdrawal in reality"),
    ],
)
def test_impossible_withdrawal_truths_are_named(truths, said) -> None:
    with pytest.raises(ParticipantError, match=said):
        Population(**truths)


def test_a_share_of_the_withdrawals_is_late_and_slow_as_put_in() -> None:
    rng = np.random.default_rng(6)
    one = draw_traits(Population(late_withdrawal_share=0.3), 2, 5)
    timings = [trial_withdrawal_timing(one, rng) for _ in range(4000)]
    late = [t for t in timings if t.delay > 0]
    assert len(late) / len(timings) == pytest.approx(0.3, abs=0.03)
    assert set(late) == {WithdrawalTiming(LATE_WITHDRAWAL_DELAY, SLOW_WITHDRAWAL_DURATION)}
    assert {t for t in timings if t.delay == 0} == {WithdrawalTiming(0.0, WITHDRAWAL_DURATION)}
    assert all(trial_withdrawal_timing(replace(one, late_withdrawal_share=0.0), rng).delay == 0 for _ in range(50))
    with pytest.raises(ParticipantError, match="late withdrawals' share"):
        Population(late_withdrawal_share=1.5)


def test_a_simulated_late_withdrawal_is_measured_whole() -> None:
    """The hand pulls back late and slowly, after the robot has come to rest (0.9 s after the press) and beyond the
    0.5 s the approach's window used to end after: the motion measure follows it until the hand rests again, and
    reads the distance put in (the move runs toward the seat, across the direction to the end effector above)."""
    press, rest, distance, rate = 12.0, 12.9, 0.03, 72.0
    late = WithdrawalTiming(LATE_WITHDRAWAL_DELAY, SLOW_WITHDRAWAL_DURATION)
    assert press + late.delay > rest + 0.5
    jitter = np.random.default_rng(4)
    times = 10.0 + np.arange(int(8.0 * rate)) / rate
    hand = [body_poses(LAYOUT, t, distance, press, jitter, late)["right_hand"][0] for t in times]
    head = [body_poses(LAYOUT, t)["head"][0] for t in times]
    tracks = {"right_hand": Track(times, np.array(hand)), "head": Track(times, np.array(head))}
    end_effector = SCENE.hand.top + np.array([-0.1, 0.0, 0.15])
    measured = motion_measures(tracks, Window(10.5, rest, press), SCENE.hand.top, end_effector, 0.1)
    assert measured.tracked_hand == "right_hand"
    assert measured.withdrawal_distance == pytest.approx(distance, abs=6 * TRACKING_JITTER)
    # its peak, and the jitter read over SPEED_SPAN (0.1 mm a pose: some 5 mm/s, 10 at most)
    peak = withdrawal_peak_speed(distance, SLOW_WITHDRAWAL_DURATION)
    assert 0.98 * peak <= measured.withdrawal_peak_speed <= peak + 0.01
