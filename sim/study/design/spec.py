"""The study's design as data (design.yaml beside this file): test 1's paths and stand-offs, test 2's paths and
speed sets, the two conditions (VR and reality), each test's smallest effect size of interest (SESOI), what the
sample size is planned on, and the questionnaires asked before or after each condition's block. Pure logic, but for
reading the YAML in `load_design`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from sim.study.design.errors import DesignError
from sim.study.design.paths import MAX_STANDOFF, MIN_STANDOFF, PATH_NAMES
from sim.study.design.yamlfile import read_yaml
from sim.study.questionnaires.errors import QuestionnaireError
from sim.study.questionnaires.instruments import STANDARD, Instrument, single_item, standard_instrument

__all__ = [
    "DEFAULT_DESIGN",
    "CONDITIONS",
    "TESTS",
    "POSITIONS",
    "WHEN",
    "Design",
    "Planning",
    "DeclaredQuestionnaire",
    "parse_design",
    "load_design",
]

DEFAULT_DESIGN = Path(__file__).resolve().parent / "design.yaml"
CONDITIONS = ("vr", "reality")
TESTS = (1, 2)
POSITIONS = ("before", "after")  # a questionnaire is asked before or after a condition's block of trials
# design.yaml's `when` words and the (condition, position) of each asking they stand for
WHEN: dict[str, tuple[tuple[str, str], ...]] = {
    **{f"{position}_{condition}": ((condition, position),) for position in POSITIONS for condition in CONDITIONS},
    **{f"{position}_each": tuple((condition, position) for condition in CONDITIONS) for position in POSITIONS},
}


@dataclass(frozen=True)
class Planning:
    """What `power` and `preregister` assume before any data: per test, the SD of the participants' own
    VR − reality differences, and the true difference the sample is planned for (usually none)."""

    sd_between: dict[int, float]
    expected_difference: dict[int, float]
    power: float  # the planned probability of "equivalent"
    participants: tuple[int, ...]  # the sample sizes simulated
    simulations: int
    seed: int


@dataclass(frozen=True)
class DeclaredQuestionnaire:
    """A questionnaire the design asks, and when: a standard instrument or a single item of the lab's own."""

    instrument: Instrument
    when: tuple[str, ...]  # as design.yaml says it: keys of WHEN

    @property
    def placements(self) -> tuple[tuple[str, str], ...]:
        """(condition, position) of each asking."""
        return tuple(placement for word in self.when for placement in WHEN[word])


@dataclass(frozen=True)
class Design:
    test1_paths: tuple[str, ...]
    test1_standoffs: tuple[float, ...]
    test1_peak_speed: float
    test2_paths: tuple[str, ...]
    test2_speed_sets: tuple[tuple[str, float], ...]  # (name, peak speed), in the design's order
    sesoi: dict[int, float]  # per test, in its measure's units: test 1 the ratio, test 2 metres
    planning: Planning | None = None
    sesoi_reason: dict[int, str] = field(default_factory=dict)  # per test, why that SESOI (for the pre-registration)
    questionnaires: tuple[DeclaredQuestionnaire, ...] = ()  # as declared: the plan asks them in this order, SSQ first

    @property
    def trials_per_participant(self) -> int:
        per_condition = len(self.test1_paths) * len(self.test1_standoffs) + len(self.test2_paths) * len(
            self.test2_speed_sets
        )
        return per_condition * len(CONDITIONS)


def _paths(value: object, what: str) -> tuple[str, ...]:
    if not isinstance(value, list) or not value:
        raise DesignError(f"{what} must be a list of path names ({', '.join(PATH_NAMES)}), got {value!r}")
    unknown = [name for name in value if name not in PATH_NAMES]
    if unknown:
        raise DesignError(f"{what}: unknown path(s) {unknown}; known paths: {', '.join(PATH_NAMES)}")
    if len(set(value)) != len(value):
        raise DesignError(f"{what} names a path twice: {value}")
    return tuple(value)


def _speed(value: object, what: str) -> float:
    if not (
        isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and 0.0 < value <= 1.0
    ):
        raise DesignError(f"{what} must be a speed in (0, 1] m/s, got {value!r}")
    return float(value)


def _section(data: dict, key: str, keys: tuple[str, ...], source: str) -> dict:
    section = data.get(key)
    if not isinstance(section, dict) or sorted(set(section) - {"sesoi_reason"}) != sorted(keys):
        raise DesignError(
            f"{source}: {key} must have exactly {', '.join(keys)} and optionally sesoi_reason, got {section!r}"
        )
    reason = section.get("sesoi_reason", "")
    if not isinstance(reason, str):
        raise DesignError(f"{source}: {key}.sesoi_reason must be text, got {reason!r}")
    return section


def _number(value: object, what: str, low: float, high: float) -> float:
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and low < value <= high):
        raise DesignError(f"{what} must be a number in ({low:g}, {high:g}], got {value!r}")
    return float(value)


def _per_test(value: object, what: str, low: float, high: float) -> dict[int, float]:
    if not isinstance(value, dict) or sorted(value) != ["test1", "test2"]:
        raise DesignError(f"{what} must give test1 and test2, got {value!r}")
    return {test: _number(value[f"test{test}"], f"{what}.test{test}", low, high) for test in TESTS}


def _planning(data: object, source: str) -> Planning:
    keys = ("sd_between", "expected_difference", "power", "participants", "simulations", "seed")
    if not isinstance(data, dict) or sorted(data) != sorted(keys):
        raise DesignError(f"{source}: planning must have exactly {', '.join(keys)}, got {data!r}")
    sizes = data["participants"]
    if not (
        isinstance(sizes, list)
        and sizes
        and all(isinstance(n, int) and not isinstance(n, bool) and 4 <= n <= 500 for n in sizes)
        and sizes == sorted(set(sizes))
    ):
        raise DesignError(f"{source}: planning.participants must be increasing numbers of 4..500, got {sizes!r}")
    simulations, seed = data["simulations"], data["seed"]
    if not (isinstance(simulations, int) and 100 <= simulations <= 100_000):
        raise DesignError(f"{source}: planning.simulations must be 100..100000, got {simulations!r}")
    if not (isinstance(seed, int) and seed >= 0):
        raise DesignError(f"{source}: planning.seed must be an integer >= 0, got {seed!r}")
    return Planning(
        sd_between=_per_test(data["sd_between"], f"{source}: planning.sd_between", 0.0, 1.0),
        expected_difference=_per_test(
            data["expected_difference"], f"{source}: planning.expected_difference", -1.0, 1.0
        ),
        power=_number(data["power"], f"{source}: planning.power", 0.5, 0.99),
        participants=tuple(sizes),
        simulations=simulations,
        seed=seed,
    )


def _when(value: object, name: str, instrument: Instrument, where: str) -> tuple[str, ...]:
    if not (isinstance(value, list) and value):
        raise DesignError(f"{where}.when must be a non-empty list of {', '.join(WHEN)}, got {value!r}")
    unknown = [word for word in value if word not in WHEN]
    if unknown:
        raise DesignError(f"{where}.when: unknown {unknown}; known: {', '.join(WHEN)}")
    placements = [placement for word in value for placement in WHEN[word]]
    if len(set(placements)) != len(placements):
        raise DesignError(f"{where}.when asks {name} twice at the same point: {value}")
    elsewhere = sorted({condition for condition, _ in placements} - set(instrument.conditions or CONDITIONS))
    if elsewhere:
        # the IPQ's items speak of the virtual world: in reality they would have nothing to refer to
        raise DesignError(
            f"{where}.when asks {name} in {', '.join(elsewhere)}; it is for {', '.join(instrument.conditions)} only"
        )
    return tuple(value)


def _questionnaires(data: object, source: str) -> tuple[DeclaredQuestionnaire, ...]:
    """design.yaml's questionnaires: {ssq: {when}, ipq: {when}, items: {name: {text, scale, labels, when}}}, any of
    them, in the order declared (the plan asks the SSQ first where several share a point)."""
    where = f"{source}: questionnaires"
    known = (*STANDARD, "items")
    if not isinstance(data, dict):
        raise DesignError(f"{where} must map {', '.join(known)} to when they are asked, got {data!r}")
    unknown = [key for key in data if key not in known]
    if unknown:
        raise DesignError(f"{where}: unknown {unknown}; known: {', '.join(known)}")
    declared = []
    for name, entry in data.items():
        if name == "items":
            if not isinstance(entry, dict):
                raise DesignError(f"{where}.items must map item names to their text, scale, labels and when")
            for item, definition in entry.items():
                there = f"{where}.items.{item}"
                if not (isinstance(definition, dict) and "when" in definition):
                    raise DesignError(f"{there} must have text, scale, labels and when, got {definition!r}")
                try:
                    instrument = single_item(
                        item, {key: value for key, value in definition.items() if key != "when"}, f"{where}.items"
                    )
                except QuestionnaireError as error:
                    raise DesignError(str(error)) from None
                declared.append(DeclaredQuestionnaire(instrument, _when(definition["when"], item, instrument, there)))
            continue
        if not (isinstance(entry, dict) and sorted(entry) == ["when"]):
            raise DesignError(f"{where}.{name} must have exactly when, got {entry!r}")
        instrument = standard_instrument(name)
        declared.append(DeclaredQuestionnaire(instrument, _when(entry["when"], name, instrument, f"{where}.{name}")))
    return tuple(declared)


def parse_design(data: object, source: str = "design") -> Design:
    required, optional = ("test1", "test2"), ("planning", "questionnaires")
    if not isinstance(data, dict) or not all(key in data for key in required):
        raise DesignError(f"{source} must have test1, test2 and optionally {', '.join(optional)}")
    unknown = [key for key in data if key not in required + optional]
    if unknown:
        raise DesignError(f"{source}: unknown {unknown}; it has test1, test2 and optionally {', '.join(optional)}")
    test1 = _section(data, "test1", ("paths", "standoffs", "peak_speed", "sesoi"), source)
    test2 = _section(data, "test2", ("paths", "speed_sets", "sesoi"), source)
    standoffs = test1["standoffs"]
    if (
        not isinstance(standoffs, list)
        or not standoffs
        or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and MIN_STANDOFF <= v <= MAX_STANDOFF
            for v in standoffs
        )
        or len(set(standoffs)) != len(standoffs)
    ):
        raise DesignError(
            f"{source}: test1.standoffs must be distinct stand-offs of {MIN_STANDOFF}..{MAX_STANDOFF} m, "
            f"got {standoffs!r}"
        )
    speed_sets = test2["speed_sets"]
    if not isinstance(speed_sets, dict) or not speed_sets:
        raise DesignError(f"{source}: test2.speed_sets must map names to peak speeds, got {speed_sets!r}")
    return Design(
        test1_paths=_paths(test1["paths"], f"{source}: test1.paths"),
        test1_standoffs=tuple(float(v) for v in standoffs),
        test1_peak_speed=_speed(test1["peak_speed"], f"{source}: test1.peak_speed"),
        test2_paths=_paths(test2["paths"], f"{source}: test2.paths"),
        test2_speed_sets=tuple(
            (str(name), _speed(speed, f"{source}: test2.speed_sets.{name}")) for name, speed in speed_sets.items()
        ),
        sesoi={
            1: _number(test1["sesoi"], f"{source}: test1.sesoi (perceived / actual)", 0.0, 1.0),
            2: _number(test2["sesoi"], f"{source}: test2.sesoi (m)", 0.0, 0.3),
        },
        planning=_planning(data["planning"], source) if "planning" in data else None,
        sesoi_reason={
            test: " ".join(str(section.get("sesoi_reason", "")).split())
            for test, section in ((1, test1), (2, test2))
            if section.get("sesoi_reason")
        },
        questionnaires=_questionnaires(data["questionnaires"], source) if "questionnaires" in data else (),
    )


def load_design(path: Path | None = None) -> Design:
    """The design in `path` (default: the bundled design.yaml)."""
    path = DEFAULT_DESIGN if path is None else Path(path)
    return parse_design(read_yaml(path, "design"), str(path))
