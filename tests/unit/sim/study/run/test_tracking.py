"""sim.study.run.tracking: a tracker's configuration (its calibration's points refused when they lie in one plane),
the scene's marked points, the announcement, each trial's pose source (the headset's uncalibrated poses in reality
named apart, a fit by its id) and the session's record of its pose sources; a touch whose poses are
not finite is taken again; a saved fit of another scene, tracker, frame or tip is refused naming what differs; and
the tracker command's refusals of a saved fit (above the bound, mirrored, malformed): one line, exit 2."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from sim.study.__main__ import main
from sim.study.design.scene import load_scene, scene_robot
from sim.study.errors import StudyError
from sim.study.motion.calibration import fit_calibration
from sim.study.run.tracker import held_problem
from sim.study.run.tracking import (
    DEFAULT_POINTS,
    BodySource,
    PoseSource,
    announcement,
    announcement_from_json,
    calibration_id,
    marked_points,
    saved_calibration,
    session_tracking,
    tracker_config,
    trial_source,
)
from sim.study.views.vr.site import page_settings, pose_conditions_from

SCENE = load_scene()
POINTS = marked_points(SCENE)
CONFIG = {
    "source": "optitrack",
    "frame": "mocap",
    "conditions": ["reality"],
    "bodies": {
        "head": {"topic": "/vrpn_client_node/head/pose"},
        "right_hand": {"topic": "/vrpn_client_node/right_hand/pose"},
        "left_hand": {"tf": "left_hand"},
    },
    "calibration": {
        "body": "right_hand",
        "points": ["hand_fingertips", "table_corner_1", "table_corner_2", "table_corner_3"],
    },
}
CORNERS = ["table_corner_1", "table_corner_2", "table_corner_3", "table_corner_4"]


def test_a_config_maps_topics_and_tf_frames_to_bodies() -> None:
    config = tracker_config(CONFIG, SCENE)
    assert config.bodies["head"] == BodySource(topic="/vrpn_client_node/head/pose")
    assert config.bodies["left_hand"] == BodySource(tf="left_hand")
    assert config.conditions == ("reality",) and config.calibration.max_residual == 0.01 and config.rest == 3.0
    assert config.stamp == "source" and tracker_config({**CONFIG, "stamp": "arrival"}, SCENE).stamp == "arrival"
    assert config.calibration.tip == 0.0
    marker = tracker_config({**CONFIG, "calibration": {**CONFIG["calibration"], "tip": 0.007}}, SCENE)
    assert marker.calibration.tip == 0.007


@pytest.mark.parametrize(
    ("change", "problem"),
    [
        ({"frame": "world"}, "named 'world', as the scene's"),
        ({"bodies": {"torso": {"topic": "/t"}}}, "unknown body 'torso'"),
        ({"bodies": {"head": {"topic": "/h", "tf": "h"}}}, "needs one of topic or tf"),
        ({"conditions": ["lab"]}, "conditions must be some of vr, reality"),
        ({"calibration": {"body": "left_hand", "points": ["hand_wrist", "a_cup", "table_corner_1"]}}, "'a_cup'"),
        ({"calibration": {"points": ["hand_wrist", "table_corner_1", "table_corner_3"]}}, "must be 4 or more"),
        ({"calibration": {"points": CORNERS}}, "calibration's points lie near one plane .RMS 0.0 mm"),
        # the hand's two ends and two corners on their line: in one plane too, tilted
        ({"calibration": {"points": ["hand_fingertips", "hand_wrist", *CORNERS[:2]]}}, "lie near one plane"),
        ({"calibration": {"points": [*CORNERS, "hand_wrist"], "max_residual": 0.02}}, "bound's 20.0 mm needed"),
        ({"calibration": {"tip": -0.007}}, "tip must be a length in m, 0 or more"),
        ({"calibration": {"body": "right_hand", "max_residual": -1}}, "max_residual must be a positive number"),
        ({"rest": 0}, "rest must be a positive number"),
        ({"stamp": "now"}, "stamp must be one of source, arrival"),
        ({"colour": "red"}, "unknown key 'colour'"),
    ],
)
def test_a_config_that_cannot_be_used_is_refused_naming_the_problem(change: dict, problem: str) -> None:
    with pytest.raises(StudyError, match=problem):
        tracker_config({**CONFIG, **change}, SCENE)


def test_the_marked_points_are_the_scenes() -> None:
    points = marked_points(SCENE)
    # the hand model's ends on its top (0.19 m long, its top at 3.5 cm), the table top's corners (1.4 x 1.0 m at z 0)
    assert np.allclose(points["hand_fingertips"], [0.645, 0.0, 0.035])
    assert np.allclose(points["hand_wrist"], [0.455, 0.0, 0.035])
    assert np.allclose(points["table_corner_1"], [-0.3, -0.5, 0.0]) and np.allclose(
        points["table_corner_3"], [1.1, 0.5, 0.0]
    )


def test_the_session_records_each_conditions_source() -> None:
    said = announcement_from_json(
        announcement("optitrack", ("reality",), {"head": 0.0002}, 3.0, {"residual_rms_m": 0.001})
    )
    record = session_tracking(4, {"vr", "reality"}, {"reality": said}, {"vr": "headset"})
    assert record["conditions"]["reality"]["source"] == "optitrack"
    assert record["conditions"]["reality"]["jitter_m"] == {"head": 0.0002}
    assert record["conditions"]["vr"] == {"source": "headset", "jitter_m": {}, "calibration": None}
    assert session_tracking(4, {"vr"}, {}, {})["conditions"] == {
        "vr": {"source": "", "jitter_m": {}, "calibration": None}
    }
    # a name on the command line overrides an announcement of another source; of the same, it keeps its figures
    assert session_tracking(4, {"reality"}, {"reality": said}, {"reality": "vicon"})["conditions"]["reality"] == {
        "source": "vicon",
        "jitter_m": {},
        "calibration": None,
    }
    same = session_tracking(4, {"reality"}, {"reality": said}, {"reality": "optitrack"})["conditions"]["reality"]
    assert same["source"] == "optitrack" and same["jitter_m"] == {"head": 0.0002}
    with pytest.raises(StudyError, match="names no source"):
        announcement_from_json('{"conditions": []}')


# what the VR page announces of itself with `vr --pose-conditions vr,reality` (a headset worn with passthrough)
HEADSET = page_settings(scene_robot(SCENE), SCENE, pose_conditions_from("vr,reality"))["pose_source"]
FIT = {"source": "optitrack", "frame": "mocap", "residual_rms_m": 0.001, "rotation": [[1.0, 0.0, 0.0]] * 3}


def test_the_headsets_poses_in_reality_are_a_source_of_their_own_uncalibrated() -> None:
    said = announcement_from_json(json.dumps(HEADSET))
    assert trial_source("vr", said, None) == PoseSource("headset", "")
    assert trial_source("reality", said, None) == PoseSource("headset (uncalibrated)", "")
    # named by hand as what it announces, it is still its uncalibrated poses; named otherwise, the name is taken
    assert trial_source("reality", said, "headset") == PoseSource("headset (uncalibrated)", "")
    assert trial_source("reality", said, "vicon") == PoseSource("vicon", "")
    assert trial_source("reality", None, None) == PoseSource("unnamed", "")
    record = session_tracking(4, {"vr", "reality"}, {"vr": said, "reality": said}, {})["conditions"]
    assert record["vr"]["source"] == "headset" and record["reality"]["source"] == "headset (uncalibrated)"


def test_a_calibrated_source_is_recorded_with_its_fits_id() -> None:
    said = announcement_from_json(announcement("optitrack", ("vr", "reality"), {}, 3.0, FIT))
    fit_id = calibration_id(FIT)
    assert len(fit_id) == 8 and int(fit_id, 16) >= 0
    assert trial_source("reality", said, None) == PoseSource("optitrack", fit_id)
    assert trial_source("vr", said, "optitrack") == PoseSource("optitrack", fit_id)  # named as it is: its fit kept
    assert trial_source("reality", said, "vicon") == PoseSource("vicon", "")
    # the id is the fit's: the same whatever the order of its keys, another for another fit, none without one
    assert calibration_id(dict(reversed(list(FIT.items())))) == fit_id
    assert calibration_id({**FIT, "residual_rms_m": 0.0011}) != fit_id
    assert calibration_id(None) == "" and calibration_id({}) == ""


def held(*positions: list[float]) -> np.ndarray:
    return np.array(positions, dtype=float)


def test_a_touch_whose_poses_are_lost_or_moving_is_taken_again() -> None:
    assert held_problem(held([0.1, 0.2, 0.3], [0.1, 0.2, 0.301]), still=0.005) == ""
    assert held_problem(held([0.1, 0.2, 0.3], [0.1, 0.2, 0.32]), still=0.005) == "it moved 10.0 mm"
    # a NaN compares as nothing: its spread is no larger than `still`, and once it was taken
    assert (
        held_problem(held([0.1, 0.2, 0.3], [math.nan] * 3), still=0.005) == "1 of its 2 poses were not finite (lost?)"
    )


NAMES = list(DEFAULT_POINTS)
WORLD = np.array([POINTS[n] for n in NAMES])


def saved(**change: object) -> dict:
    """A saved fit as the relay writes it, of CONFIG's tracker; `change` replaces its keys."""
    fit = fit_calibration(NAMES, WORLD, WORLD + np.array([0.2, 0.1, 0.0]), bound=0.01).to_data()
    return {"calibration": {"source": "optitrack", "frame": "mocap", "world_frame": "world", **fit, **change}}


def test_a_saved_fit_of_this_scene_tracker_and_frame_is_taken() -> None:
    config = tracker_config(CONFIG, SCENE)
    fit = saved_calibration(saved(), config, POINTS)
    assert np.allclose(fit.transform.translation, [-0.2, -0.1, 0.0]) and fit.names == tuple(NAMES)


@pytest.mark.parametrize(
    ("change", "problem"),
    [
        ({"source": "vicon"}, "fit.json is a fit of source 'vicon', not this session's 'optitrack' .the config's."),
        ({"frame": "optitrack_world"}, "fit.json is a fit of frame 'optitrack_world', not this session's 'mocap'"),
        ({"tip_m": 0.007}, "fit.json was made with a tip of 7.0 mm, the config says 0.0 mm"),
    ],
)
def test_a_saved_fit_of_another_tracker_frame_or_tip_is_refused(change: dict, problem: str) -> None:
    with pytest.raises(StudyError, match=problem):
        saved_calibration(saved(**change), tracker_config(CONFIG, SCENE), POINTS, "fit.json")


def test_a_saved_fit_of_another_scene_is_refused_naming_the_point_that_moved() -> None:
    # the table moved 10 cm along x since the fit (before: the old touches fitted the old places, 1.5 mm residual,
    # every pose relayed 100 mm off)
    moved = {n: p + np.array([0.1, 0.0, 0.0]) if n.startswith("table") else p for n, p in POINTS.items()}
    with pytest.raises(
        StudyError,
        match=r"fit.json was fitted to another scene: its table_corner_1 is at \(-0.300, -0.500, 0.000\) m, this "
        r"scene's at \(-0.200, -0.500, 0.000\) m, 100.0 mm apart: calibrate again",
    ):
        saved_calibration(saved(), tracker_config(CONFIG, SCENE), moved, "fit.json")


def tracker_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], data: object, config: dict = CONFIG
) -> list[str]:
    """The tracker command's refusal of a saved fit `data` (written as JSON; a string as is): its exit code 2 and
    its one line."""
    path = tmp_path / "tracker.yaml"
    path.write_text(yaml.safe_dump(config))
    fit = tmp_path / "fit.json"
    fit.write_text(data if isinstance(data, str) else json.dumps(data))
    command = [
        "tracker",
        "--config",
        str(path),
        "--participant",
        "1",
        "--out",
        str(tmp_path),
        "--calibration",
        str(fit),
    ]
    return [str(main(command))] + capsys.readouterr().err.strip().splitlines()


def test_the_tracker_command_refuses_a_saved_fit_above_the_bound_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tight = {**CONFIG, "calibration": {**CONFIG["calibration"], "max_residual": 0.002}}
    touched = WORLD + np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    fit = fit_calibration(NAMES, WORLD, touched, bound=0.01).to_data()
    data = {"calibration": {"source": "optitrack", "frame": "mocap", "world_frame": "world", **fit}}
    code, line = tracker_command(tmp_path, capsys, data, tight)
    assert code == "2" and line.startswith("sim.study tracker: error: calibration refused: its largest residual is ")
    assert "above the bound of 2.0 mm" in line


def test_the_tracker_command_refuses_a_mirrored_or_malformed_saved_fit_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fit = saved()
    points = fit["calibration"]["points"]
    mirrored = [{**p, "tracker": [p["tracker"][0], p["tracker"][2], p["tracker"][1]]} for p in points]
    code, line = tracker_command(tmp_path, capsys, {"calibration": {**fit["calibration"], "points": mirrored}})
    assert code == "2" and "error: calibration refused: the tracker's frame is mirrored: check its axis" in line
    # a touch of 2 coordinates (before: a traceback)
    short = [*points[:2], {**points[2], "tracker": points[2]["tracker"][:2]}, *points[3:]]
    code, line = tracker_command(tmp_path, capsys, {"calibration": {**fit["calibration"], "points": short}})
    assert code == "2" and line.endswith(
        "fit.json: point 3 (table_corner_1)'s tracker must be 3 coordinates, got 2 coordinates"
    )
    code, line = tracker_command(tmp_path, capsys, {"calibration": {**fit["calibration"], "points": "all"}})
    assert code == "2" and line.endswith("fit.json is not a saved calibration: no list of points")
    code, line = tracker_command(tmp_path, capsys, "[1, 2")
    assert code == "2" and "error: cannot read the calibration" in line
