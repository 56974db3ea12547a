"""Helpers for the study's integration tests: plans written by hand, trial by trial, and a small design."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import yaml

# A study of 14 trials per participant: quick to simulate, and enough to recover the biases put in
SMALL_DESIGN = {
    "test1": {"paths": ["straight"], "standoffs": [0.08, 0.14, 0.2], "peak_speed": 0.15, "sesoi": 0.05},
    "test2": {"paths": ["straight", "vertical"], "speed_sets": {"slow": 0.2, "fast": 0.3}, "sesoi": 0.02},
}


def trial(
    index: int,
    condition: str,
    test: int,
    path: str,
    standoff: float,
    peak_speed: float,
    speed_set: str = "",
    group: int = 0,
) -> dict:
    """One trial of a plan file, as sim.study.design.plan writes it."""
    return {
        "index": index,
        "condition": condition,
        "test": test,
        "path": path,
        "standoff": standoff,
        "peak_speed": peak_speed,
        "speed_set": speed_set,
        "group": group,
    }


def questionnaire(index: int, name: str, condition: str, position: str, after_trial: int) -> dict:
    """One questionnaire of a plan file, as sim.study.design.plan writes it: `name` asked `position` (before or
    after) `condition`'s block, once trial `after_trial` has ended (0: before the first)."""
    return {
        "index": index,
        "name": name,
        "administration": f"{name}_{position}_{condition}",
        "condition": condition,
        "position": position,
        "after_trial": after_trial,
    }


def write_plan(
    path: Path,
    participant: int,
    first_condition: str,
    trials: list[dict],
    questionnaires: Sequence[dict] = (),
    items: Mapping[str, dict] | None = None,
) -> Path:
    """A plan file of `trials`, and of `questionnaires` (none by default: most of these plans are for the trials),
    with the lab's own `items` that they name ({name: {text, scale, labels}})."""
    conditions = ["vr", "reality"] if first_condition == "vr" else ["reality", "vr"]
    plan = {"participant": participant, "seed": 0, "conditions": conditions, "trials": trials}
    path.write_text(yaml.safe_dump({**plan, "questionnaires": list(questionnaires), "items": dict(items or {})}))
    return path
