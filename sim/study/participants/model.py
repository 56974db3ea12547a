"""A simulated participant's behaviour, with known truths so that the analysis can be checked against them. Pure
logic. The simulated participant (a TCP client of the endpoint, like a Unity scene) acts on it one trial at a time,
and `power` draws whole studies from it at once: both through the same functions, so what `power` plans for is
what `simulate` runs.

A Population gives the distributions; each participant's traits are drawn from it once, seeded by
(seed, participant):
  distance perception   test 1's measure, perceived / actual distance: in reality a bias of the participant's own
                        (mean 1: unbiased on average), in VR that bias plus a VR − reality difference of the
                        participant's own (mean `vr_distance_shift`, SD `distance_shift_sd`); each judgement is
                        multiplied by a log-normal factor of mean 1;
  comfort distance      test 2's measure, where the robot is when the press lands: the participant's own in reality,
                        plus a VR − reality difference of their own (mean `vr_comfort_shift`, SD `comfort_shift_sd`);
                        each trial's varies by `comfort_noise`;
  the press             the participant anticipates: knowing the approach, they press so that the press lands when
                        the robot reaches their comfort distance;
  preference            ranks a group's paths by their order in the participant's own ranking of all paths;
  questionnaires        each answer is the item's lowest plus a binomial count of its scale's steps, so that its
                        mean is exactly the level put in, without the bias that rounding and clipping a normal draw
                        would add at the scale's ends:
                        - SSQ: each symptom's mean rating is `ssq_level` (0..3) before the participant has been in
                          VR and `ssq_level + vr_ssq_rise` after, times a susceptibility of the participant's own
                          (gamma, mean 1, CV `symptom_spread`): the SSQ total's mean rises by 3.74 x 21 x rise
                          (21: the symptoms' memberships in the three clusters);
                        - IPQ: each item's score (a reversed item's answer mirrored) has the mean `ipq_level`
                          (0..6), which is then every subscale's; the participant's own level is a beta draw around
                          it (concentration `answer_concentration`);
                        - the lab's own items: the mean answer lies `item_level` of the way from the scale's lowest
                          to its highest answer, the participant's own drawn likewise.
  the input delay        what the page would report for a press, from the first reading that saw it to its stamp:
                        uniform up to INPUT_DELAY_MAX_S (the VR page's within a millisecond of its frame's trigger
                        event, the button page's within one 60 Hz frame after the browser's gamepad poll).
                        It is reported with the press, not added to its stamp: where the press lands stays the
                        comfort distance put in.
  withdrawal            test 2: after the press the hand under the robot withdraws: the participant's own distance in
                        reality (mean `withdrawal_mean`, SD `withdrawal_sd`), plus a VR − reality difference of
                        their own (mean `vr_withdrawal_shift`, SD `withdrawal_shift_sd`); each trial's varies by
                        `withdrawal_noise`; none is below 0. Test 1 has no press: the hand stays. A share of the
                        trials (`late_withdrawal_share`) withdraw late and slowly: LATE_WITHDRAWAL_DELAY after the
                        press, after the robot is at rest, over SLOW_WITHDRAWAL_DURATION; the others at once, over
                        WITHDRAWAL_DURATION.
  Questionnaire traits and answers are drawn from streams of their own: the trials' draws are those of before. So are
  the withdrawal's traits, each trial's withdrawal and the tracking's jitter.

The tracked body these behaviours move (the poses the pose topics carry) is sim.study.participants.body's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.study.design.paths import ON_TOP, PATH_NAMES
from sim.study.participants.errors import ParticipantError
from sim.study.questionnaires.instruments import standard_instrument

__all__ = [
    "MIN_COMFORT",
    "KNOWN_TRUTHS",
    "Population",
    "Traits",
    "draw_traits",
    "judged_ratios",
    "comfort_distances",
    "perceived_distance",
    "comfort_at_press",
    "arrival_time",
    "study_measures",
    "preferred_path",
    "questionnaire_answer",
    "INPUT_DELAY_MAX_S",
    "input_delay",
    "trial_withdrawal",
    "WithdrawalTiming",
    "trial_withdrawal_timing",
    "WITHDRAWAL_DURATION",
    "LATE_WITHDRAWAL_DELAY",
    "SLOW_WITHDRAWAL_DURATION",
]

MIN_COMFORT = ON_TOP + 0.01  # m: a press must land before the approach's end, on top of the hand
MAX_WITHDRAWAL = 0.3  # m: a population's mean withdrawal beyond this is no flinch but leaving the table
# what `participant` and `simulate` take from the command line (--vr-distance-shift ...): the truths to recover
KNOWN_TRUTHS = {
    "vr_distance_shift": "VR - reality of perceived / actual distance, the population's mean",
    "distance_shift_sd": "SD of the participants' own VR - reality differences of perceived / actual",
    "vr_comfort_shift": "VR - reality of the distance at the press (m), the population's mean",
    "comfort_shift_sd": "SD of the participants' own VR - reality differences of the distance at the press (m)",
    "withdrawal_mean": "test 2: how far the hand withdraws after the press in reality (m), the population's mean",
    "vr_withdrawal_shift": "VR - reality of the hand's withdrawal after the press (m), the population's mean",
    "withdrawal_shift_sd": "SD of the participants' own VR - reality differences of the hand's withdrawal (m)",
    "late_withdrawal_share": "the share of test 2 trials (0..1) in which the hand withdraws late and slowly",
    "ssq_level": "SSQ: each symptom's mean rating (0..3) before the participant has been in VR",
    "vr_ssq_rise": "SSQ: how much each symptom's mean rating rises once the participant has been in VR",
    "ipq_level": "IPQ: every subscale's mean score (0..6)",
    "item_level": "the lab's own items: the mean answer, as the fraction of the way from the lowest to the highest",
}


@dataclass(frozen=True)
class Population:
    distance_bias_sd: float = 0.08  # SD of the participants' perceived / actual in reality (mean 1)
    vr_distance_shift: float = -0.15  # VR − reality of perceived / actual: a 15 % underestimate in VR
    distance_shift_sd: float = 0.06  # SD of the participants' own VR − reality differences
    perception_noise: float = 0.05  # log-SD of a single judgement
    comfort_mean: float = 0.12  # m, in reality
    comfort_sd: float = 0.03
    vr_comfort_shift: float = -0.02  # m: closer in VR
    comfort_shift_sd: float = 0.02  # m
    comfort_noise: float = 0.01  # m: one trial's, around the participant's own
    withdrawal_mean: float = 0.03  # m: how far the hand withdraws after the press, in reality
    withdrawal_sd: float = 0.008  # m: SD of the participants' own in reality
    vr_withdrawal_shift: float = -0.01  # m: VR − reality: they withdraw less in VR
    withdrawal_shift_sd: float = 0.005  # m: SD of the participants' own VR − reality differences
    withdrawal_noise: float = 0.004  # m: one trial's, around the participant's own
    # of test 2's trials, those whose withdrawal comes after the robot rests and is slow: the measure must follow it
    late_withdrawal_share: float = 0.25
    ssq_level: float = 0.1  # SSQ: a symptom's mean rating before VR (0..3): total 7.9 on average
    vr_ssq_rise: float = 0.2  # SSQ: a symptom's mean rating after VR, more: total 23.6 on average
    symptom_spread: float = 0.5  # SSQ: the CV of the participants' susceptibility
    ipq_level: float = 3.5  # IPQ: every subscale's mean score (0..6)
    item_level: float = 0.7  # the lab's own items: the mean answer, from lowest (0) to highest (1)
    answer_concentration: float = 10.0  # how closely participants' own IPQ and item levels follow the population's

    def __post_init__(self) -> None:
        spreads = {
            "distance_bias_sd": self.distance_bias_sd,
            "distance_shift_sd": self.distance_shift_sd,
            "perception_noise": self.perception_noise,
            "comfort_sd": self.comfort_sd,
            "comfort_shift_sd": self.comfort_shift_sd,
            "comfort_noise": self.comfort_noise,
            "withdrawal_sd": self.withdrawal_sd,
            "withdrawal_shift_sd": self.withdrawal_shift_sd,
            "withdrawal_noise": self.withdrawal_noise,
        }
        bad = [f"{name} {value!r}" for name, value in spreads.items() if not (math.isfinite(value) and value >= 0.0)]
        if bad:
            raise ParticipantError(f"a population's spreads must be >= 0: {', '.join(bad)}")
        if not (math.isfinite(self.vr_distance_shift) and -0.9 < self.vr_distance_shift < 2.0):
            raise ParticipantError(
                f"the VR distance shift must be > -0.9 and < 2 (of the ratio), got {self.vr_distance_shift}"
            )
        if not (math.isfinite(self.vr_comfort_shift) and abs(self.vr_comfort_shift) < 0.2):
            raise ParticipantError(f"the VR comfort shift must be within ±0.2 m, got {self.vr_comfort_shift}")
        in_vr = self.withdrawal_mean + self.vr_withdrawal_shift
        if not (
            math.isfinite(in_vr) and 0.0 <= self.withdrawal_mean <= MAX_WITHDRAWAL and 0.0 <= in_vr <= MAX_WITHDRAWAL
        ):
            raise ParticipantError(
                f"the withdrawal in reality ({self.withdrawal_mean}) and in VR (+ shift {self.vr_withdrawal_shift}) "
                f"must be within 0..{MAX_WITHDRAWAL} m"
            )
        if not (0.0 <= self.late_withdrawal_share <= 1.0):
            raise ParticipantError(f"the late withdrawals' share must be within 0..1, got {self.late_withdrawal_share}")
        ssq, ipq = _scale("ssq"), _scale("ipq")
        after = self.ssq_level + self.vr_ssq_rise
        if not (math.isfinite(after) and ssq[0] <= self.ssq_level <= ssq[1] and ssq[0] <= after <= ssq[1]):
            raise ParticipantError(
                f"the SSQ level before VR ({self.ssq_level}) and after (+ rise {self.vr_ssq_rise}) must be within "
                f"{ssq[0]}..{ssq[1]}"
            )
        if not (ipq[0] < self.ipq_level < ipq[1]):
            raise ParticipantError(f"the IPQ level must be inside {ipq[0]}..{ipq[1]}, got {self.ipq_level}")
        if not (0.0 < self.item_level < 1.0):
            raise ParticipantError(f"the items' level must be inside 0..1 (of their scale), got {self.item_level}")
        if not (math.isfinite(self.symptom_spread) and self.symptom_spread > 0.0 and self.answer_concentration > 0.0):
            raise ParticipantError(
                f"the symptom spread and the answers' concentration must be > 0, got {self.symptom_spread} and "
                f"{self.answer_concentration}"
            )

    def draws(self, rng: np.random.Generator, participants: int) -> dict[str, np.ndarray]:
        """Each trait for `participants` participants, one array each. Perceived / actual stays above 0.1 and the
        comfort distance above MIN_COMFORT, as people's do."""
        ratio = np.maximum(rng.normal(1.0, self.distance_bias_sd, participants), 0.1)
        ratio_vr = np.maximum(ratio + rng.normal(self.vr_distance_shift, self.distance_shift_sd, participants), 0.1)
        comfort = np.maximum(rng.normal(self.comfort_mean, self.comfort_sd, participants), MIN_COMFORT)
        comfort_vr = comfort + rng.normal(self.vr_comfort_shift, self.comfort_shift_sd, participants)
        return {
            "ratio_reality": ratio,
            "ratio_vr": ratio_vr,
            "comfort_reality": comfort,
            "comfort_vr": np.maximum(comfort_vr, MIN_COMFORT),
        }

    def withdrawal_draws(self, rng: np.random.Generator, participants: int) -> dict[str, np.ndarray]:
        """Each participant's own withdrawal (m) per condition, none below 0. Apart from `draws`, so that adding the
        withdrawal changed none of the other traits' draws."""
        reality = np.maximum(rng.normal(self.withdrawal_mean, self.withdrawal_sd, participants), 0.0)
        vr = reality + rng.normal(self.vr_withdrawal_shift, self.withdrawal_shift_sd, participants)
        return {"withdrawal_reality": reality, "withdrawal_vr": np.maximum(vr, 0.0)}


@dataclass(frozen=True)
class Traits:
    participant: int
    distance_ratio: dict[str, float]  # per condition: perceived / actual, the participant's mean
    perception_noise: float
    comfort_distance: dict[str, float]  # per condition, m: where the robot is at the press, the participant's mean
    comfort_noise: float
    ranking: tuple[str, ...]  # every path, most preferred first
    symptoms: dict[str, float]  # SSQ: a symptom's mean rating, before (False) and after (True) having been in VR
    presence: float  # IPQ: the mean item score as a fraction of the scale (0..1)
    item_level: float  # the lab's own items: the mean answer as a fraction of the scale (0..1)
    withdrawal: dict[str, float]  # per condition, m: how far the hand withdraws after a press, the participant's mean
    withdrawal_noise: float
    late_withdrawal_share: float = 0.0  # of test 2's trials, the share whose withdrawal is late and slow


def _scale(name: str) -> tuple[int, int]:
    """The lowest and highest answer of a standard instrument (each has one scale for all its items)."""
    item = standard_instrument(name).items[0]
    return item.low, item.high


def _beta(rng: np.random.Generator, mean: float, concentration: float) -> float:
    return float(rng.beta(mean * concentration, (1.0 - mean) * concentration))


def draw_traits(population: Population, participant: int, seed: int) -> Traits:
    if participant < 1 or seed < 0:
        raise ParticipantError(f"participant must be >= 1 and seed >= 0, got {participant} and {seed}")
    rng = np.random.default_rng([seed, participant, 1])  # a stream apart from the plan's
    drawn = {name: float(values[0]) for name, values in population.draws(rng, 1).items()}
    ranking = tuple(PATH_NAMES[k] for k in rng.permutation(len(PATH_NAMES)))
    answering = np.random.default_rng([seed, participant, 3])  # apart: the trials' traits are those of before
    shape = 1.0 / population.symptom_spread**2  # a gamma of mean 1 and this CV
    susceptibility = float(answering.gamma(shape, 1.0 / shape))
    low, high = _scale("ipq")
    moving = np.random.default_rng([seed, participant, 6])  # apart, likewise: the withdrawal came later
    withdrawal = {name: float(values[0]) for name, values in population.withdrawal_draws(moving, 1).items()}
    return Traits(
        participant,
        {"vr": drawn["ratio_vr"], "reality": drawn["ratio_reality"]},
        population.perception_noise,
        {"vr": drawn["comfort_vr"], "reality": drawn["comfort_reality"]},
        population.comfort_noise,
        ranking,
        {
            "before_vr": susceptibility * population.ssq_level,
            "after_vr": susceptibility * (population.ssq_level + population.vr_ssq_rise),
        },
        _beta(answering, (population.ipq_level - low) / (high - low), population.answer_concentration),
        _beta(answering, population.item_level, population.answer_concentration),
        {"vr": withdrawal["withdrawal_vr"], "reality": withdrawal["withdrawal_reality"]},
        population.withdrawal_noise,
        population.late_withdrawal_share,
    )


def judged_ratios(ratio: np.ndarray, noise: float, rng: np.random.Generator) -> np.ndarray:
    """Perceived / actual of single judgements around each participant's `ratio` (log-normal, mean 1)."""
    return ratio * np.exp(rng.normal(-(noise**2) / 2.0, noise, np.shape(ratio)))


def comfort_distances(comfort: np.ndarray, noise: float, rng: np.random.Generator) -> np.ndarray:
    """Single trials' comfort distances (m) around each participant's `comfort`."""
    return np.maximum(comfort + rng.normal(0.0, noise, np.shape(comfort)), MIN_COMFORT)


def _condition(traits: Traits, condition: str) -> None:
    if condition not in traits.distance_ratio:
        raise ParticipantError(f"unknown condition {condition!r}; known: {', '.join(traits.distance_ratio)}")


def perceived_distance(traits: Traits, condition: str, actual: float, rng: np.random.Generator) -> float:
    """What the participant shows for an actual distance (m)."""
    _condition(traits, condition)
    if not (math.isfinite(actual) and actual >= 0.0):
        raise ParticipantError(f"an actual distance must be >= 0 m, got {actual!r}")
    ratio = judged_ratios(np.array([traits.distance_ratio[condition]]), traits.perception_noise, rng)
    return float(actual * ratio[0])


def comfort_at_press(traits: Traits, condition: str, rng: np.random.Generator) -> float:
    """Where (m from the hand) this trial's press is to land."""
    _condition(traits, condition)
    return float(comfort_distances(np.array([traits.comfort_distance[condition]]), traits.comfort_noise, rng)[0])


# s, one frame of the page that reads the participant's input, by condition (see the module's docstring)
# s: the longest input delay each page reports (sim.study.views.vr's presses.js: from the first reading that saw
# the press to its stamp): the VR page stamps a trigger as the event of the frame that read it fires, within a
# millisecond; the button page at its next frame after the browser's gamepad poll saw it, within a 60 Hz frame
INPUT_DELAY_MAX_S = {"vr": 0.001, "reality": 1 / 60}


def input_delay(condition: str, rng: np.random.Generator) -> float:
    """A press's input delay (s) as its page would measure it: uniform up to INPUT_DELAY_MAX_S."""
    if condition not in INPUT_DELAY_MAX_S:
        raise ParticipantError(f"no input delay for the condition {condition!r}; known: {', '.join(INPUT_DELAY_MAX_S)}")
    return float(rng.uniform(0.0, INPUT_DELAY_MAX_S[condition]))


def arrival_time(times: np.ndarray, distances: np.ndarray, target: float) -> float:
    """When (s) an approach with these distances to the hand first comes within `target`, interpolated between
    samples; ParticipantError when it never does."""
    inside = np.flatnonzero(distances <= target)
    if inside.size == 0:
        raise ParticipantError(
            f"the approach never comes within {target:.3f} m of the hand (it ends {distances[-1]:.3f} m)"
        )
    k = int(inside[0])
    if k == 0:
        return float(times[0])
    before, after = float(distances[k - 1]), float(distances[k])
    fraction = (before - target) / (before - after)
    return float(times[k - 1] + fraction * (times[k] - times[k - 1]))


def study_measures(
    population: Population, test: int, participant: np.ndarray, vr: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """A whole study's measures at once, one per trial (its participant's index from 0, and whether it was in VR),
    each participant drawn afresh: test 1 perceived / actual, test 2 the distance at the press (m)."""
    drawn = population.draws(rng, int(participant.max()) + 1)
    if test == 1:
        ratio = np.where(vr, drawn["ratio_vr"][participant], drawn["ratio_reality"][participant])
        return judged_ratios(ratio, population.perception_noise, rng)
    if test == 2:
        comfort = np.where(vr, drawn["comfort_vr"][participant], drawn["comfort_reality"][participant])
        return comfort_distances(comfort, population.comfort_noise, rng)
    raise ParticipantError(f"test must be 1 or 2, got {test!r}")


def preferred_path(traits: Traits, paths: Sequence[str]) -> str:
    """The group's path the participant prefers: the first of them in their ranking."""
    unknown = [path for path in paths if path not in traits.ranking]
    if not paths or unknown:
        raise ParticipantError(f"cannot rank paths {list(paths)}; known: {', '.join(traits.ranking)}")
    return min(paths, key=traits.ranking.index)


def questionnaire_answer(
    traits: Traits,
    questionnaire: str,
    low: int,
    high: int,
    reversed_: bool,
    been_in_vr: bool,
    rng: np.random.Generator,
) -> int:
    """The participant's answer to an item on the scale low..high of `questionnaire` (ssq, ipq, or one of the lab's
    own): the lowest plus a binomial count of the scale's steps, its mean the participant's level; a reversed item's
    answer mirrored, so that its score has that mean."""
    if not (isinstance(low, int) and isinstance(high, int) and low < high):
        raise ParticipantError(f"an item's scale must be lowest < highest, got {low}..{high}")
    steps = high - low
    if questionnaire == "ssq":
        # the level is a mean rating: capped where every symptom would be rated at the top
        chance = min(traits.symptoms["after_vr" if been_in_vr else "before_vr"] / steps, 1.0)
    elif questionnaire == "ipq":
        chance = traits.presence
    else:
        chance = traits.item_level
    scored = low + int(rng.binomial(steps, chance))
    return low + high - scored if reversed_ else scored


def trial_withdrawal(traits: Traits, condition: str, rng: np.random.Generator) -> float:
    """How far (m) the hand withdraws after this trial's press, around the participant's own; never below 0."""
    _condition(traits, condition)
    return max(float(rng.normal(traits.withdrawal[condition], traits.withdrawal_noise)), 0.0)


# s: a quick withdrawal, as a flinch is, from the press on
WITHDRAWAL_DURATION = 0.4
# s: a late one starts this long after the press, when the robot has braked and rests (a stop's braking and the
# runner's 0.5 s hold take about a second), and takes this long: it ends some 2 s after the robot rests, inside the
# measure's limit (sim.study.motion's WITHDRAWAL_LIMIT), and far outside the approach's own window
LATE_WITHDRAWAL_DELAY = 1.5
SLOW_WITHDRAWAL_DURATION = 1.2


@dataclass(frozen=True)
class WithdrawalTiming:
    """When a trial's withdrawal starts after the press (s) and how long it takes (s)."""

    delay: float
    duration: float


def trial_withdrawal_timing(traits: Traits, rng: np.random.Generator) -> WithdrawalTiming:
    """At once and quick, or (with the participant's late_withdrawal_share) late and slow."""
    if rng.random() < traits.late_withdrawal_share:
        return WithdrawalTiming(LATE_WITHDRAWAL_DELAY, SLOW_WITHDRAWAL_DURATION)
    return WithdrawalTiming(0.0, WITHDRAWAL_DURATION)
