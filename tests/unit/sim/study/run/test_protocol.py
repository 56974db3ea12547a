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
    MAX_SEQ,
    PROTOCOL,
    PROTOCOL_FILE,
    Answer,
    TrialStatus,
    answer_from_json,
    answer_to_json,
    checked_answer,
    checked_distance,
    chosen_path,
    input_delay_from_seq,
    input_delay_seq,
    item_prompt,
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
        (" 3\n", "questionnaire", "answer", 3),
        ("-1", "questionnaire", "answer", -1),
        ("2.5", "questionnaire", "unknown", "not an answer"),
        ("severe", "questionnaire", "unknown", "not an answer"),
    ],
)
def test_the_observers_keyboard_lines_are_read_in_their_phase(line: str, phase: str, kind: str, value) -> None:
    typed = observer_input(line, phase)
    assert typed.kind == kind
    if kind == "distance":
        assert typed.distance == pytest.approx(value)
    elif kind == "answer":
        assert typed.answer == value
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
        ("questionnaire", "answer"),
        ("done", None),
    ]
    assert (PROTOCOL.stop_source("vr"), PROTOCOL.stop_source("reality")) == ("vr_trigger", "button")
    assert "keyboard" in PROTOCOL.stop_sources and PROTOCOL.max_perceived_distance == 2.0
    assert list(PROTOCOL.poses) == ["head", "left_hand", "right_hand"] and PROTOCOL.pose_frame == "world"
    assert all(kind == "geometry_msgs/PoseStamped" for _, kind in PROTOCOL.poses.values())


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
        (lambda d: d["inputs"]["answer"].update(type="std_msgs/Int32"), "input answer must be a std_msgs/String"),
        (lambda d: d["poses"]["bodies"].pop("head"), "malformed"),
        (
            lambda d: d["poses"]["bodies"].update(torso=d["poses"]["bodies"]["head"]),
            "the poses must be exactly head, left_hand, right_hand",
        ),
        (
            lambda d: d["poses"]["bodies"]["head"].update(type="geometry_msgs/Pose"),
            "pose head must be a geometry_msgs/PoseStamped",
        ),
        (lambda d: d["limits"].update(tracking_gap_s=0), "the tracking gap must be > 0 s"),
    ],
)
def test_a_malformed_table_is_one_error_that_says_what(tmp_path, change, said) -> None:
    with pytest.raises(RunError, match=said):
        load_protocol(broken_table(tmp_path, change))


# --- questionnaires ------------------------------------------------------------------------------------------------

ITEM = TrialStatus(
    5,
    0,
    38,
    "questionnaire",
    "vr",
    administration="ssq_before_vr",
    questionnaire="ssq",
    item="nausea",
    item_text="Nausea",
    item_number=4,
    item_count=16,
    scale_low=0,
    scale_high=3,
    scale_labels=("none", "slight", "moderate", "severe"),
)


def test_an_items_status_carries_what_an_answerer_needs() -> None:
    assert status_from_json(status_to_json(ITEM)) == ITEM
    data = json.loads(status_to_json(ITEM))
    assert data["scale_labels"] == ["none", "slight", "moderate", "severe"] and data["item_text"] == "Nausea"
    assert item_prompt(ITEM) == "ssq_before_vr, item 4 of 16 (nausea): Nausea [0 none, 1 slight, 2 moderate, 3 severe]?"
    unlabelled = TrialStatus(
        5, 38, 38, "questionnaire", "vr", item_text="Safe?", scale_low=1, scale_high=3, scale_labels=("no", "", "yes")
    )
    assert item_prompt(unlabelled).endswith("Safe? [1 no, 2, 3 yes]?")


def test_an_answer_survives_json_and_must_be_a_whole_number() -> None:
    answer = Answer("ssq_before_vr", "nausea", 2)
    assert answer_from_json(answer_to_json(answer)) == answer
    assert answer_from_json('{"administration": "a_x", "item": "G1", "answer": 3.0}').answer == 3
    for text, said in [
        ("[", "not JSON"),
        ('{"administration": "a", "item": "b"}', "exactly"),
        ('{"administration": "a", "item": 1, "answer": 1}', "must be texts"),
        ('{"administration": "a", "item": "b", "answer": 2.5}', "whole number, got 2.5"),
        ('{"administration": "a", "item": "b", "answer": true}', "whole number, got True"),
        ('{"administration": "a", "item": "b", "answer": "2"}', "whole number, got '2'"),
    ]:
        with pytest.raises(RunError, match=said):
            answer_from_json(text)


def test_an_answer_counts_for_the_item_asked_and_on_its_scale() -> None:
    assert checked_answer(Answer("ssq_before_vr", "nausea", 3), ITEM) == 3
    assert checked_answer(Answer("ssq_before_vr", "nausea", 0), ITEM) == 0
    for answer, said in [
        (Answer("ssq_before_vr", "nausea", 4), "the answer 4 is not one of 0..3"),
        (Answer("ssq_before_vr", "nausea", -1), "the answer -1 is not one of 0..3"),
        (Answer("ssq_before_vr", "vertigo", 1), "an answer to ssq_before_vr item 'vertigo' while"),
        (Answer("ssq_after_vr", "nausea", 1), "an answer to ssq_after_vr"),
    ]:
        with pytest.raises(RunError, match=said):
            checked_answer(answer, ITEM)
    with pytest.raises(RunError, match="no questionnaire item is asked in phase ready"):
        checked_answer(Answer("ssq_before_vr", "nausea", 1), TrialStatus(5, 1, 38, "ready"))


def test_a_stops_input_delay_goes_in_its_seq_in_microseconds_zero_when_not_measured() -> None:
    assert input_delay_seq(0.0083) == 8300 and input_delay_from_seq(8300) == pytest.approx(0.0083)
    assert input_delay_seq(0.0) == 1  # measured, and under a microsecond: never 0, which says "not measured"
    assert input_delay_seq(math.nan) == input_delay_seq(-0.002) == 0 and math.isnan(input_delay_from_seq(0))
    assert input_delay_seq(1e9) == MAX_SEQ  # a uint32
    with pytest.raises(StudyError, match="seq"):
        input_delay_from_seq(-1)
