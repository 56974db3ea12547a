"""The pre-registration summary, written from the design file (`python -m sim.study preregister`): hypotheses,
measures, the participant's input devices, the participant's motion, the questionnaires, the SESOIs with their
reasoning, the planned sample and its power, the models (the primary analysis at the trial level), the missing trials'
sensitivity analysis and the decision rules. Pure logic: what is analysed is what
the design declares, and the summary names the file and its SHA-256 so that a reader can check the analysis used
that very file."""

from __future__ import annotations

from sim.study.analysis.contrasts import FACTOR_NAMES, MEASURES
from sim.study.analysis.missing import IMPUTATIONS, SEED
from sim.study.analysis.mixed_model import CROSSOVER_TERMS, formula
from sim.study.analysis.motion import DEFINED, MODELLED, MOTION_MEASURES
from sim.study.analysis.questionnaires import SSQ_SUSPECT_SOURCE, SSQ_SUSPECT_TOTAL
from sim.study.design.spec import TESTS, Design
from sim.study.motion.calibration import MIN_POINTS
from sim.study.motion.measures import HAND_RADIUS
from sim.study.power.sample_size import PlannedSample
from sim.study.questionnaires.instruments import Instrument
from sim.study.run.protocol import BODIES, POSE_FRAME, POSE_TOPICS, POSE_TYPE, PROTOCOL, TRACKING_GAP

__all__ = ["preregistration"]

_UNITS = {1: "", 2: " m"}
_CONDITION_NAMES = {"vr": "VR", "reality": "reality"}
_HYPOTHESES = {
    1: "People perceive the robot's distance from their hand the same in VR as in reality",
    2: "People stop an approaching robot at the same distance from their hand in VR as in reality",
}


def _factors(design: Design, test: int) -> str:
    if test == 1:
        standoffs = ", ".join(f"{s:g}" for s in design.test1_standoffs)
        return (
            f"paths {', '.join(design.test1_paths)} × stand-offs {standoffs} m, at a peak speed of "
            f"{design.test1_peak_speed:g} m/s"
        )
    speeds = ", ".join(f"{name} ({speed:g} m/s)" for name, speed in design.test2_speed_sets)
    return f"paths {', '.join(design.test2_paths)} × speed sets {speeds}; after each speed set's group, a preference"


def _input_devices() -> list[str]:
    """How the participant stops the robot, per condition: the protocol's stop sources."""
    lines = [
        "## Input devices",
        "",
        "How a stop press is given, per condition (a press names its source). Each press's latency is recorded in two "
        "parts, from the input's change to its stamp and from the stamp to its arrival at the runner, and reported per "
        "source with the difference between the two conditions' sources.",
        "",
    ]
    for name, entry in PROTOCOL.data["stop_sources"].items():
        where = f"in {_CONDITION_NAMES[entry['condition']]}" if entry["condition"] else "in neither condition: flagged"
        lines.append(f"- `{name}` ({where}): {entry['meaning']}.")
    return lines


def _motion() -> list[str]:
    """What is recorded of the participant's body, what is derived from it per trial, and how it is compared: the
    protocol's pose topics and tracking gap, the analysis's measures."""
    lines = [
        "## The participant's motion (secondary, exploratory)",
        "",
        f"Recorded during every trial, at the tracker's frame rate: the head's and both hands' poses, each a "
        f"`{POSE_TYPE}` in the `{POSE_FRAME}` frame, stamped on the runner's clock. A body not tracked in a frame "
        "sends nothing for it.",
        "",
    ]
    for body in BODIES:
        lines.append(f"- `{POSE_TOPICS[body]}`: {PROTOCOL.data['poses']['bodies'][body]['meaning']}.")
    lines += [
        "",
        "The trackers: in VR, the headset's own tracking (the VR page); in reality, a tracker (a motion-capture "
        "driver's pose topics or TF frames, or the headset worn with passthrough), its bodies mapped to the head and "
        "hands by a configuration file. A tracker other than the headset is calibrated into the world frame at each "
        f"session's start: the experimenter touches at least {MIN_POINTS} marked points of the table and the hand "
        "model, not all in one plane (in one plane, a tracker whose frame is mirrored would fit as well as a proper "
        "one), the rigid transform is fitted by least squares, and a fit whose largest residual is above the bound "
        "the configuration declares is refused, as is one that a mirror image of the touches fits better, or whose "
        "touches are in another unit; the fit and its residuals, in-sample and each point left out, are recorded "
        "with the session. Each "
        "tracker's jitter (the RMS distance of a body's positions from their mean while it is held still) is "
        "measured at each session's start and reported beside the motion: the withdrawal's peak speed is sensitive "
        "to it. Each trial records the tracker that tracked it and its calibration (the headset worn in reality, "
        "not calibrated to the real table, counts as a tracker of its own); the report names the tracker each "
        "condition used, and where a participant's conditions were not tracked by one tracker with one calibration, "
        "every VR − reality contrast of a motion measure carries that caveat, as the tracker is then part of the "
        "contrast.",
        "",
        "Derived per trial, of the hand under the robot (of the two tracked hands, the one nearest the scene's hand "
        f"as the approach starts, within {HAND_RADIUS:g} m; recorded as `tracked_hand`) and the head:",
        "",
    ]
    lines += [f"- **{measure.label}** (`{measure.column}`): {measure.definition}." for measure in DEFINED]
    tests = " and ".join(
        f"test {test}'s {', '.join(m.label for m in MOTION_MEASURES if m.test == test)}"
        for test in sorted({m.test for m in MOTION_MEASURES}, reverse=True)
    )
    return lines + [
        f"- **untracked time** per body (`hand_untracked`, `head_untracked`): a body's poses further apart than "
        f"{TRACKING_GAP:g} s leave a gap in its tracking, and the approach's time in such gaps is untracked. A trial "
        "without a value of a measure (nothing tracked, no tracked hand at the scene's hand, no pose of the head, a "
        "tracking gap in the withdrawal's window, or no press) is left out of it, never read as 0; the report counts "
        "those trials per condition, and why, beside each contrast.",
        "",
        f"Compared as the stop distance is, each participant's mean per condition, then VR − reality in pairs with "
        f"its 95 % t interval: {tests}. Test 2's {MODELLED.label} also gets the crossover mixed model, "
        f"{formula(f'{MODELLED.label} (m)', FACTOR_NAMES[MODELLED.test])}. These are secondary and exploratory "
        "measures of comfort beside the press: no equivalence margin is declared for them and no verdict is drawn.",
    ]


def _scoring(instrument: Instrument) -> str:
    if instrument.rule == "weighted_sum":
        weights = ", ".join(f"{s.name} × {s.weight:g}" for s in instrument.subscales)
        total = (
            f"; {instrument.total.name}: {instrument.total.weight:g} × the sum of the raw sums"
            if instrument.total
            else ""
        )
        return f"each subscale's raw sum weighted ({weights}){total}"
    if len(instrument.items) == 1:
        return "its answer"
    reversed_ = [item.id for item in instrument.items if item.reversed]
    means = ", ".join(s.name for s in instrument.subscales)
    return f"the mean of each subscale's items ({means})" + (f", {', '.join(reversed_)} reversed" if reversed_ else "")


def _questionnaires(design: Design) -> list[str]:
    lines = ["## Questionnaires", ""]
    if not design.questionnaires:
        return lines + ["None declared."]
    lines += ["Asked in their place in every session, to check the measures' validity, not as outcomes:", ""]
    for declared in design.questionnaires:
        instrument = declared.instrument
        count = len(instrument.items)
        when = ", ".join(f"{position} {_CONDITION_NAMES[condition]}" for condition, position in declared.placements)
        lines.append(
            f"- **{instrument.title}** (`{instrument.name}`, {count} item{'s' if count != 1 else ''}), {when}; "
            f"scored as {_scoring(instrument)}."
        )
    return lines + [
        "",
        f"A participant whose SSQ total after VR is above {SSQ_SUSPECT_TOTAL:g} is named in the report as one whose VR "
        f"data are suspect, and stays in the analysis. {SSQ_SUSPECT_SOURCE}.",
    ]


def _power_table(sample: PlannedSample, test: int) -> list[str]:
    lines = ["| participants | P(equivalent) | P(different) |", "|---|---|---|"]
    lines += [f"| {r.participants} | {r.p_equivalent:.3f} | {r.p_different:.3f} |" for r in sample.rows[test]]
    return lines


def preregistration(design: Design, source: str, digest: str, sample: PlannedSample) -> str:
    """The Markdown summary of `design` (read from `source`, whose SHA-256 is `digest`) with its planned sample."""
    planning = design.planning
    assert planning is not None  # plan_sample refuses a design without one
    lines = [
        "# Pre-registration: VR against reality",
        "",
        f"Written by `python -m sim.study preregister` from `{source}` (SHA-256 `{digest}`). The analysis "
        "(`python -m sim.study analyse --design` with this file) judges by exactly what is declared here.",
        "",
        "## Hypotheses",
        "",
    ]
    for test in TESTS:
        lines.append(
            f"- **Test {test}.** {_HYPOTHESES[test]}: the VR − reality difference in {MEASURES[test]} lies within "
            f"±{design.sesoi[test]:g}{_UNITS[test]} (equivalence). The alternative: it lies outside, or is not 0."
        )
    lines += [
        "",
        "## Design",
        "",
        "Within participants: every participant does both conditions, VR and reality; odd participant numbers start "
        "with VR, even ones with reality. In each condition test 1 comes first, then test 2, each trial's order "
        "drawn from a seed per participant.",
        "",
    ]
    lines += [f"- Test {test}: {_factors(design, test)}." for test in TESTS]
    lines += [
        f"- {design.trials_per_participant} trials per participant.",
        "",
        "## Measures",
        "",
        "- Test 1: perceived / actual distance. The participant shows the distance between the robot and their "
        "hand; the actual one is the robot's distance to the hand's surface with the robot at rest (its nearest "
        "collision surface, or its end-effector point where the scene says so), from the recorded joint states.",
        "- Test 2: the robot's distance to the hand's surface when the participant's stop press lands, from the "
        "recorded joint state nearest the press. A trial without a press has no measure.",
        "",
        *_input_devices(),
        "",
        *_motion(),
        "",
        *_questionnaires(design),
        "",
        "## Smallest effects of interest",
        "",
        "| test | SESOI | why |",
        "|---|---|---|",
    ]
    for test in TESTS:
        reason = design.sesoi_reason.get(test, "(the design gives no reasoning)")
        lines.append(f"| {test} | ±{design.sesoi[test]:g}{_UNITS[test]} | {reason} |")
    lines += ["", "## Planned sample and its power", ""]
    assumed = "; ".join(
        f"test {test}: true VR − reality {planning.expected_difference[test]:+g}{_UNITS[test]}, SD of the "
        f"participants' own differences {planning.sd_between[test]:g}{_UNITS[test]}"
        for test in TESTS
    )
    lines.append(
        f"Simulated from the participant model ({sample.simulations} studies per size, seed {sample.seed}), each "
        f"analysed as the real study will be. Assumed: {assumed}. Wanted: P(equivalent) ≥ {planning.power:g} in "
        "both tests."
    )
    lines.append("")
    if sample.participants is not None:
        lines.append(f"**Planned: {sample.participants} participants.**")
    else:
        tried = max(r.participants for r in sample.rows[1])
        lines.append(f"**No size tried reaches the power wanted: more than {tried} participants are needed.**")
    for test in TESTS:
        lines += ["", f"Test {test}:", ""] + _power_table(sample, test)
    lines += [
        "",
        "## Models",
        "",
        "The primary analysis: a linear mixed model per test (statsmodels MixedLM, REML), fitted at the trial level "
        "to every trial with a measure, never to per-participant means:",
        "",
    ]
    for test in TESTS:
        lines.append(f"- Test {test}: {formula(MEASURES[test], FACTOR_NAMES[test])}.")
    lines += [
        "- Random effects: an intercept and a condition slope per participant (fitted without the slope only if no "
        "optimiser converges, which the report then says).",
        "- Condition (VR +½, reality −½), period (first block +½) and sequence (VR first +½) are coded ±½, the "
        "factors sum-to-zero: the condition's coefficient is the VR − reality difference averaged over the design's "
        "cells.",
        *(f"- {line}" for line in CROSSOVER_TERMS),
        "- Intervals: Student's t with participants − 2 degrees of freedom.",
        "",
        "## Missing trials",
        "",
        "A trial can lack its measure (no answer, no press, a trial voided by a tracking loss), and not at random: "
        "fast withdrawals and hands near the arm lose more trials, in some cells more than in others. A mean of the "
        "trials a participant kept would weigh the cells by how many each kept, and be biased. The trial-level model "
        "above has condition × factor × path as fixed effects, so its contrast is unbiased when the trials are "
        "missing at random given those (MAR). The report counts the missing trials per condition.",
        "",
        f"Sensitivity analysis (delta-adjusted multiple imputation, a pattern-mixture model): each missing trial is "
        f"imputed {IMPUTATIONS} times from the primary model (its fixed effects drawn from their sampling "
        "distribution, the participant's random effects given their observed trials, a residual); in each scenario "
        "one condition's imputed trials are shifted by δ; the model is refitted to each completed set, the "
        "contrasts pooled by Rubin's rules (Barnard–Rubin degrees of freedom) and judged by the decision rules "
        f"below. Scenarios: δ = 0 (MAR), and each condition's missing trials shifted by −SESOI and +SESOI "
        f"(seed {SEED}). The report states the verdict under each beside the primary one; the primary verdict is "
        "the one drawn, and a scenario that changes it is reported as a limit on it.",
        "",
        "## Decision rules",
        "",
        "For each test, on the condition's coefficient:",
        "",
        "- **equivalent** when its 90 % confidence interval lies inside ±SESOI (two one-sided tests at α = 0.05);",
        "- **different** when its 95 % confidence interval excludes 0;",
        "- **inconclusive** otherwise. A coefficient both equivalent and non-zero is reported as equivalent, and as "
        "non-zero.",
        "",
        "Secondary and descriptive, reported beside the verdicts: the paired TOST on each participant's mean per "
        "condition against the same SESOI, and Bland–Altman agreement (bias and 95 % limits); biased where trials "
        "are missing unevenly, so no verdict rests on them. No verdict is drawn from fewer than 3 "
        "participants with both conditions.",
    ]
    return "\n".join(lines) + "\n"
