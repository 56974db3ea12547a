"""sim.study.analysis.motion on records of known motion: the VR − reality withdrawal put in comes out (paired and
from the mixed model), the tracking gaps are summed per condition and body, trials without a body's poses are left
out and named, and records without any motion say so in the report instead of failing."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from sim.study.analysis.motion import MODELLED, motion_lines, motion_recorded, summarise_motion
from sim.study.analysis.report import write_report
from sim.study.errors import StudyError
from sim.study.run.records import TrialRecord
from tests.unit.sim.study.analysis.test_summary import study

VR_MORE = 0.02  # m: the participants withdraw this much farther in VR, on average


def difference(participant: int) -> float:
    """A participant's own VR − reality withdrawal (m): around VR_MORE, ±5 mm, averaging VR_MORE over 1..12."""
    return VR_MORE + 0.005 * ((participant % 3) - 1)


def moved(record: TrialRecord) -> TrialRecord:
    """`record` with a tracked right hand and head, no gaps: the withdrawal VR_MORE farther in VR (by the
    participant's own difference), 1 cm less in test 1; the head 5 cm nearer the robot in VR; peak speed 0.3 m/s in
    reality, 0.4 in VR."""
    vr = record.condition == "vr"
    withdrawal = 0.03 + 0.002 * record.participant + (difference(record.participant) if vr else 0.0)
    if record.test == 1:
        withdrawal -= 0.01
    return replace(
        record,
        tracked_hand="right_hand",
        withdrawal_distance=withdrawal,
        withdrawal_peak_speed=0.4 if vr else 0.3,
        head_distance_at_press=(0.40 if vr else 0.45) if record.pressed else math.nan,
        hand_untracked=0.0,
        head_untracked=0.0,
    )


def tracked_study(participants: int = 12) -> list[TrialRecord]:
    return [moved(record) for record in study(participants)]


def test_the_vr_withdrawal_put_in_is_recovered_per_condition_and_in_pairs() -> None:
    summary = summarise_motion(tracked_study())
    assert summary.recorded and summary.notes == ()
    by_name = {(c.measure.test, c.measure.column): c for c in summary.comparisons}
    assert list(by_name) == [
        (2, "withdrawal_distance"),
        (2, "withdrawal_peak_speed"),
        (2, "head_distance_at_press"),
        (1, "withdrawal_distance"),
    ]
    withdrawal = by_name[2, "withdrawal_distance"]
    paired = withdrawal.vr_vs_reality
    assert paired is not None and paired.n == 12
    assert paired.mean_difference == pytest.approx(VR_MORE) and paired.ci_low < VR_MORE < paired.ci_high
    assert paired.ci_low > 0.0 and paired.t_p < 0.001
    reality_mean = 0.03 + 0.002 * 6.5  # participants 1..12
    assert withdrawal.conditions["reality"].mean == pytest.approx(reality_mean)
    assert withdrawal.conditions["vr"].mean == pytest.approx(reality_mean + VR_MORE)
    speed, head = by_name[2, "withdrawal_peak_speed"].vr_vs_reality, by_name[2, "head_distance_at_press"].vr_vs_reality
    assert speed is not None and speed.mean_difference == pytest.approx(0.1)
    assert head is not None and head.mean_difference == pytest.approx(-0.05)
    test1 = by_name[1, "withdrawal_distance"]
    assert test1.conditions["reality"].mean == pytest.approx(reality_mean - 0.01)
    assert test1.vr_vs_reality is not None and test1.vr_vs_reality.mean_difference == pytest.approx(VR_MORE)
    assert all(c.model is None for c in summary.comparisons)  # only when asked


def test_the_mixed_model_recovers_the_withdrawal_contrast() -> None:
    summary = summarise_motion(tracked_study(), model=True)
    fits = {c.measure: c.model for c in summary.comparisons if c.model is not None}
    assert list(fits) == [MODELLED]  # test 2's withdrawal distance only
    fit = fits[MODELLED]
    assert fit is not None and fit.participants == 12 and fit.trials == 12 * 18
    assert fit.contrast.estimate == pytest.approx(VR_MORE, abs=1e-6)  # complete data: the paired mean
    assert fit.contrast.ci_low < VR_MORE < fit.contrast.ci_high
    line = "\n".join(motion_lines(summary))
    assert "withdrawal distance (cm) ~ condition × speed set × path + period + sequence" in line
    assert "VR − reality +2.0 cm [+1." in line


def test_gaps_are_summed_per_condition_and_body_and_untracked_trials_are_named() -> None:
    records = tracked_study(participants=4)
    vr_test2 = [k for k, r in enumerate(records) if r.condition == "vr" and r.test == 2]
    records[vr_test2[0]] = replace(records[vr_test2[0]], hand_untracked=0.25)
    records[vr_test2[1]] = replace(records[vr_test2[1]], hand_untracked=0.5, head_untracked=0.2)
    untracked_hand = [k for k, r in enumerate(records) if r.participant == 3 and r.condition == "reality"]
    for k in untracked_hand:  # participant 3's hand in reality: never seen
        records[k] = replace(records[k], tracked_hand="", withdrawal_distance=math.nan, hand_untracked=math.nan)
    # a withdrawal the runner should not have written for an untracked hand is left out all the same
    k = next(k for k, r in enumerate(records) if r.participant == 4 and r.condition == "reality" and r.test == 2)
    records[k] = replace(records[k], tracked_hand="", hand_untracked=math.nan, withdrawal_distance=5.0)
    # a hand seen, with a gap in the withdrawal's window: its withdrawal is missing, and counted apart
    gapped = vr_test2[2]
    records[gapped] = replace(records[gapped], withdrawal_distance=math.nan, withdrawal_peak_speed=math.nan)
    summary = summarise_motion(records, model=True)
    vr, reality = summary.tracking["vr"], summary.tracking["reality"]
    trials = len(records) // 2
    assert vr.trials == reality.trials == trials
    assert vr.bodies["hand"].tracked == trials and vr.bodies["hand"].with_gap == 2
    assert vr.bodies["hand"].untracked_total == pytest.approx(0.75) and vr.bodies["hand"].untracked_most == 0.5
    assert vr.bodies["head"].with_gap == 1 and vr.bodies["head"].untracked_total == pytest.approx(0.2)
    assert reality.bodies["hand"].tracked == trials - len(untracked_hand) - 1
    assert reality.bodies["hand"].with_gap == 0 and reality.bodies["hand"].untracked_most == 0.0
    assert reality.hands == {"right_hand": trials - len(untracked_hand) - 1}
    assert summary.untracked == {"hand": {3: {"reality": len(untracked_hand)}, 4: {"reality": 1}}, "head": {}}
    withdrawal = summary.comparisons[0]
    assert withdrawal.vr_vs_reality is not None and withdrawal.vr_vs_reality.n == 3  # participant 3 left out
    assert withdrawal.conditions["reality"].n == 3 and withdrawal.conditions["reality"].mean < 1.0
    # the model leaves participant 3 out too, rather than refusing the whole study for them (3 are then too few)
    assert summary.notes == (
        "test 2's withdrawal distance: no mixed model: 3 participants in 2 sequences leave too few to compare",
    )
    lines = "\n".join(motion_lines(summary))
    assert "| vr | 56 | 56 | 2 | 0.75 | 0.50 | 56 | 1 | 0.20 | 0.20 |" in lines
    assert (
        "Trials in which no tracked hand was at the scene's hand as the approach started (neither hand sent a pose, "
        "or neither was within 25 cm of it), left out of its measures: participant 3 (14 in reality); "
        "participant 4 (1 in reality)." in lines
    )
    # beside each contrast, the trials it leaves out per condition, and why
    reality_test2 = sum(1 for k in untracked_hand if records[k].test == 2) + 1
    assert withdrawal.left_out == {"reality": {"hand": reality_test2}, "vr": {"gap": 1}}
    assert f"| {reality_test2}; 1 |" in lines.split("withdrawal distance (cm)")[1].split("\n")[0]
    assert (
        f"- test 2's withdrawal distance: reality {reality_test2} ({reality_test2} no tracked hand at the scene's "
        "hand); vr 1 (1 a tracking gap in the withdrawal's window)" in lines
    )
    assert "0.1 s (the protocol's tracking gap)" in lines


def test_too_few_participants_with_a_value_are_said_not_raised() -> None:
    records = tracked_study(participants=4)
    # only participant 1 has a head distance in VR: no mean there, and no pair
    records = [
        r if r.condition == "reality" or r.participant == 1 else replace(r, head_untracked=math.nan) for r in records
    ]
    summary = summarise_motion(records, model=True)
    head = next(c for c in summary.comparisons if c.measure.column == "head_distance_at_press")
    assert "vr" not in head.conditions and "reality" in head.conditions and head.vr_vs_reality is None
    assert summary.notes == (
        "test 2's head to the end effector at the press in vr: 1 participant(s) with a value, too few for a mean",
        "test 2's head to the end effector at the press: 1 participant(s) with a value in both conditions, too few "
        "to compare",
    )
    lines = "\n".join(motion_lines(summary))
    assert "| 2 | head to the end effector at the press (cm) | 45.0 [45.0, 45.0] (n 4) | – | – | – | – | – |" in lines
    withdrawal = summary.comparisons[0]
    assert withdrawal.model is not None and withdrawal.model.participants == 4
    three = summarise_motion(tracked_study(participants=3), model=True)  # 1 df: too few for the model
    assert three.comparisons[0].model is None
    assert three.notes == (
        "test 2's withdrawal distance: no mixed model: 3 participants in 2 sequences leave too few to compare",
    )


def test_records_without_motion_say_so() -> None:
    old = study(participants=3)  # as read from a file written before the motion's columns
    assert not motion_recorded(old)
    summary = summarise_motion(old, model=True)
    assert not summary.recorded and summary.comparisons == () and summary.tracking == {}
    assert "No motion was recorded" in "\n".join(motion_lines(summary))
    with pytest.raises(StudyError, match="no trial records"):
        summarise_motion([])


def test_the_report_has_the_motion_section_or_says_none_was_recorded(tmp_path: Path) -> None:
    report = write_report(tracked_study(participants=4), tmp_path / "tracked", sesoi={1: 0.05, 2: 0.02}).read_text()
    section = report.index("## The participant's motion")
    assert report.index("## Test 2: comfort distance") < section < report.index("## Stop presses: latency")
    assert "| 2 | withdrawal distance (cm) | " in report and "| 1 | withdrawal distance (cm) | " in report
    assert "Test 2's withdrawal distance in the stop distance's crossover mixed model" in report  # with the design
    old = write_report(study(participants=4), tmp_path / "old").read_text()
    assert "## The participant's motion\n\nNo motion was recorded" in old


def test_a_measure_with_every_trial_left_out_says_why() -> None:
    """Every test 1 withdrawal missing (a gap in its window in VR; no hand at the scene's hand in reality): no row
    for it, and a note that says how many were left out, and why, per condition."""
    records = [
        r
        if r.test == 2
        else replace(r, withdrawal_distance=math.nan)
        if r.condition == "vr"
        else replace(r, tracked_hand="", hand_untracked=math.nan, withdrawal_distance=math.nan)
        for r in tracked_study(participants=4)
    ]
    summary = summarise_motion(records)
    assert [(c.measure.test, c.measure.column) for c in summary.comparisons][-1] == (2, "head_distance_at_press")
    per_condition = sum(1 for r in records if r.test == 1 and r.condition == "vr")
    assert (
        f"no test 1 trial has a withdrawal distance: all left out, reality {per_condition} ({per_condition} no "
        f"tracked hand at the scene's hand); vr {per_condition} ({per_condition} a tracking gap in the withdrawal's "
        "window)" in summary.notes
    )
