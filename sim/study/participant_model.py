"""A simulated participant's behaviour, with known biases so that the analysis can be checked against them. Pure
logic; the simulated participant (a TCP client of the endpoint, like a Unity scene) acts on it.

Each participant has traits drawn once from a Population, seeded by (seed, participant):
  distance perception   perceived = actual × bias[condition] × lognormal(0, perception_noise); the population
                        default underestimates by 15 % in VR and is unbiased in reality;
  comfort distance      presses stop once the end effector is this close to the hand (test 2), plus a shift in
                        VR, then after a reaction time;
  preference            ranks a group's paths by their order in the participant's own ranking of all paths.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from sim.study.errors import StudyError
from sim.study.paths import PATH_NAMES

__all__ = ["Population", "Traits", "draw_traits", "perceived_distance", "comfort_threshold", "preferred_path"]


@dataclass(frozen=True)
class Population:
    distance_bias: dict[str, float] = field(default_factory=lambda: {"vr": 0.85, "reality": 1.0})
    perception_noise: float = 0.05  # log-sd of a single judgement
    comfort_mean: float = 0.12  # m
    comfort_sd: float = 0.03
    comfort_vr_shift: float = -0.02  # m: closer in VR
    reaction_mean: float = 0.25  # s
    reaction_sd: float = 0.04


@dataclass(frozen=True)
class Traits:
    participant: int
    distance_bias: dict[str, float]
    perception_noise: float
    comfort_distance: float  # m, in reality
    comfort_vr_shift: float
    reaction_time: float  # s
    ranking: tuple[str, ...]  # every path, most preferred first


def draw_traits(population: Population, participant: int, seed: int) -> Traits:
    if participant < 1 or seed < 0:
        raise StudyError(f"participant must be >= 1 and seed >= 0, got {participant} and {seed}")
    rng = np.random.default_rng([seed, participant, 1])  # a stream apart from the plan's
    comfort = float(np.clip(rng.normal(population.comfort_mean, population.comfort_sd), 0.04, 0.25))
    reaction = float(np.clip(rng.normal(population.reaction_mean, population.reaction_sd), 0.1, 0.6))
    ranking = tuple(PATH_NAMES[k] for k in rng.permutation(len(PATH_NAMES)))
    return Traits(
        participant,
        dict(population.distance_bias),
        population.perception_noise,
        comfort,
        population.comfort_vr_shift,
        reaction,
        ranking,
    )


def perceived_distance(traits: Traits, condition: str, actual: float, rng: np.random.Generator) -> float:
    """What the participant shows for an actual distance (m)."""
    if condition not in traits.distance_bias:
        raise StudyError(f"unknown condition {condition!r}; known: {', '.join(traits.distance_bias)}")
    if not (math.isfinite(actual) and actual >= 0.0):
        raise StudyError(f"an actual distance must be >= 0 m, got {actual!r}")
    return float(actual * traits.distance_bias[condition] * rng.lognormal(0.0, traits.perception_noise))


def comfort_threshold(traits: Traits, condition: str) -> float:
    """The distance (m) at which the participant decides to press (the press itself follows the reaction time)."""
    shift = traits.comfort_vr_shift if condition == "vr" else 0.0
    return max(traits.comfort_distance + shift, 0.03)


def preferred_path(traits: Traits, paths: Sequence[str]) -> str:
    """The group's path the participant prefers: the first of them in their ranking."""
    unknown = [path for path in paths if path not in traits.ranking]
    if not paths or unknown:
        raise StudyError(f"cannot rank paths {list(paths)}; known: {', '.join(traits.ranking)}")
    return min(paths, key=traits.ranking.index)
