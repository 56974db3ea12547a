"""sim.study.run.tracking: a tracker's configuration, the scene's marked points, the announcement and the session's
record of its pose sources; and the tracker command's refusal of a saved fit above the bound (one line, exit 2)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from sim.study.__main__ import main
from sim.study.design.scene import load_scene
from sim.study.errors import StudyError
from sim.study.motion.calibration import fit_calibration
from sim.study.run.tracking import (
    BodySource,
    announcement,
    announcement_from_json,
    marked_points,
    session_tracking,
    tracker_config,
)

SCENE = load_scene()
CONFIG = {
    "source": "optitrack",
    "frame": "mocap",
    "conditions": ["reality"],
    "bodies": {
        "head": {"topic": "/vrpn_client_node/head/pose"},
        "right_hand": {"topic": "/vrpn_client_node/right_hand/pose"},
        "left_hand": {"tf": "left_hand"},
    },
    "calibration": {"body": "right_hand", "points": ["hand_fingertips", "table_corner_1", "table_corner_2"]},
}


def test_a_config_maps_topics_and_tf_frames_to_bodies() -> None:
    config = tracker_config(CONFIG, SCENE)
    assert config.bodies["head"] == BodySource(topic="/vrpn_client_node/head/pose")
    assert config.bodies["left_hand"] == BodySource(tf="left_hand")
    assert config.conditions == ("reality",) and config.calibration.max_residual == 0.01 and config.rest == 3.0
    assert config.stamp == "source" and tracker_config({**CONFIG, "stamp": "arrival"}, SCENE).stamp == "arrival"


@pytest.mark.parametrize(
    ("change", "problem"),
    [
        ({"frame": "world"}, "named 'world', as the scene's"),
        ({"bodies": {"torso": {"topic": "/t"}}}, "unknown body 'torso'"),
        ({"bodies": {"head": {"topic": "/h", "tf": "h"}}}, "needs one of topic or tf"),
        ({"conditions": ["lab"]}, "conditions must be some of vr, reality"),
        ({"calibration": {"body": "left_hand", "points": ["hand_wrist", "a_cup", "table_corner_1"]}}, "'a_cup'"),
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


def test_the_tracker_command_refuses_a_saved_fit_above_the_bound_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "tracker.yaml"
    config.write_text(yaml.safe_dump({**CONFIG, "calibration": {**CONFIG["calibration"], "max_residual": 0.002}}))
    points = marked_points(SCENE)
    names = ["hand_fingertips", "hand_wrist", "table_corner_1", "table_corner_2"]
    world = np.array([points[n] for n in names])
    touched = world + np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.0, 0.0]])
    saved = tmp_path / "fit.json"
    saved.write_text(json.dumps({"calibration": fit_calibration(names, world, touched, bound=1.0).to_data()}))
    command = [
        "tracker",
        "--config",
        str(config),
        "--participant",
        "1",
        "--out",
        str(tmp_path),
        "--calibration",
        str(saved),
    ]
    assert main(command) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("sim.study tracker: error: calibration refused: its largest residual is ")
    assert "above the bound of 2.0 mm" in line
