"""sim.study.run.records: the tidy CSV round-trips exactly, and a damaged one is refused with its line named."""

from __future__ import annotations

import math
from dataclasses import astuple, replace
from pathlib import Path

import pytest

from sim.study.errors import StudyError
from sim.study.run.records import TrialRecord, read_records, write_records

PRESSED = TrialRecord(
    4,
    12,
    "vr",
    1,
    2,
    "lateral_arc",
    0.02,
    0.2,
    "medium",
    3,
    101.26,
    True,
    2.4123,
    "vr_trigger",
    0.0,
    0.0612,
    0.0554,
    0.0619,
    0.0051,
    math.nan,
    "straight",
    0.0123,
    0.0041,
    "right_hand",
    0.034,
    0.21,
    0.52,
    0.0,
    0.016,
    pose_source="headset (uncalibrated)",
    calibration_id="",
    page_clock_offset=-3.5e-3,
    page_clock_uncertainty=1.25e-3,
    move_least_separation=0.3517,
)
RESTED = TrialRecord(
    4,
    3,
    "reality",
    2,
    1,
    "straight",
    0.15,
    0.15,
    "",
    0,
    20.04,
    False,
    math.nan,
    "",
    0.0,
    math.nan,
    0.1500,
    math.nan,
    0.0,
    0.1311,
    "",
)


def same_value(x: object, y: object) -> bool:
    return (x == y) or (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y))


def same(a: TrialRecord, b: TrialRecord) -> bool:
    return all(same_value(x, y) for x, y in zip(vars(a).values(), vars(b).values()))


def test_records_round_trip_exactly(tmp_path: Path) -> None:
    path = tmp_path / "participant_04.csv"
    write_records(path, [PRESSED, RESTED])
    back = read_records(path)
    assert len(back) == 2 and same(back[0], PRESSED) and same(back[1], RESTED)
    assert not list(tmp_path.glob("*.partial"))


def test_rewriting_replaces_the_file_whole(tmp_path: Path) -> None:
    path = tmp_path / "participant_04.csv"
    write_records(path, [PRESSED])
    write_records(path, [PRESSED, replace(PRESSED, index=13)])
    assert [record.index for record in read_records(path)] == [12, 13]


@pytest.mark.parametrize(
    "damage, problem",
    [
        (lambda text: text.replace("participant,", "person,", 1), "header"),
        (lambda text: text.replace("vr_trigger", "vr_trigger,extra"), "columns"),
        (lambda text: text.replace(",true,", ",yes,"), "column pressed"),
        (lambda text: text.replace(",12,", ",twelve,"), "column index"),
    ],
)
def test_a_damaged_file_is_refused_naming_where(tmp_path: Path, damage, problem: str) -> None:
    path = tmp_path / "participant_04.csv"
    write_records(path, [PRESSED])
    path.write_text(damage(path.read_text()))
    with pytest.raises(StudyError, match=problem):
        read_records(path)


def test_a_missing_file_is_a_study_error(tmp_path: Path) -> None:
    with pytest.raises(StudyError, match="cannot read"):
        read_records(tmp_path / "absent.csv")


GROUPS = [
    "press_input_delay",
    "tracked_hand",
    "link",
    "start_lead",
    "hand_monitored",
    "pose_source",
    "robot_clock_offset",
    "move_least_separation",
]


@pytest.mark.parametrize("first", GROUPS)
def test_a_file_written_before_a_group_of_columns_is_read_with_them_at_their_defaults(
    tmp_path: Path, first: str
) -> None:
    path = tmp_path / "participant_04.csv"
    write_records(path, [PRESSED])
    header, row = (line.split(",") for line in path.read_text().splitlines())
    kept = header.index(first)
    path.write_text(",".join(header[:kept]) + "\n" + ",".join(row[:kept]) + "\n")
    (back,) = read_records(path)
    later = {name: getattr(PRESSED, name) for name in header[kept:]}
    defaults = {name: getattr(TrialRecord(*astuple(PRESSED)[:kept]), name) for name in header[kept:]}
    assert same(replace(back, **later), PRESSED)
    assert all(same_value(getattr(back, name), value) for name, value in defaults.items())
    following = GROUPS[GROUPS.index(first) + 1 :]
    if kept + 1 < (header.index(following[0]) if following else len(header)):  # inside a group of several
        path.write_text(",".join(header[: kept + 1]) + "\n" + ",".join(row[: kept + 1]) + "\n")
        with pytest.raises(StudyError, match="header"):
            read_records(path)
