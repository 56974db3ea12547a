"""The sample size, before anyone is recruited: whole studies simulated from the participant model, without physics,
each analysed exactly as `analyse` analyses a real one (`contrasts.judge`: the mixed model and the verdict against
the SESOI), at each number of participants (`python -m sim.study power`).

A simulated study of N participants has the trials the design gives participants 1..N (their session plans, so the
same counterbalancing), and measures drawn from `participants.model.study_measures` with the test's VR − reality
difference and its SD between participants as asked; the other spreads are the population's. The model's matrices
are built once per N and refitted with each study's values. Studies run in chunks on a process pool; each chunk has
its own seed (from the seed, N and the chunk's number), so the figures do not depend on the number of workers.
"""

from __future__ import annotations

import math
import multiprocessing
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np

from sim.study.analysis.contrasts import FACTOR_NAMES, factor_level, judge
from sim.study.analysis.mixed_model import ModelDesign, Trials, model_design
from sim.study.design.plan import make_plan
from sim.study.design.spec import TESTS, Design, Planning
from sim.study.participants.model import Population, study_measures
from sim.study.power.errors import PowerError

__all__ = [
    "PowerQuestion",
    "PowerRow",
    "PlannedSample",
    "study_layout",
    "power_rows",
    "needed",
    "planning_of",
    "planned_questions",
    "plan_sample",
]

_CHUNK = 25  # studies per task: small enough for the progress bar, large enough to hide the pool's overhead
# a fit's matrices are small: BLAS threads only fight over the cores the workers already fill (2x slower)
_BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@dataclass(frozen=True)
class PowerQuestion:
    test: int
    difference: float  # the true VR − reality difference, in the measure's units
    sd_between: float  # the SD of the participants' own VR − reality differences
    sesoi: float
    participants: tuple[int, ...]
    simulations: int  # studies per N
    seed: int

    def __post_init__(self) -> None:
        problems = []
        if self.test not in TESTS:
            problems.append(f"test must be one of {TESTS}, got {self.test!r}")
        if not math.isfinite(self.difference):
            problems.append(f"the difference must be finite, got {self.difference!r}")
        if not (math.isfinite(self.sd_between) and self.sd_between >= 0.0):
            problems.append(f"the SD between participants must be >= 0, got {self.sd_between!r}")
        if not (math.isfinite(self.sesoi) and self.sesoi > 0.0):
            problems.append(f"the SESOI must be > 0, got {self.sesoi!r}")
        if not self.participants or any(not 4 <= n <= 500 for n in self.participants):
            problems.append(
                f"the numbers of participants must be 4..500 (two per order at least), got {self.participants}"
            )
        if not 1 <= self.simulations <= 100_000:
            problems.append(f"the simulations must be 1..100000, got {self.simulations}")
        if self.seed < 0:
            problems.append(f"the seed must be >= 0, got {self.seed}")
        if problems:
            raise PowerError("; ".join(problems))

    def population(self, base: Population) -> Population:
        """`base` with this question's difference and SD for its test."""
        if self.test == 1:
            return replace(base, vr_distance_shift=self.difference, distance_shift_sd=self.sd_between)
        return replace(base, vr_comfort_shift=self.difference, comfort_shift_sd=self.sd_between)


@dataclass(frozen=True)
class PowerRow:
    participants: int
    simulations: int
    p_different: float  # the 95 % CI excludes 0
    p_equivalent: float  # the 90 % CI lies inside ±SESOI
    slope_dropped: float  # the share of fits without the random condition slope


def study_layout(design: Design, test: int, participants: int, seed: int) -> Trials:
    """The model's rows of `test` for participants 1..N as their plans have them; the values are NaN."""
    rows = [
        (plan.participant, trial, plan.conditions[0] == "vr")
        for plan in (make_plan(design, number, seed) for number in range(1, participants + 1))
        for trial in plan.trials
        if trial.test == test
    ]
    return Trials(
        participant=np.array([participant for participant, _, _ in rows]),
        vr=np.array([trial.condition == "vr" for _, trial, _ in rows]),
        vr_first=np.array([vr_first for _, _, vr_first in rows]),
        factor=np.array([factor_level(test, trial.standoff, trial.speed_set) for _, trial, _ in rows]),
        path=np.array([trial.path for _, trial, _ in rows]),
        value=np.full(len(rows), math.nan),
    )


@dataclass(frozen=True)
class _Chunk:
    participants: int
    number: int
    studies: int
    test: int
    population: Population
    sesoi: float
    seed: int
    model: ModelDesign
    participant_index: np.ndarray  # 0.. per row
    vr: np.ndarray


def _run_chunk(chunk: _Chunk) -> tuple[int, int, int, int]:
    """(participants, different, equivalent, slope dropped) over the chunk's studies."""
    rng = np.random.default_rng([chunk.seed, chunk.participants, chunk.number])
    different = equivalent = dropped = 0
    for _ in range(chunk.studies):
        values = study_measures(chunk.population, chunk.test, chunk.participant_index, chunk.vr, rng)
        fit, judged = judge(chunk.model, values, chunk.sesoi)
        different += judged.different
        equivalent += judged.equivalent
        dropped += not fit.with_slope
    return chunk.participants, different, equivalent, dropped


def _chunks(question: PowerQuestion, design: Design, population: Population) -> list[_Chunk]:
    chunks = []
    for n in question.participants:
        layout = study_layout(design, question.test, n, question.seed)
        model = model_design(layout, FACTOR_NAMES[question.test])
        index = np.unique(layout.participant, return_inverse=True)[1]
        for number, start in enumerate(range(0, question.simulations, _CHUNK)):
            studies = min(_CHUNK, question.simulations - start)
            chunks.append(
                _Chunk(
                    n,
                    number,
                    studies,
                    question.test,
                    population,
                    question.sesoi,
                    question.seed,
                    model,
                    index,
                    layout.vr,
                )
            )
    return chunks


@contextmanager
def _single_threaded_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """A pool of fresh interpreters whose BLAS runs one thread each: they read it from the environment when they
    load it, and they start while it is set (the pool's whole life)."""
    saved = {name: os.environ.get(name) for name in _BLAS_THREADS}
    os.environ.update({name: "1" for name in _BLAS_THREADS})
    try:
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            yield pool
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextmanager
def _studies_run(workers: int) -> Iterator[ProcessPoolExecutor | None]:
    """Where the chunks run: here (None) with 1 worker, else on a pool of `workers` (0: one per core, at most 2),
    started once for every question asked while it is open."""
    workers = workers or min(2, os.cpu_count() or 1)
    if workers == 1:
        yield None
    else:
        with _single_threaded_pool(workers) as pool:
            yield pool


def _rows(
    question: PowerQuestion,
    design: Design,
    base: Population | None,
    pool: ProcessPoolExecutor | None,
    progress: Callable[[int], None] | None,
) -> list[PowerRow]:
    chunks = _chunks(question, design, question.population(base or Population()))
    counts = {n: [0, 0, 0] for n in question.participants}
    results = map(_run_chunk, chunks) if pool is None else pool.map(_run_chunk, chunks)
    for chunk, (n, different, equivalent, dropped) in zip(chunks, results):
        counts[n][0] += different
        counts[n][1] += equivalent
        counts[n][2] += dropped
        if progress is not None:
            progress(chunk.studies)
    k = question.simulations
    return [PowerRow(n, k, counts[n][0] / k, counts[n][1] / k, counts[n][2] / k) for n in question.participants]


def power_rows(
    question: PowerQuestion,
    design: Design,
    base: Population | None = None,
    workers: int = 0,
    progress: Callable[[int], None] | None = None,
) -> list[PowerRow]:
    """One row per N of the question, in its order. `workers`: processes (0: one per core, at most 2; 1: here,
    without a pool); `progress` is called with the studies each finished chunk held. `base`: the population whose
    other spreads are used (default: Population())."""
    with _studies_run(workers) as pool:
        return _rows(question, design, base, pool, progress)


def needed(rows: Sequence[PowerRow], power: float, verdict: str) -> int | None:
    """The smallest N whose probability of `verdict` ("different" or "equivalent") reaches `power`, if one does."""
    if verdict not in ("different", "equivalent"):
        raise PowerError(f"verdict must be 'different' or 'equivalent', got {verdict!r}")
    for row in sorted(rows, key=lambda row: row.participants):
        if (row.p_different if verdict == "different" else row.p_equivalent) >= power:
            return row.participants
    return None


@dataclass(frozen=True)
class PlannedSample:
    """The design's planning carried out: per N tried, in order, each test's row; the N planned (the first at which
    every test reaches the planned power of "equivalent"), None when none of those tried does."""

    participants: int | None
    rows: dict[int, list[PowerRow]]  # per test
    simulations: int
    seed: int


def planning_of(design: Design) -> Planning:
    if design.planning is None:
        raise PowerError("the design has no planning section: it says nothing to plan the sample on")
    return design.planning


def planned_questions(
    design: Design, sizes: Sequence[int] | None = None, simulations: int | None = None
) -> list[dict[int, PowerQuestion]]:
    """The design's planning (its difference and SD per test, its seed) as each test's PowerQuestion per N to try,
    `sizes` (default: its own) in increasing order; `simulations` overrides its studies per N. Every question is
    checked here, so a bad value is one PowerError before anything runs."""
    planning = planning_of(design)
    simulations = simulations if simulations is not None else planning.simulations
    return [
        {
            test: PowerQuestion(
                test,
                planning.expected_difference[test],
                planning.sd_between[test],
                design.sesoi[test],
                (n,),
                simulations,
                planning.seed,
            )
            for test in TESTS
        }
        for n in sorted(sizes if sizes is not None else planning.participants)
    ]


def plan_sample(
    design: Design,
    questions: list[dict[int, PowerQuestion]],
    workers: int = 0,
    progress: Callable[[int], None] | None = None,
) -> PlannedSample:
    """The planned questions (planned_questions) answered N by N, up to the first N at which every test reaches the
    design's power of "equivalent"."""
    planning = planning_of(design)
    first = questions[0][TESTS[0]]
    rows: dict[int, list[PowerRow]] = {test: [] for test in TESTS}
    with _studies_run(workers) as pool:  # one pool for every size and test: its workers start once
        for at_size in questions:
            for test in TESTS:
                rows[test] += _rows(at_size[test], design, None, pool, progress)
            if all(rows[test][-1].p_equivalent >= planning.power for test in TESTS):
                return PlannedSample(rows[TESTS[0]][-1].participants, rows, first.simulations, first.seed)
    return PlannedSample(None, rows, first.simulations, first.seed)
