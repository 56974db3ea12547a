"""sim.study.analysis.trackers: each condition's tracker, its jitter and calibration, from the sessions' tracking
records; the caveat on every motion contrast when the conditions' trackers differ, and none when they are the
same; and the report that carries both."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sim.study.analysis.report import write_report
from sim.study.analysis.trackers import load_trackers, summarise_trackers, tracker_caveat, tracker_lines
from sim.study.errors import StudyError
from tests.unit.sim.study.analysis.test_motion import tracked_study

FIT = {"residual_rms_m": 0.0012, "residual_max_m": 0.0021}


def session(participant: int, vr: str, reality: str) -> dict:
    mocap = {"source": reality, "jitter_m": {"head": 0.0001 * participant, "right_hand": 0.0002}, "calibration": FIT}
    headset = {"source": vr, "jitter_m": {}, "calibration": None}
    return {"participant": participant, "conditions": {"vr": headset, "reality": mocap}}


def test_differing_trackers_are_named_with_their_jitter_and_carry_the_caveat() -> None:
    summary = summarise_trackers([session(p, "headset", "optitrack") for p in (1, 2, 3)])
    assert summary is not None and summary.differing == (1, 2, 3) and summary.paired == 3
    reality = summary.conditions["reality"]
    assert reality.sources == {"optitrack": 3} and reality.calibrated == 3
    assert reality.jitter["head"] == pytest.approx((0.0002, 0.0003, 3))
    assert reality.residual_rms == pytest.approx(0.0012) and "head" not in summary.conditions["vr"].jitter
    caveat = tracker_caveat(summary)
    assert "different trackers (or one unnamed) for 3 of 3 participants" in caveat
    assert "vr: headset (3); reality: optitrack (3)" in caveat
    lines = "\n".join(tracker_lines(summary))
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
    same = summarise_trackers([session(p, "optitrack", "optitrack") for p in (1, 2)])
    assert same is not None and same.differing == () and tracker_caveat(same) == ""
    assert "had the same tracker in both" in "\n".join(tracker_lines(same))
    unnamed = summarise_trackers([session(1, "", "")])
    assert unnamed is not None and unnamed.differing == (1,) and "unnamed (1)" in tracker_caveat(unnamed)
    assert summarise_trackers([]) is None and tracker_caveat(None) == ""


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
