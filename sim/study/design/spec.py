"""The study's design as data (design.yaml beside this file): test 1's paths and stand-offs, test 2's paths and
speed sets, the two conditions (VR and reality), each test's smallest effect size of interest (SESOI) and what the
sample size is planned on. Pure logic, but for reading the YAML in `load_design`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from sim.study.design.errors import DesignError
from sim.study.design.paths import MAX_STANDOFF, MIN_STANDOFF, PATH_NAMES
from sim.study.design.yamlfile import read_yaml

__all__ = ["DEFAULT_DESIGN", "CONDITIONS", "TESTS", "Design", "Planning", "parse_design", "load_design"]

DEFAULT_DESIGN = Path(__file__).resolve().parent / "design.yaml"
CONDITIONS = ("vr", "reality")
TESTS = (1, 2)


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
class Design:
    test1_paths: tuple[str, ...]
    test1_standoffs: tuple[float, ...]
    test1_peak_speed: float
    test2_paths: tuple[str, ...]
    test2_speed_sets: tuple[tuple[str, float], ...]  # (name, peak speed), in the design's order
    sesoi: dict[int, float]  # per test, in its measure's units: test 1 the ratio, test 2 metres
    planning: Planning | None = None
    sesoi_reason: dict[int, str] = field(default_factory=dict)  # per test, why that SESOI (for the pre-registration)

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


def parse_design(data: object, source: str = "design") -> Design:
    if not isinstance(data, dict) or sorted(data) not in (["test1", "test2"], ["planning", "test1", "test2"]):
        raise DesignError(f"{source} must have exactly test1, test2 and optionally planning")
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
    )


def load_design(path: Path | None = None) -> Design:
    """The design in `path` (default: the bundled design.yaml)."""
    path = DEFAULT_DESIGN if path is None else Path(path)
    return parse_design(read_yaml(path, "design"), str(path))
