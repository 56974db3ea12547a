"""A participant's session plan from the design, the participant number and a seed. Pure logic.

As the proposal has it (thesis §2.3): every participant does both conditions, half start with VR (odd participant
numbers) and half with reality (even ones). In each condition test 1 comes first: its combinations of path and
stopping distance (the same in both conditions), each in an order of its own. Then test 2: one group of three
trials per speed set, each group's paths in random order, the groups in random order; after each group the
participant says which approach they preferred. The random orders come from numpy's generator seeded with
(seed, participant): the same inputs give the same plan.

The design's questionnaires are placed before or after a condition's block of trials, as design.yaml says, the SSQ
first and the others in the design's order where several share a point; placing them draws nothing, so the trials'
orders are those of plans made before there were questionnaires. The plan carries the lab's own single items, so
that it alone says what to ask (the standard instruments are the bundled ones, by name).

The plan is written as YAML (`plan_to_data`), which the runner executes and the observer can print (`printable`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from sim.study.design.errors import DesignError
from sim.study.design.paths import MAX_STANDOFF, MIN_STANDOFF, ON_TOP, PATH_NAMES
from sim.study.design.spec import CONDITIONS, POSITIONS, DeclaredQuestionnaire, Design
from sim.study.questionnaires.errors import QuestionnaireError
from sim.study.questionnaires.instruments import (
    STANDARD,
    Instrument,
    single_item,
    single_item_data,
    standard_instrument,
)

__all__ = [
    "PlannedTrial",
    "PlannedQuestionnaire",
    "SessionPlan",
    "condition_order",
    "make_plan",
    "plan_to_data",
    "plan_from_data",
    "printable",
]

SSQ = "ssq"  # the Simulator Sickness Questionnaire's name among the standard instruments


@dataclass(frozen=True)
class PlannedTrial:
    index: int  # 1-based, in the order they are run
    condition: str  # "vr" | "reality"
    test: int  # 1 (distance perception) | 2 (comfort distance)
    path: str
    standoff: float  # m: test 1's stopping distance; test 2's end on top of the hand (ON_TOP)
    peak_speed: float  # m/s
    speed_set: str = ""  # test 2
    group: int = 0  # test 2: 1.. within the condition; a preference is asked after each group


@dataclass(frozen=True)
class PlannedQuestionnaire:
    index: int  # 1-based, in the order they are asked
    name: str  # the instrument: a standard one (ssq, ipq) or one of the plan's own items
    administration: str  # <name>_<position>_<condition>, e.g. ssq_before_vr: what its answers' rows are named by
    condition: str  # "vr" | "reality"
    position: str  # "before" | "after" the condition's block of trials
    after_trial: int  # the index of the last trial run before it is asked; 0 before the first trial


@dataclass(frozen=True)
class SessionPlan:
    participant: int
    seed: int
    conditions: tuple[str, ...]  # in the order they are run
    trials: tuple[PlannedTrial, ...]
    questionnaires: tuple[PlannedQuestionnaire, ...] = ()  # in the order they are asked
    items: tuple[Instrument, ...] = ()  # the lab's own single items that its questionnaires name

    def instrument(self, name: str) -> Instrument:
        """The instrument a planned questionnaire names: one of the plan's own items, or a standard one."""
        for item in self.items:
            if item.name == name:
                return item
        if name in STANDARD:
            return standard_instrument(name)
        raise DesignError(f"the plan asks no questionnaire {name!r}; known: {', '.join(self.instrument_names)}")

    @property
    def instrument_names(self) -> tuple[str, ...]:
        """What a planned questionnaire may name: a standard instrument or one of the plan's own items."""
        return STANDARD + tuple(item.name for item in self.items)

    def groups(self, condition: str) -> list[list[PlannedTrial]]:
        """Test 2's groups of `condition`, in order."""
        found: dict[int, list[PlannedTrial]] = {}
        for trial in self.trials:
            if trial.condition == condition and trial.test == 2:
                found.setdefault(trial.group, []).append(trial)
        return [found[group] for group in sorted(found)]


def condition_order(participant: int) -> tuple[str, ...]:
    """Odd participants start with VR, even ones with reality."""
    return CONDITIONS if participant % 2 == 1 else CONDITIONS[::-1]


def make_plan(design: Design, participant: int, seed: int) -> SessionPlan:
    if not (isinstance(participant, int) and participant >= 1):
        raise DesignError(f"the participant number must be an integer >= 1, got {participant!r}")
    if not (isinstance(seed, int) and seed >= 0):
        raise DesignError(f"the seed must be an integer >= 0, got {seed!r}")
    rng = np.random.default_rng([seed, participant])
    combinations = [(path, standoff) for path in design.test1_paths for standoff in design.test1_standoffs]
    trials: list[PlannedTrial] = []
    conditions = condition_order(participant)
    for condition in conditions:
        for k in rng.permutation(len(combinations)):
            path, standoff = combinations[k]
            trials.append(PlannedTrial(len(trials) + 1, condition, 1, path, standoff, design.test1_peak_speed))
        for group, s in enumerate(rng.permutation(len(design.test2_speed_sets)), start=1):
            name, speed = design.test2_speed_sets[s]
            for k in rng.permutation(len(design.test2_paths)):
                trials.append(
                    PlannedTrial(len(trials) + 1, condition, 2, design.test2_paths[k], ON_TOP, speed, name, group)
                )
    return SessionPlan(
        participant,
        seed,
        conditions,
        tuple(trials),
        _placed(design, conditions, trials),
        tuple(q.instrument for q in design.questionnaires if q.instrument.name not in STANDARD),
    )


def _block(trials: Sequence[PlannedTrial], condition: str) -> dict[str, int]:
    """Where a questionnaire before or after `condition`'s block is asked: after which trial (0: before the
    first)."""
    indices = [trial.index for trial in trials if trial.condition == condition]
    return {"before": indices[0] - 1, "after": indices[-1]} if indices else {}


def _asking_order(design: Design) -> list[DeclaredQuestionnaire]:
    """The design's questionnaires in the order asked where several share a point: the SSQ first, then the others
    as declared. Simulator sickness fades within minutes of leaving the headset, so the SSQ after VR is asked before
    the IPQ or any other questionnaire takes that time, whatever order a design declares them in (before a block it
    costs nothing, and one rule for every point is simpler to state)."""
    return sorted(design.questionnaires, key=lambda declared: declared.instrument.name != SSQ)  # stable


def _placed(
    design: Design, conditions: tuple[str, ...], trials: list[PlannedTrial]
) -> tuple[PlannedQuestionnaire, ...]:
    placed: list[PlannedQuestionnaire] = []
    for condition in conditions:
        block = _block(trials, condition)
        for position in POSITIONS:
            for declared in _asking_order(design):
                if (condition, position) in declared.placements:
                    name = declared.instrument.name
                    placed.append(
                        PlannedQuestionnaire(
                            len(placed) + 1,
                            name,
                            f"{name}_{position}_{condition}",
                            condition,
                            position,
                            block[position],
                        )
                    )
    return tuple(placed)


def plan_to_data(plan: SessionPlan) -> dict[str, Any]:
    return {
        "participant": plan.participant,
        "seed": plan.seed,
        "conditions": list(plan.conditions),
        "trials": [asdict(trial) for trial in plan.trials],
        "questionnaires": [asdict(questionnaire) for questionnaire in plan.questionnaires],
        "items": {item.name: single_item_data(item) for item in plan.items},
    }


_TRIAL_KEYS = ("index", "condition", "test", "path", "standoff", "peak_speed", "speed_set", "group")


def _trial(entry: object, number: int, source: str) -> PlannedTrial:
    where = f"{source}: trial {number}"
    if not isinstance(entry, dict) or sorted(entry) != sorted(_TRIAL_KEYS):
        raise DesignError(f"{where} must have exactly {', '.join(_TRIAL_KEYS)}, got {entry!r}")
    checks = [
        (entry["index"] == number, f"index {entry['index']!r} where {number} comes"),
        (entry["condition"] in CONDITIONS, f"condition {entry['condition']!r} is not one of {', '.join(CONDITIONS)}"),
        (entry["test"] in (1, 2), f"test {entry['test']!r} is not 1 or 2"),
        (entry["path"] in PATH_NAMES, f"path {entry['path']!r} is not one of {', '.join(PATH_NAMES)}"),
        (
            isinstance(entry["standoff"], float) and MIN_STANDOFF <= entry["standoff"] <= MAX_STANDOFF,
            f"stand-off {entry['standoff']!r} is not {MIN_STANDOFF}..{MAX_STANDOFF} m",
        ),
        (
            isinstance(entry["peak_speed"], float) and 0.0 < entry["peak_speed"] <= 1.0,
            f"peak speed {entry['peak_speed']!r} is not in (0, 1] m/s",
        ),
        (
            isinstance(entry["speed_set"], str)
            and isinstance(entry["group"], int)
            and not isinstance(entry["group"], bool),
            f"speed_set {entry['speed_set']!r} / group {entry['group']!r} are malformed",
        ),
    ]
    for ok, problem in checks:
        if not ok:
            raise DesignError(f"{where}: {problem}")
    return PlannedTrial(**entry)


_QUESTIONNAIRE_KEYS = ("index", "name", "administration", "condition", "position", "after_trial")


def _questionnaire(entry: object, number: int, source: str, plan: SessionPlan) -> PlannedQuestionnaire:
    where = f"{source}: questionnaire {number}"
    if not isinstance(entry, dict) or sorted(entry) != sorted(_QUESTIONNAIRE_KEYS):
        raise DesignError(f"{where} must have exactly {', '.join(_QUESTIONNAIRE_KEYS)}, got {entry!r}")
    name, condition, position = entry["name"], entry["condition"], entry["position"]
    checks = [
        (
            entry["index"] == number and not isinstance(entry["index"], bool),
            f"index {entry['index']!r} where {number} comes",
        ),
        (name in plan.instrument_names, f"name {name!r} is none of {', '.join(plan.instrument_names)}"),
        (condition in plan.conditions, f"condition {condition!r} is not one of {', '.join(plan.conditions)}"),
        (position in POSITIONS, f"position {position!r} is not one of {', '.join(POSITIONS)}"),
        (
            entry["administration"] == f"{name}_{position}_{condition}",
            f"administration {entry['administration']!r} is not {name}_{position}_{condition}",
        ),
        (
            entry["after_trial"] == _block(plan.trials, condition).get(position),
            f"after_trial {entry['after_trial']!r} is not where the {condition} block's {position} is",
        ),
    ]
    for ok, problem in checks:
        if not ok:
            raise DesignError(f"{where}: {problem}")
    allowed = plan.instrument(name).conditions
    if allowed and condition not in allowed:
        raise DesignError(f"{where}: {name} is for {', '.join(allowed)} only, not {condition}")
    return PlannedQuestionnaire(**entry)


def _items(data: object, source: str) -> tuple[Instrument, ...]:
    if not isinstance(data, dict):
        raise DesignError(f"{source}: items must map the lab's own item names to text, scale and labels")
    try:
        return tuple(single_item(name, entry, f"{source}: items") for name, entry in data.items())
    except QuestionnaireError as error:
        raise DesignError(str(error)) from None


def plan_from_data(data: object, source: str = "plan") -> SessionPlan:
    """A plan as written by `plan_to_data`, checked; DesignError names what is malformed."""
    keys = ("participant", "seed", "conditions", "trials", "questionnaires", "items")
    if isinstance(data, dict) and sorted(data) == sorted(keys[:4]):
        raise DesignError(
            f"{source} has no questionnaires: it was written before they were planned; make it again with "
            "`python -m sim.study plan`"
        )
    if not isinstance(data, dict) or sorted(data) != sorted(keys):
        raise DesignError(f"{source} must have exactly {', '.join(keys)}")
    if not (isinstance(data["participant"], int) and data["participant"] >= 1):
        raise DesignError(f"{source}: participant must be an integer >= 1, got {data['participant']!r}")
    if not (isinstance(data["seed"], int) and data["seed"] >= 0):
        raise DesignError(f"{source}: seed must be an integer >= 0, got {data['seed']!r}")
    if not isinstance(data["conditions"], list) or sorted(data["conditions"]) != sorted(CONDITIONS):
        raise DesignError(f"{source}: conditions must be {' and '.join(CONDITIONS)} in the order run")
    if not isinstance(data["trials"], list) or not data["trials"]:
        raise DesignError(f"{source}: trials must be a non-empty list")
    trials = tuple(_trial(entry, number, source) for number, entry in enumerate(data["trials"], start=1))
    plan = SessionPlan(
        data["participant"], data["seed"], tuple(data["conditions"]), trials, (), _items(data["items"], source)
    )
    if not isinstance(data["questionnaires"], list):
        raise DesignError(f"{source}: questionnaires must be a list (empty for none)")
    questionnaires = tuple(
        _questionnaire(entry, number, source, plan) for number, entry in enumerate(data["questionnaires"], start=1)
    )
    # in the order a session reaches them: by the trial they follow, a block's end before the next one's start
    order = [(q.after_trial, q.position == "before") for q in questionnaires]
    if order != sorted(order):
        raise DesignError(f"{source}: the questionnaires are not in the order the session reaches them")
    administrations = [q.administration for q in questionnaires]
    repeated = sorted({a for a in administrations if administrations.count(a) > 1})
    if repeated:
        raise DesignError(f"{source}: {', '.join(repeated)} asked more than once")
    return replace(plan, questionnaires=questionnaires)


def printable(plan: SessionPlan) -> str:
    """The plan as the observer prints it: a markdown table with room for the responses."""
    lines = [
        f"# Session plan: participant {plan.participant} (seed {plan.seed})",
        "",
        f"Conditions in this order: {' then '.join(plan.conditions)}.",
        "",
        "| # | condition | test | path | stop at | peak speed | group | response |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for trial in plan.trials:
        stop = "on the hand" if trial.test == 2 else f"{trial.standoff * 100:.0f} cm"
        group = f"{trial.speed_set} ({trial.group})" if trial.test == 2 else ""
        lines.append(
            f"| {trial.index} | {trial.condition} | {trial.test} | {trial.path} | {stop} | "
            f"{trial.peak_speed:.2f} m/s | {group} | |"
        )
    if plan.questionnaires:
        lines += ["", "Questionnaires, in the order asked:", ""]
    for questionnaire in plan.questionnaires:
        instrument = plan.instrument(questionnaire.name)
        count = len(instrument.items)
        when = (
            f"before trial {questionnaire.after_trial + 1}"
            if questionnaire.position == "before"
            else f"after trial {questionnaire.after_trial}"
        )
        lines.append(
            f"{questionnaire.index}. {questionnaire.administration}: "
            f"{instrument.title}, {count} item{'s' if count > 1 else ''}, {when}"
        )
    return "\n".join(lines) + "\n"
