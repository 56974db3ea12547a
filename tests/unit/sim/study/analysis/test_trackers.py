"""sim.study.analysis.trackers: each condition's tracker, its jitter and calibration, from the sessions' tracking
records; the caveat on every motion contrast when the conditions' trials were tracked by different trackers or
calibrations, by the trials' rows (a source changed mid-session counted trial by trial; rows written before the
source's columns by their session's record), and none when by one; and the report that carries both."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from sim.study.analysis.report import write_report
from sim.study.analysis.trackers import (
    load_trackers,
    summarise_trackers,
    tracker_caveat,
    tracker_lines,
    trial_sources,
)
from sim.study.errors import StudyError
from sim.study.run.records import TrialRecord
from sim.study.run.tracking import calibration_id
from tests.unit.sim.study.analysis.test_motion import tracked_study

FIT = {"residual_rms_m": 0.0012, "residual_max_m": 0.0021}
FIT_ID = calibration_id(FIT)
PER_CONDITION = sum(r.condition == "vr" for r in tracked_study(1))  # one participant's trials in a condition


def session(participant: int, vr: str, reality: str) -> dict:
    mocap = {"source": reality, "jitter_m": {"head": 0.0001 * participant, "right_hand": 0.0002}, "calibration": FIT}
    headset = {"source": vr, "jitter_m": {}, "calibration": None}
    return {"participant": participant, "conditions": {"vr": headset, "reality": mocap}}


def sourced(records: list[TrialRecord], vr: tuple[str, str], reality: tuple[str, str]) -> list[TrialRecord]:
    """`records` with each condition's rows tracked by (source, calibration id)."""
    by = {"vr": vr, "reality": reality}
    return [replace(r, pose_source=by[r.condition][0], calibration_id=by[r.condition][1]) for r in records]


def test_differing_trackers_are_named_with_their_jitter_and_carry_the_caveat() -> None:
    summary = summarise_trackers([session(p, "headset", "optitrack") for p in (1, 2, 3)])
    assert summary is not None
    reality = summary.conditions["reality"]
    assert reality.sources == {"optitrack": 3} and reality.calibrated == 3
    assert reality.jitter["head"] == pytest.approx((0.0002, 0.0003, 3))
    assert reality.residual_rms == pytest.approx(0.0012) and "head" not in summary.conditions["vr"].jitter
    # rows written before the trial's source: each takes its session record's source for its condition
    sources = trial_sources(tracked_study(3), summary)
    assert sources is not None and sources.differing == (1, 2, 3) and sources.paired == 3
    caveat = tracker_caveat(sources)
    assert "different trackers or calibrations (or one unnamed) for 3 of 3 participants" in caveat
    n = PER_CONDITION * 3
    assert (
        f"vr: headset (3 participants, {n} trials); reality: optitrack (calibration {FIT_ID}) (3 participants, "
        f"{n} trials)" in caveat
    )
    lines = "\n".join(tracker_lines(summary, sources))
    assert (
        "| reality | optitrack (3) | 0.20 (most 0.30, n 3) |" in lines
        and "| vr | headset (3) | not measured |" in lines
    )


def test_the_headsets_jitter_as_the_vr_page_announces_it_a_body_not_tracked_at_rest_not_measured() -> None:
    # the page's rest: the head and the right hand measured, the left hand not tracked in it (null, never 0)
    headset = {"source": "headset", "jitter_m": {"head": 0.0001, "left_hand": None, "right_hand": 0.0004}}
    summary = summarise_trackers([{"participant": 1, "conditions": {"vr": {**headset, "rest_s": 3.0}}}])
    assert summary is not None
    assert summary.conditions["vr"].jitter == {"head": (0.0001, 0.0001, 1), "right_hand": (0.0004, 0.0004, 1)}
    lines = "\n".join(tracker_lines(summary))
    assert "| vr | headset (1) | 0.10 (most 0.10, n 1) | not measured | 0.40 (most 0.40, n 1) |" in lines


def test_the_same_tracker_in_both_conditions_carries_no_caveat_and_an_unnamed_one_does() -> None:
    fitted = (("optitrack", FIT_ID), ("optitrack", FIT_ID))
    same = trial_sources(sourced(tracked_study(2), *fitted))
    assert same is not None and same.differing == () and same.paired == 2 and tracker_caveat(same) == ""
    summary = summarise_trackers([session(p, "optitrack", "optitrack") for p in (1, 2)])
    assert "had the same tracker (and calibration) in every trial of both" in "\n".join(tracker_lines(summary, same))
    unnamed = trial_sources(sourced(tracked_study(1), ("unnamed", ""), ("unnamed", "")))
    assert unnamed is not None and unnamed.differing == (1,)
    assert f"unnamed (1 participant, {PER_CONDITION} trials)" in tracker_caveat(unnamed)
    untracked = [replace(r, hand_untracked=float("nan"), head_untracked=float("nan")) for r in tracked_study(1)]
    assert trial_sources(untracked) is None and tracker_caveat(None) == ""
    assert trial_sources(tracked_study(1)) is None  # rows written before the source's, and no session's record
    assert summarise_trackers([]) is None


def test_the_caveat_follows_the_trials_rows_not_the_sessions_records() -> None:
    # `vr --pose-conditions vr,reality`: the headset's uncalibrated poses in reality are a source of their own
    headset = summarise_trackers([session(p, "headset", "headset") for p in (1, 2)])
    rows = sourced(tracked_study(2), ("headset", ""), ("headset (uncalibrated)", ""))
    sources = trial_sources(rows, headset)
    assert sources is not None and sources.differing == (1, 2)
    assert "reality: headset (uncalibrated) (2 participants" in tracker_caveat(sources)
    # records that differ, rows that agree: no caveat
    differing = summarise_trackers([session(p, "headset", "optitrack") for p in (1, 2)])
    same = trial_sources(sourced(tracked_study(2), ("optitrack", FIT_ID), ("optitrack", FIT_ID)), differing)
    assert tracker_caveat(same) == ""
    # one tracker, calibrated anew between the conditions: its fits differ by up to their residuals
    refitted = trial_sources(sourced(tracked_study(2), ("optitrack", FIT_ID), ("optitrack", "0badf175")))
    assert refitted is not None and refitted.differing == (1, 2)
    assert "reality: optitrack (calibration 0badf175) (2 participants" in tracker_caveat(refitted)


def test_a_source_changed_mid_session_is_counted_trial_by_trial() -> None:
    # participant 1's reality: the headset worn with passthrough for the first trials, then the calibrated mocap;
    # its session's record names the latest alone
    rows = sourced(tracked_study(2), ("optitrack", FIT_ID), ("optitrack", FIT_ID))
    reality_1 = [k for k, r in enumerate(rows) if r.participant == 1 and r.condition == "reality"]
    for k in reality_1[:3]:
        rows[k] = replace(rows[k], pose_source="headset (uncalibrated)", calibration_id="")
    summary = summarise_trackers([session(p, "optitrack", "optitrack") for p in (1, 2)])
    sources = trial_sources(rows, summary)
    assert sources is not None and sources.differing == (1,) and sources.paired == 2
    assert sources.conditions["reality"] == {
        "headset (uncalibrated)": (1, 3),
        f"optitrack (calibration {FIT_ID})": (2, 2 * PER_CONDITION - 3),
    }
    caveat = tracker_caveat(sources)
    assert "for 1 of 2 participants" in caveat and "headset (uncalibrated) (1 participant, 3 trials)" in caveat


def test_the_report_names_the_trackers_and_puts_the_caveat_beside_the_contrasts(tmp_path: Path) -> None:
    folder = tmp_path / "tracking"
    folder.mkdir()
    for p in range(1, 13):
        (folder / f"participant_{p:02d}.json").write_text(json.dumps(session(p, "headset", "optitrack")))
    trackers = summarise_trackers(load_trackers(tmp_path))
    report = write_report(tracked_study(), tmp_path, trackers=trackers).read_text()
    motion = report.split("## The participant's motion")[1].split("\n## ")[0]
    caveat = motion.index("**Caveat on every VR − reality contrast here** (test 2's withdrawal distance, ")
    assert motion.index("| 2 | withdrawal distance (cm) |") < caveat < motion.index("| reality | optitrack (12) |")
    (folder / "participant_13.json").write_text("[]")
    with pytest.raises(StudyError, match="is not a session's tracking record"):
        load_trackers(tmp_path)
