"""sim.study.run.protocol: the table (protocol.json) as read and checked, the trial status a VR client reads, and
the answers it may give."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from sim.study.errors import StudyError
from sim.study.run.errors import RunError
from sim.study.run.protocol import (
    PROTOCOL,
    PROTOCOL_FILE,
    TrialStatus,
    checked_distance,
    chosen_path,
    load_protocol,
    observer_input,
    status_from_json,
    status_to_json,
)


def test_a_status_survives_json_and_absent_numbers_are_null() -> None:
    status = TrialStatus(
        3,
        7,
        38,
        "preference",
        "vr",
        2,
        "straight",
        0.02,
        0.3,
        "fast",
        2,
        12.5,
        ("straight", "lateral_arc", "over_the_top"),
    )
    assert status_from_json(status_to_json(status)) == status
    waiting = TrialStatus(3, 1, 38, "ready", "reality", 1, "vertical", 0.1, 0.15)
    data = json.loads(status_to_json(waiting))
    assert data["motion_start"] is None and data["group_paths"] == []
    back = status_from_json(status_to_json(waiting))
    assert math.isnan(back.motion_start) and back.group_paths == ()


@pytest.mark.parametrize(
    "text, problem",
    [
        ("{", "not JSON"),
        ('{"participant": 1}', "exactly"),
        (status_to_json(TrialStatus(1, 1, 2, "ready")).replace('"ready"', '"dancing"'), "unknown trial phase"),
    ],
)
def test_a_malformed_status_is_a_study_error(text: str, problem: str) -> None:
    with pytest.raises(StudyError, match=problem):
        status_from_json(text)


def test_answers_are_checked() -> None:
    assert checked_distance(0.12) == 0.12
    for bad in (-0.01, math.nan, math.inf, 2.5):
        with pytest.raises(StudyError, match="perceived distance"):
            checked_distance(bad)
    group = ("straight", "lateral_arc", "over_the_top")
    assert chosen_path("lateral_arc", group) == "lateral_arc"
    assert chosen_path(" 3\n", group) == "over_the_top"
    for bad in ("0", "4", "vertical", ""):
        with pytest.raises(StudyError, match="preference"):
            chosen_path(bad, group)


@pytest.mark.parametrize(
    "line, phase, kind, value",
    [
        ("\n", "ready", "go", None),
        ("s\n", "moving", "stop", None),
        ("STOP", "moving", "stop", None),
        ("0.12", "distance", "distance", 0.12),
        ("0.12 m", "distance", "distance", 0.12),
        ("12 cm\n", "distance", "distance", 0.12),
        ("2", "preference", "preference", "2"),
        ("lateral_arc", "preference", "preference", "lateral_arc"),
        ("near", "distance", "unknown", "not a distance"),
        ("2", "moving", "unknown", "means nothing in phase moving"),
    ],
)
def test_the_observers_keyboard_lines_are_read_in_their_phase(line: str, phase: str, kind: str, value) -> None:
    typed = observer_input(line, phase)
    assert typed.kind == kind
    if kind == "distance":
        assert typed.distance == pytest.approx(value)
    elif value is not None:
        assert value in typed.text


# --- the table ----------------------------------------------------------------------------------------------------


def test_the_table_gives_each_phase_at_most_one_input_and_each_condition_its_stop_source() -> None:
    assert [(phase.name, phase.accepts) for phase in PROTOCOL.phases] == [
        ("to_start", None),
        ("ready", "go"),
        ("moving", "stop"),
        ("at_rest", None),
        ("distance", "distance"),
        ("preference", "preference"),
        ("done", None),
    ]
    assert (PROTOCOL.stop_source("vr"), PROTOCOL.stop_source("reality")) == ("vr_trigger", "button")
    assert "keyboard" in PROTOCOL.stop_sources and PROTOCOL.max_perceived_distance == 2.0


def broken_table(tmp_path, change) -> Path:
    data = json.loads(PROTOCOL_FILE.read_text())
    change(data)
    path = tmp_path / "protocol.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize(
    "change, said",
    [
        (lambda d: d["phases"][1].update(accepts="wave"), "accepts 'wave', which is no input"),
        (lambda d: d["inputs"].pop("go"), "malformed"),
        (lambda d: d["phases"].pop(), "end with done"),
        (lambda d: d["phases"][2].pop("panel"), "says nothing on the VR panel"),
        (lambda d: d["limits"].pop("stamp_window_s"), "malformed"),
        (lambda d: d["status"].pop("type"), "needs a topic and a type"),
    ],
)
def test_a_malformed_table_is_one_error_that_says_what(tmp_path, change, said) -> None:
    with pytest.raises(RunError, match=said):
        load_protocol(broken_table(tmp_path, change))
