"""The study's report: every participant's CSV in a directory, summarised (sim.study.analysis.summary) into `report.md`
with its plots beside it (`python -m sim.study analyse DIR`): the verdicts on VR against reality first (the trial-level
mixed model's, with the sensitivity analysis of the missing trials beside them), then each test's mixed model, the
missing trials' scenarios (sim.study.analysis.missing), the paired comparisons, the participant's motion
(sim.study.analysis.motion), the stop presses' latency per path (sim.study.analysis.latency), the questionnaires' scores
(sim.study.analysis.questionnaires), and the plots (Bland–Altman among them). A pilot (one participant) gets that
participant's means per condition and a note in place of all that needs more participants (intervals, comparisons,
models, verdicts), with the model it would fit.

One concern, and a long one: the report is one document, its text and the plots it points to written from one summary;
the statistics it reports are their own modules'."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from sim.study.analysis.clocks import clock_lines
from sim.study.analysis.contrasts import FACTOR_NAMES, MEASURES, TestContrast
from sim.study.analysis.errors import AnalysisError
from sim.study.analysis.latency import LatencySummary, keyboard_flag, latency_lines, summarise_latency
from sim.study.analysis.links import link_lines
from sim.study.analysis.missing import IMPUTATIONS, Scenario
from sim.study.analysis.mixed_model import CROSSOVER_TERMS, formula
from sim.study.analysis.motion import MotionSummary, motion_lines, summarise_motion
from sim.study.analysis.questionnaires import QuestionnaireSummary, questionnaire_lines
from sim.study.analysis.statistics import Estimate, PairedComparison
from sim.study.analysis.summary import StudySummary, cell, per_participant, perceived_ratio, summarise
from sim.study.analysis.trackers import TrackerSummary, TrialSources, tracker_caveat, tracker_lines, trial_sources
from sim.study.design.spec import CONDITIONS
from sim.study.run.records import TrialRecord, read_records

__all__ = ["load_study", "write_report"]

_COLOURS = {"vr": "tab:purple", "reality": "tab:green"}


def load_study(directory: Path) -> list[TrialRecord]:
    """Every participant_*.csv in `directory`; AnalysisError if there is none, or one participant appears twice."""
    files = sorted(Path(directory).glob("participant_*.csv"))
    if not files:
        raise AnalysisError(f"no participant_*.csv in {directory}")
    records: list[TrialRecord] = []
    owners: dict[int, Path] = {}
    for path in files:
        for record in read_records(path):
            owner = owners.setdefault(record.participant, path)
            if owner != path:
                raise AnalysisError(f"participant {record.participant} is in both {owner.name} and {path.name}")
            records.append(record)
    return records


def _estimate_cell(estimate: Estimate, scale: float = 1.0, digits: int = 3) -> str:
    return (
        f"{estimate.mean * scale:.{digits}f} [{estimate.ci_low * scale:.{digits}f}, "
        f"{estimate.ci_high * scale:.{digits}f}]"
    )


def _p(value: float) -> str:
    return "< 0.001" if value < 0.001 else f"{value:.3f}"


def _comparison_row(label: str, c: PairedComparison, scale: float, digits: int) -> str:
    return (
        f"| {label} | {c.n} | {c.mean_a * scale:.{digits}f} | {c.mean_b * scale:.{digits}f} | "
        f"{c.mean_difference * scale:+.{digits}f} "
        f"[{c.ci_low * scale:+.{digits}f}, {c.ci_high * scale:+.{digits}f}] "
        f"| {c.t:.2f} | {_p(c.t_p)} | {c.cohen_dz:.2f} | {c.wilcoxon_w:g} | {_p(c.wilcoxon_p)} | "
        f"{c.rank_biserial:+.2f} |"
    )


_COMPARISON_HEAD = (
    "| | n | VR | reality | VR − reality [95 % CI] | t | p (t) | d_z | W | p (Wilcoxon) | r |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|"
)


_UNITS = {1: "", 2: " m"}


def _sensitivity_text(c: TestContrast, test: int) -> str:
    if c.sensitivity is None:
        return f"not run: {c.sensitivity_problem}"
    return c.sensitivity.summary(_UNITS[test])


def _scenario_name(scenario: Scenario, units: str) -> str:
    if not scenario.shifted:
        return "δ = 0: missing at random"
    return f"{'VR' if scenario.shifted == 'vr' else 'reality'}'s missing trials {scenario.delta:+g}{units}"


def _sensitivity_lines(contrasts: Mapping[int, TestContrast]) -> list[str]:
    """Each test's delta-adjusted scenarios (sim.study.analysis.missing), where trials are missing."""
    run = {test: c.sensitivity for test, c in sorted(contrasts.items()) if c.sensitivity and c.sensitivity.scenarios}
    if not run:
        return []
    imputations = next(iter(run.values())).imputations
    lines = [
        "### Missing trials: the sensitivity analysis",
        "",
        "The verdict above holds if the missing trials (no answer, no press, a trial voided) are missing at random "
        "given condition, factor and path. Were they not (fast withdrawals and hands near the arm lose more trials), "
        "how far would they have to differ to change it? Each missing trial is imputed from the primary model (fixed "
        "effects drawn from their sampling distribution, the participant's random effects given their observed "
        f"trials, a residual), {imputations} times; in each scenario one condition's imputed trials are shifted by δ; "
        "the model is refitted to each completed set and the contrasts pooled by Rubin's rules (Barnard–Rubin "
        "degrees of freedom), then judged by the same rules. δ = ±SESOI moves every missing trial of one condition "
        "by the whole margin.",
        "",
        "| test | missing (VR / reality) | scenario | VR − reality [95 % CI] | 90 % CI | verdict |",
        "|---|---|---|---|---|---|",
    ]
    for test, sensitivity in run.items():
        missing = f"{sensitivity.missing['vr']} / {sensitivity.missing['reality']} of {sensitivity.trials}"
        for scenario in sensitivity.scenarios:
            v = scenario.verdict
            lines.append(
                f"| {test} | {missing} | {_scenario_name(scenario, _UNITS[test])} | {v.estimate:+.4f} "
                f"[{v.ci95[0]:+.4f}, {v.ci95[1]:+.4f}] | [{v.ci90[0]:+.4f}, {v.ci90[1]:+.4f}] | {v.label} |"
            )
    return lines + [""]


def _verdict_lines(contrasts: Mapping[int, TestContrast]) -> list[str]:
    if not contrasts:
        return []
    lines = [
        "## VR against reality: the verdicts",
        "",
        "Each test's VR − reality contrast is the condition's coefficient in its mixed model (below), fitted to "
        "every trial with a measure and averaged over the design's cells, so that a cell that lost trials weighs as "
        "much as one that kept them: unbiased when trials are missing at random given condition, factor and path. "
        "It is judged against the SESOI declared in the design: **equivalent** if its 90 % CI lies inside ±SESOI, "
        "**different** if its 95 % CI excludes 0, else **inconclusive**. Beside it: the sensitivity analysis of the "
        "missing trials (delta-adjusted multiple imputation: the line under the table, its scenarios below), and, "
        "descriptive only, the paired TOST on per-participant means and their Bland–Altman agreement (a "
        "participant's mean weighs the cells by the trials each kept, so it is biased where trials are missing "
        "unevenly).",
        "",
        "| test | measure | SESOI | VR − reality [95 % CI] | 90 % CI | verdict | paired TOST p | "
        "Bland–Altman bias [95 % limits of agreement] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for test, c in sorted(contrasts.items()):
        v, a = c.verdict, c.agreement
        lines.append(
            f"| {test} | {MEASURES[test]} | ±{v.sesoi:g} | {v.estimate:+.4f} [{v.ci95[0]:+.4f}, {v.ci95[1]:+.4f}] | "
            f"[{v.ci90[0]:+.4f}, {v.ci90[1]:+.4f}] | **{v.label}** | {_p(c.tost.p)} "
            f"({'equivalent' if c.tost.equivalent else 'not shown equivalent'}) | "
            f"{a.bias:+.4f} [{a.low:+.4f}, {a.high:+.4f}] |"
        )
    lines.append("")
    lines += [
        f"- Test {test}: {c.verdict.label}: {c.verdict.explanation}. Missing trials' sensitivity: "
        f"{_sensitivity_text(c, test)}."
        for test, c in sorted(contrasts.items())
    ]
    lines.append("")
    for test, c in sorted(contrasts.items()):
        fit = c.fit
        lines += [
            f"### Test {test}: the mixed model",
            "",
            f"{formula(MEASURES[test], FACTOR_NAMES[test])}; random effects: {fit.random_effects}. REML "
            f"(statsmodels MixedLM), {fit.participants} participants, {fit.trials} trials; 95 % CIs from Student's t "
            f"with {fit.df} df (participants − sequences). Condition, period and sequence are coded ±½, the factors "
            "sum-to-zero.",
            "",
            *(f"- {line}" for line in CROSSOVER_TERMS),
            "",
        ]
        lines += [f"- {note}" for note in fit.notes] + ([""] if fit.notes else [])
        lines += ["| term | estimate | SE | 95 % CI |", "|---|---|---|---|"]
        lines += [
            f"| {k.name} | {k.estimate:+.4f} | {k.se:.4f} | [{k.ci_low:+.4f}, {k.ci_high:+.4f}] |"
            for k in fit.coefficients
        ]
        lines += [
            "",
            "Variances: " + ", ".join(f"{name} {value:.3g}" for name, value in fit.variances.items()) + ".",
            "",
        ]
    return lines + _sensitivity_lines(contrasts)


def _pilot_means(estimates: Mapping[str, Estimate], scale: float, digits: int) -> list[str]:
    return [
        f"| {condition} | {estimates[condition].mean * scale:.{digits}f} |"
        if condition in estimates
        else f"| {condition} | – (no trial with a value) |"
        for condition in CONDITIONS
    ]


def _pilot_lines(summary: StudySummary, modelled: bool) -> list[str]:
    """A pilot's tests: the participant's means per condition, and what needs more participants said, not computed:
    with `modelled` (the design's SESOIs given), the model each test would get."""
    lines = [
        f"A pilot of 1 participant (participant {summary.participants[0]}), {summary.trials} trials: intervals "
        "across participants, the paired VR − reality comparisons, the mixed models and the verdicts need at least "
        "2 participants (the mixed models at least 3), and are left out. The figures below are this participant's "
        "means of their trials per condition. Distances are the end effector's to the hand's surface, from FK of "
        "the achieved joint states.",
        "",
        "## Test 1: distance perception",
        "",
        "Perceived / actual distance (1 = exact; 0.85 = a 15 % underestimate), actual = the robot at rest:",
        "",
        "| condition | ratio |",
        "|---|---|",
        *_pilot_means(summary.distance_ratio, 1.0, 3),
        "",
        "## Test 2: comfort distance",
        "",
        "Distance to the hand at the press, cm:",
        "",
        "| condition | at the press |",
        "|---|---|",
        *_pilot_means(summary.stop_distance, 100.0, 1),
        "",
    ]
    if not modelled:
        return lines
    lines += [
        "## The mixed models: not fitted in a pilot",
        "",
        "A pilot of 1 participant: each test's mixed model, and the verdict on VR against reality with it, needs at "
        "least 3 participants. With them, each test's measure would be modelled (REML, statsmodels MixedLM; random "
        "effects: an intercept and a condition slope per participant) as:",
        "",
        *(f"- Test {test}: {formula(MEASURES[test], FACTOR_NAMES[test])}" for test in sorted(MEASURES)),
        "",
        "Condition, period and sequence coded ±½, the factors sum-to-zero.",
        "",
        *(f"- {line}" for line in CROSSOVER_TERMS),
        "",
    ]
    return lines


def _markdown(
    summary: StudySummary,
    latency: LatencySummary,
    motion: MotionSummary,
    plots: list[Path],
    title: str,
    questionnaires: QuestionnaireSummary | None,
    modelled: bool,
    trackers: TrackerSummary | None = None,
    links: Sequence[str] = (),
    notes: Sequence[str] = (),
    sources: TrialSources | None = None,
) -> str:
    flag = keyboard_flag(latency)  # first, as it biases the contrast
    lines = [f"# {title}", "", *([flag, ""] if flag else []), *(line for note in notes for line in (note, ""))]
    if summary.pilot:
        lines += _pilot_lines(summary, modelled)
        if summary.extrapolation_error is not None:
            lines += [
                f"The thesis's estimate (the planned distance at the press time) differs from the measured distance "
                f"at the press by {summary.extrapolation_error.mean * 1000:.1f} mm on average.",
                "",
            ]
        return _rest(lines, summary, latency, motion, plots, questionnaires, trackers, links, sources)
    assert summary.distance_ratio_vr_vs_reality and summary.stop_distance_vr_vs_reality  # 2+ participants
    assert summary.extrapolation_error
    lines += [
        *_verdict_lines(summary.contrasts),
        f"{len(summary.participants)} participants, {summary.trials} trials. Descriptive: each participant's "
        "trials with a value are averaged per condition (and per speed set or path in their rows), then VR and "
        "reality are compared in pairs (paired t-test with Cohen's d_z; Wilcoxon signed-rank with the matched-pairs "
        "rank-biserial r). Where trials are missing unevenly across the cells these means are biased"
        + ("; the verdicts above are the trial-level model's" if summary.contrasts else "")
        + ". Intervals are 95 % t intervals across participants. Distances are the end effector's to the hand's "
        "surface, from FK of the achieved joint states.",
        "",
        "## Test 1: distance perception",
        "",
        "Perceived / actual distance (1 = exact; 0.85 = a 15 % underestimate), actual = the robot at rest:",
        "",
        "| condition | ratio [95 % CI] |",
        "|---|---|",
    ]
    lines += [f"| {condition} | {_estimate_cell(summary.distance_ratio[condition])} |" for condition in CONDITIONS]
    lines += [
        "",
        _COMPARISON_HEAD,
        _comparison_row("perceived / actual", summary.distance_ratio_vr_vs_reality, 1.0, 3),
        "",
        "## Test 2: comfort distance",
        "",
        "Distance to the hand at the press, cm:",
        "",
        "| condition | at the press [95 % CI] |",
        "|---|---|",
    ]
    lines += [
        f"| {condition} | {_estimate_cell(summary.stop_distance[condition], 100.0, 1)} |" for condition in CONDITIONS
    ]
    lines += [
        "",
        "VR against reality, cm:",
        "",
        _COMPARISON_HEAD,
        _comparison_row("all", summary.stop_distance_vr_vs_reality, 100.0, 1),
    ]
    lines += [
        _comparison_row(f"speed set {name}", c, 100.0, 1) for name, c in summary.stop_distance_by_speed_set.items()
    ]
    lines += [_comparison_row(f"path {name}", c, 100.0, 1) for name, c in summary.stop_distance_by_path.items()]
    paths = sorted({path for counts in summary.preferences.values() for path in counts})
    lines += [
        "",
        "Preferred approach (one answer per group of test 2):",
        "",
        "| condition | " + " | ".join(paths) + " |",
        "|---|" + "---|" * len(paths),
    ]
    lines += [
        f"| {condition} | " + " | ".join(str(summary.preferences[condition][path]) for path in paths) + " |"
        for condition in CONDITIONS
    ]
    error = summary.extrapolation_error
    lines += [
        "",
        f"The thesis's estimate (the planned distance at the press time) differs from the measured distance "
        f"at the press by {_estimate_cell(error, 1000.0, 1)} mm on average.",
        "",
    ]
    return _rest(lines, summary, latency, motion, plots, questionnaires, trackers, links, sources)


def _rest(
    lines: list[str],
    summary: StudySummary,
    latency: LatencySummary,
    motion: MotionSummary,
    plots: list[Path],
    questionnaires: QuestionnaireSummary | None,
    trackers: TrackerSummary | None = None,
    links: Sequence[str] = (),
    sources: TrialSources | None = None,
) -> str:
    """The sections after the tests', a pilot's as well: the motion (with its trackers, and the caveat when the
    trials' `sources` differ between the conditions), the latency, the robot's trajectory controller (`links`, where
    one ran), the notes, the questionnaires and the plots."""
    trackers_section = tracker_lines(trackers, sources) if motion.recorded else []
    motion_section = motion_lines(motion, tracker_caveat(sources), trackers_section)
    lines += [*motion_section, *latency_lines(latency), *links]
    if summary.notes:
        lines += ["Notes:", ""] + [f"- {note}" for note in summary.notes] + [""]
    if questionnaires is not None:
        lines += questionnaire_lines(questionnaires)
    lines += ["## Plots", ""] + [f"![{plot.stem}]({plot.name})" for plot in plots]
    return "\n".join(lines) + "\n"


def _plot_test1(records: list[TrialRecord], summary: StudySummary, path: Path) -> Path:
    import matplotlib.pyplot as plt

    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5))
    top = 0.0
    for condition in CONDITIONS:
        rows = [r for r in records if r.test == 1 and r.condition == condition and math.isfinite(r.perceived_distance)]
        actual = np.array([r.distance_at_rest for r in rows]) * 100
        perceived = np.array([r.perceived_distance for r in rows]) * 100
        top = max(top, float(actual.max(initial=0)), float(perceived.max(initial=0)))
        ratio = summary.distance_ratio.get(condition)  # none in a pilot's condition without a value
        label = condition if ratio is None else f"{condition} (×{ratio.mean:.2f})"
        left.scatter(actual, perceived, s=12, alpha=0.6, color=_COLOURS[condition], label=label)
    left.plot([0, top * 1.05], [0, top * 1.05], "k--", linewidth=1, label="perceived = actual")
    left.set(xlabel="actual distance (cm)", ylabel="perceived distance (cm)", title="Test 1: every trial")
    left.legend()
    vr, reality = (per_participant(records, cell(1, condition), perceived_ratio) for condition in ("vr", "reality"))
    for participant in sorted(set(vr) & set(reality)):
        right.plot([0, 1], [reality[participant], vr[participant]], "-o", color="grey", alpha=0.6)
    right.axhline(1.0, color="k", linestyle="--", linewidth=1)
    right.set(
        xticks=[0, 1],
        xticklabels=["reality", "VR"],
        xlim=(-0.3, 1.3),
        ylabel="perceived / actual",
        title="Test 1: each participant's mean ratio",
    )
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


def _plot_test2(records: list[TrialRecord], summary: StudySummary, path: Path) -> Path:
    import matplotlib.pyplot as plt

    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5))
    # by peak speed, as the summary orders them (a pilot's summary has no comparison per speed set)
    speed_sets = [name for _, name in sorted({(r.peak_speed, r.speed_set) for r in records if r.test == 2})]
    for offset, condition in ((-0.18, "vr"), (0.18, "reality")):
        data = [
            [
                v * 100
                for v in per_participant(
                    records, cell(2, condition, speed_set=name), lambda r: r.distance_at_press
                ).values()
            ]
            for name in speed_sets
        ]
        boxes = left.boxplot(data, positions=np.arange(len(speed_sets)) + offset, widths=0.3, patch_artist=True)
        for box in boxes["boxes"]:
            box.set_facecolor(_COLOURS[condition])
            box.set_alpha(0.6)
        left.plot([], [], "s", color=_COLOURS[condition], label=condition)
    left.set(
        xticks=range(len(speed_sets)),
        xticklabels=speed_sets,
        ylabel="distance at the press (cm)",
        title="Test 2: per speed set (participant means)",
    )
    left.legend()
    paths = sorted({p for counts in summary.preferences.values() for p in counts})
    width = 0.38
    for k, condition in enumerate(CONDITIONS):
        counts = [summary.preferences[condition][p] for p in paths]
        right.bar(np.arange(len(paths)) + (k - 0.5) * width, counts, width, color=_COLOURS[condition], label=condition)
    right.set(
        xticks=range(len(paths)), xticklabels=paths, ylabel="groups preferred", title="Test 2: preferred approach"
    )
    right.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


def _plot_agreement(contrasts: Mapping[int, TestContrast], path: Path) -> Path:
    import matplotlib.pyplot as plt
    from statsmodels.graphics.agreement import mean_diff_plot

    figure, axes = plt.subplots(1, len(contrasts), figsize=(5.5 * len(contrasts), 4.5), squeeze=False)
    for axis, (test, c) in zip(axes[0], sorted(contrasts.items())):
        participants = sorted(c.vr_means)
        mean_diff_plot(
            np.array([c.vr_means[p] for p in participants]),
            np.array([c.reality_means[p] for p in participants]),
            ax=axis,
        )
        axis.axhspan(-c.verdict.sesoi, c.verdict.sesoi, color="tab:green", alpha=0.12, label="±SESOI")
        axis.set(
            title=f"Test {test}: Bland–Altman, participant means",
            xlabel=f"mean of VR and reality: {MEASURES[test]}",
            ylabel="VR − reality",
        )
        axis.legend(loc="lower right")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


def write_report(
    records: list[TrialRecord],
    out: Path,
    title: str = "Perception study",
    sesoi: Mapping[int, float] | None = None,
    questionnaires: QuestionnaireSummary | None = None,
    trackers: TrackerSummary | None = None,
    notes: Sequence[str] = (),
    imputations: int = IMPUTATIONS,
) -> Path:
    """report.md and its plots in `out`; with `sesoi` (per test, the design's), the verdicts, mixed models (the
    withdrawal's among them) and Bland–Altman plot too; with `questionnaires`, their section; with `trackers` (the
    sessions' pose sources), which tracked each condition; the caveat when the conditions' trackers differ comes from
    the rows' pose sources (those of rows written before them from `trackers`); `notes`, paragraphs under the title
    (what the scene changed for the arm); `imputations`: per scenario of the missing trials' sensitivity analysis.
    AnalysisError when the records cannot be analysed."""
    import matplotlib

    matplotlib.use("Agg")
    summary = summarise(records, sesoi, imputations)
    out.mkdir(parents=True, exist_ok=True)
    plots = [
        _plot_test1(records, summary, out / "test1_distance_perception.png"),
        _plot_test2(records, summary, out / "test2_comfort_distance.png"),
    ]
    if summary.contrasts:
        plots.append(_plot_agreement(summary.contrasts, out / "agreement_bland_altman.png"))
    report = out / "report.md"
    # the withdrawal's mixed model with the design's, as the full analysis is asked for with the design
    motion = summarise_motion(records, model=sesoi is not None)
    latency = summarise_latency(records)
    links = link_lines(records) + clock_lines(records)  # the robot's controller, then the session's clocks
    sources = trial_sources(records, trackers)
    modelled = sesoi is not None
    report.write_text(
        _markdown(summary, latency, motion, plots, title, questionnaires, modelled, trackers, links, notes, sources)
    )
    return report
