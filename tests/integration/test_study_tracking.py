"""The person tracked in both conditions by two pose sources, end to end with real parts: the runner node (rospy,
rosbag record), the endpoint, the engine stand-in in lockstep, the tracker relay node (rospy) calibrated by touches
typed at its terminal, and a scripted client of the endpoint that is both the VR scene (its poses straight on the
study's topics, in the world) and a motion-capture system in reality (its poses on a driver's topics and on /tf, in
a frame of its own turned and moved from the world, with jitter), and in reality also a VR page left open (its
poses on the study's topics, through the endpoint), which the runner drops: only the announced source's count.
And pose sources that change mid-session, all scripted through the endpoint: the VR page tracking VR, a calibrated
tracker announced for reality's first trial, then the page started anew with `--pose-conditions vr,reality` (a
headset worn in reality too): each trial's row names the source that tracked it, the headset's uncalibrated poses in
reality as a source of their own, and the report's caveat follows from the rows, not the session's record."""

from __future__ import annotations

import csv
import json
import queue
import re
import struct
import subprocess
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from rosbags.rosbag1 import Reader

from bridge.client import TcpClient
from sim.geometry.frames import rpy_to_matrix
from sim.launchers import Runner, finish, start
from sim.study.__main__ import main
from sim.study.design.paths import ON_TOP
from sim.study.design.scene import load_scene, scene_robot
from sim.study.motion.calibration import RigidTransform
from sim.study.run.protocol import (
    GO_TOPIC,
    POSE_FRAME,
    POSE_TOPICS,
    POSE_TYPE,
    PREFERENCE_TOPIC,
    PROTOCOL,
    STATUS_TOPIC,
    STOP_TOPIC,
    TOPIC_TYPES,
    status_from_json,
)
from sim.study.run.tracking import (
    CALIBRATION_TOPIC,
    TF_STATIC_TOPIC,
    TRACKING_TOPIC,
    announcement,
    calibration_id,
    marked_points,
)
from sim.study.views.vr.site import page_settings, pose_conditions_from
from sim.wire.rosmsgs import (
    JOINT_STATE,
    TYPESTORE,
    deserialize,
    encode_message,
    encode_pose_stamped,
    time_msg,
    to_seconds,
)
from tests.integration.sim_helpers import start_engine
from tests.integration.study_helpers import trial, write_plan
from tests.rosenv import PYTHON, REPO, kill_process

pytestmark = [pytest.mark.lane("alone", on=("project",)), pytest.mark.timeout(300)]

SCENE = load_scene()
ROBOT = scene_robot(SCENE)
POINTS = marked_points(SCENE)
# not all in one plane (the hand model's ends are 35 mm up), or a mirrored mocap frame could not be told
TOUCHED = ["hand_fingertips", "hand_wrist", "table_corner_1", "table_corner_2", "table_corner_3"]
# The motion-capture system's frame in the scene's world: turned about every axis, its origin well away
MOCAP = RigidTransform(rpy_to_matrix(0.05, -0.1, 1.9), np.array([1.5, -1.2, 0.8]))
JITTER = 0.0003  # m, SD per axis of every mocap position
HEAD, LEFT_HAND = np.array([0.55, -0.65, 0.45]), np.array([0.35, -0.45, 0.02])
PRESS_AFTER, WITHDRAWAL, WITHDRAWAL_SPEED = 0.5, 0.03, 0.1  # s after the start; m; m/s (away from the robot, -y)
IDENTITY = (0.0, 0.0, 0.0, 1.0)
MOCAP_TOPICS = {"head": "/mocap/head/pose", "right_hand": "/mocap/right_hand/pose"}  # the left hand comes on /tf
TRACKER = {
    "source": "mocap_sim",
    "frame": "mocap",
    "conditions": ["reality"],
    "bodies": {
        "head": {"topic": MOCAP_TOPICS["head"]},
        "right_hand": {"topic": MOCAP_TOPICS["right_hand"]},
        "left_hand": {"tf": "left_hand_marker"},
    },
    "calibration": {"body": "right_hand", "points": TOUCHED, "max_residual": 0.003, "hold": 0.3},
    "rest": 1.0,
}


def tf_message(stamp: float, parent: str, child: str, position: np.ndarray) -> bytes:
    """A tf2_msgs/TFMessage of one TransformStamped, serialized (rosbags' store has no tf2_msgs)."""
    t = time_msg(stamp)
    head = struct.pack(f"<4I{len(parent)}s", 0, t.sec, t.nanosec, len(parent), parent.encode())
    tail = struct.pack(f"<I{len(child)}s7d", len(child), child.encode(), *position, *IDENTITY)
    return struct.pack("<I", 1) + head + tail


class TwoTrackers:
    """The VR scene and the mocap system, scripted. Until the session starts the mocap streams the bodies at rest
    (the right hand on the point being touched) at some 100 Hz of wall time; in each trial it says go, presses stop
    PRESS_AFTER s into the approach (stamped), and from the approach's start on sends the bodies' poses at each
    joint state's stamp: in VR on the study's topics, in reality as the mocap sees them. The right hand withdraws
    from the press."""

    def __init__(self, port: int) -> None:
        self.client = TcpClient("127.0.0.1", port)
        self.rng = np.random.default_rng(7)
        self.touching = SCENE.hand.top.copy()  # where the right hand rests, or the point it touches
        self.streaming = threading.Event()
        self.streaming.set()
        self.done = threading.Event()
        self.status: Any = None
        for topic in (GO_TOPIC, STOP_TOPIC, PREFERENCE_TOPIC):
            self.client.register_publisher(topic, TOPIC_TYPES[topic])
        for topic in (*POSE_TOPICS.values(), *MOCAP_TOPICS.values()):
            self.client.register_publisher(topic, POSE_TYPE, queue_size=100)
        self.client.register_publisher("/tf", "tf2_msgs/TFMessage", queue_size=100)
        self.client.subscribe(STATUS_TOPIC, TOPIC_TYPES[STATUS_TOPIC], self.on_status)
        self.client.subscribe(ROBOT.joint_states_topic, JOINT_STATE, self.on_joint_state)
        self.streamer = threading.Thread(target=self.stream, daemon=True)

    def mocap(self, stamp: float, world: dict[str, np.ndarray]) -> None:
        """The bodies as the mocap system reports them: in its own frame, with jitter."""
        seen = {body: MOCAP.inverse().apply(p) + self.rng.normal(0.0, JITTER, 3) for body, p in world.items()}
        for body, topic in MOCAP_TOPICS.items():
            self.client.publish(topic, encode_pose_stamped(stamp, "mocap", seen[body], IDENTITY))
        self.client.publish("/tf", tf_message(stamp, "mocap", "left_hand_marker", seen["left_hand"]))

    def stream(self) -> None:
        stamp = 0.0
        while self.streaming.wait(0) and not self.done.is_set():
            stamp += 0.01
            self.mocap(stamp, {"head": HEAD, "right_hand": self.touching, "left_hand": LEFT_HAND})
            self.done.wait(0.01)

    def on_status(self, payload: bytes) -> None:
        status = status_from_json(deserialize(payload, TOPIC_TYPES[STATUS_TOPIC]).data)
        self.streaming.clear()  # the session has started: from now on the mocap sends on the runner's clock
        self.status = status if status.phase in ("moving", "at_rest") else None
        if status.phase == "ready":
            self.client.publish(GO_TOPIC, encode_message(TOPIC_TYPES[GO_TOPIC]))
        elif status.phase == "moving":
            stamp = time_msg(status.motion_start + PRESS_AFTER)
            source = PROTOCOL.stop_source(status.condition)
            stop = encode_message(TOPIC_TYPES[STOP_TOPIC], seq=0, stamp=stamp, frame_id=source)
            self.client.publish(STOP_TOPIC, stop)
            self.poses(status, status.motion_start)  # tracked from the approach's start (its joint state came first)
        elif status.phase == "preference":
            self.client.publish(PREFERENCE_TOPIC, encode_message(TOPIC_TYPES[PREFERENCE_TOPIC], data="1"))
        elif status.phase == "done":
            self.done.set()

    def on_joint_state(self, payload: bytes) -> None:
        status = self.status
        if status is not None:
            self.poses(status, to_seconds(deserialize(payload, JOINT_STATE).header.stamp))

    def poses(self, status: Any, stamp: float) -> None:
        """The bodies at `stamp` in the trial of `status`, from the tracker of its condition."""
        withdrawn = min(max(stamp - status.motion_start - PRESS_AFTER, 0.0) * WITHDRAWAL_SPEED, WITHDRAWAL)
        world = {"head": HEAD, "right_hand": SCENE.hand.top - np.array([0.0, withdrawn, 0.0]), "left_hand": LEFT_HAND}
        if status.condition == "reality":
            self.mocap(stamp, world)
            # and a VR page left open in a second browser, sending its headset's poses through the endpoint: 10 cm
            # off, never withdrawing; the runner takes reality's poses from its announced source (the relay) alone
            for body, position in world.items():
                off = (SCENE.hand.top if body == "right_hand" else position) + np.array([0.1, 0.0, 0.0])
                self.client.publish(POSE_TOPICS[body], encode_pose_stamped(stamp, POSE_FRAME, off, IDENTITY))
        else:
            for body, position in world.items():
                self.client.publish(POSE_TOPICS[body], encode_pose_stamped(stamp, POSE_FRAME, position, IDENTITY))


def calibrate(relay: subprocess.Popen, lines: queue.Queue, trackers: TwoTrackers) -> list[str]:
    """The experimenter at the relay's terminal: at each prompt, the hand on the point named, then Enter; until the
    relay says it relays. Its output's lines."""
    said = []
    while True:
        line = lines.get(timeout=60)
        said.append(line)
        assert "error" not in line, said
        if line.startswith("sim.study tracker: touch "):
            trackers.touching = POINTS[line.split()[3]]
            threading.Event().wait(0.1)  # the hand reaches the point before Enter
            assert relay.stdin is not None
            relay.stdin.write(b"\n")
            relay.stdin.flush()
        elif line.startswith("tracker mocap_sim: relaying"):
            trackers.touching = SCENE.hand.top.copy()
            return said


def bag_messages(bag: Path, topic: str, node: str = "") -> list[tuple[str, bytes]]:
    """The bag's messages on `topic` (from the ROS node `node` alone, if given), as (type, bytes)."""
    with Reader(bag) as reader:
        connections = [c for c in reader.connections if c.topic == topic and (not node or c.ext.callerid == node)]
        return [(c.msgtype, raw) for c, _, raw in reader.messages(connections=connections)]


def test_a_session_tracked_by_the_headset_in_vr_and_a_calibrated_mocap_in_reality(
    roscore, endpoint, tmp_path: Path
) -> None:
    config = tmp_path / "tracker.yaml"
    config.write_text(yaml.safe_dump(TRACKER))
    plan = write_plan(
        tmp_path / "plan.yaml",
        5,
        "vr",
        [
            trial(1, "vr", 2, "straight", ON_TOP, 0.3, "fast", 1),
            trial(2, "reality", 2, "straight", ON_TOP, 0.3, "fast", 1),
        ],
    )
    out = tmp_path / "out"
    engine = start_engine(roscore, tmp_path, "panda", endpoint.port, "--no-auto-simulate")
    trackers = TwoTrackers(endpoint.port)
    trackers.client.connect(timeout=30)
    trackers.streamer.start()
    command = [PYTHON, "-m", "sim.study", "tracker", "--config", str(config), "--participant", "5", "--out", str(out)]
    # a process group of its own: kill_process signals the group (without one, the relay outlived every run)
    relay = subprocess.Popen(
        command,
        env=roscore.env,
        cwd=REPO,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    lines: queue.Queue[str] = queue.Queue()
    assert relay.stdout is not None
    reader = threading.Thread(target=lambda: [lines.put(b.decode().rstrip()) for b in relay.stdout], daemon=True)
    reader.start()
    runner = None
    try:
        said = calibrate(relay, lines, trackers)
        runner = start(Runner(plan, out, extra=("--pose-source", "vr=headset")), roscore.env, tmp_path, "runner")
        finish(runner, 120)
        assert trackers.done.wait(10)
    finally:
        if runner is not None:
            runner.stop()
        kill_process(relay)
        trackers.done.set()
        trackers.client.close()
        engine.stop()
    # The calibration: the mocap's frame recovered from five touches of a jittery hand, within a few jitters
    saved = json.loads((out / "tracking" / "mocap_sim_participant_05.json").read_text())
    fit = saved["calibration"]
    assert np.allclose(fit["rotation"], MOCAP.rotation, atol=0.01), said
    assert np.allclose(fit["translation"], MOCAP.translation, atol=0.003), said
    assert fit["residual_max_m"] < 0.003 and [p["name"] for p in fit["points"]] == TOUCHED
    # each point left out of the fit and predicted by the others, said and saved beside the in-sample residuals
    assert 0.0 < fit["left_out_max_m"] < 0.003 and fit["tip_m"] == 0.0 and fit["body"] == "right_hand"
    assert any("each point left out of the fit" in line for line in said), said
    # its jitter at rest, each body's (the RMS distance of a 3-D jitter of SD JITTER per axis: sqrt(3) of it)
    for body in ("head", "right_hand", "left_hand"):
        assert saved["jitter_m"][body] == pytest.approx(JITTER * np.sqrt(3), rel=0.35), (body, saved["jitter_m"])
    # Both conditions measured: the right hand withdrew, in reality through the relay, calibrated, within the jitter
    with open(out / "participant_05.csv", newline="") as source:
        vr, reality = list(csv.DictReader(source))
    for row, within in ((vr, 1e-6), (reality, 0.003)):
        assert row["tracked_hand"] == "right_hand" and float(row["hand_untracked"]) == 0.0, row
        assert float(row["withdrawal_distance"]) == pytest.approx(WITHDRAWAL, abs=within), row
    # each row names its source: VR's by the command line (no calibration), reality's the relay, with its fit's id
    fit_id = calibration_id(fit)
    assert (vr["pose_source"], vr["calibration_id"]) == ("headset", "")
    assert (reality["pose_source"], reality["calibration_id"]) == ("mocap_sim", fit_id) and len(fit_id) == 8
    # The session's record names each condition's source; the bag holds the fit, the announcement and the TF
    record = json.loads((out / "tracking" / "participant_05.json").read_text())
    assert record["conditions"]["vr"]["source"] == "headset"
    assert record["conditions"]["reality"]["source"] == "mocap_sim"
    assert record["conditions"]["reality"]["calibration"]["residual_rms_m"] == fit["residual_rms_m"]
    bag = out / "bags" / "participant_05.bag"
    ((_, calibration),) = bag_messages(bag, CALIBRATION_TOPIC)
    assert (
        json.loads(TYPESTORE.deserialize_ros1(calibration, "std_msgs/msg/String").data)["translation"]
        == (fit["translation"])
    )
    assert len(bag_messages(bag, TRACKING_TOPIC)) == 1
    assert [kind for kind, _ in bag_messages(bag, TF_STATIC_TOPIC)] == ["tf2_msgs/msg/TFMessage"]
    relayed = [
        TYPESTORE.deserialize_ros1(raw, kind)
        for kind, raw in bag_messages(bag, POSE_TOPICS["left_hand"], "/study_tracker_mocap_sim")
    ]
    reality_start = float(reality["motion_start"])
    from_tf = [m for m in relayed if to_seconds(m.header.stamp) >= reality_start]
    assert from_tf and all(m.header.frame_id == POSE_FRAME for m in from_tf)
    where = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in from_tf])
    assert np.max(np.linalg.norm(where - LEFT_HAND, axis=1)) < 0.005  # the TF frame, calibrated into the world
    # The report names each condition's tracker and jitter, and every motion contrast carries the caveat
    assert main(["analyse", str(out)]) == 0
    report = (out / "report.md").read_text()
    assert "| vr | headset (1) | not measured |" in report
    assert re.search(r"^\| reality \| mocap_sim \(1\) \| 0\.[3-7]\d \(most ", report, re.M), report
    assert "**Caveat on every VR − reality contrast here** (test 2's withdrawal distance" in report
    assert f"vr: headset (1 participant, 1 trial); reality: mocap_sim (calibration {fit_id}) (1 participant" in report


# What the VR page announces of itself: by default (VR alone), and with `vr --pose-conditions vr,reality` (a headset
# worn with passthrough in reality too); neither with a calibration
PAGE = page_settings(ROBOT, SCENE)["pose_source"]
PAGE_IN_BOTH = page_settings(ROBOT, SCENE, pose_conditions_from("vr,reality"))["pose_source"]
# A calibrated tracker for reality, announced through the endpoint (the runner records its announcement; its
# residuals go to the report's table)
MOCAP_FIT = {"residual_rms_m": 0.0011, "residual_max_m": 0.0019}
MOCAP_ANNOUNCED = announcement("mocap_sim", ("reality",), {}, None, MOCAP_FIT)
# As each trial goes to its start, what is announced then: the tracker for reality's first trial, then the page
# started anew with `--pose-conditions vr,reality`, which takes reality over from it
ANNOUNCED_AT = {2: MOCAP_ANNOUNCED, 3: json.dumps(PAGE_IN_BOTH)}


class SourcesChanging:
    """A VR page, scripted through the endpoint, and what else announces itself as a pose source through it: PAGE
    (latched) from the start, then ANNOUNCED_AT each trial's start. It sends the bodies' poses in the world at each
    joint state's stamp from every approach's start, in both conditions, the right hand withdrawing from the press
    (PRESS_AFTER s in)."""

    def __init__(self, port: int) -> None:
        self.client = TcpClient("127.0.0.1", port)
        self.done = threading.Event()
        self.status: Any = None
        for topic in (GO_TOPIC, STOP_TOPIC, PREFERENCE_TOPIC):
            self.client.register_publisher(topic, TOPIC_TYPES[topic])
        for topic in POSE_TOPICS.values():
            self.client.register_publisher(topic, POSE_TYPE, queue_size=100)
        self.client.register_publisher(TRACKING_TOPIC, "std_msgs/String", latch=True)
        self.client.subscribe(STATUS_TOPIC, TOPIC_TYPES[STATUS_TOPIC], self.on_status)
        self.client.subscribe(ROBOT.joint_states_topic, JOINT_STATE, self.on_joint_state)

    def announce(self, text: str) -> None:
        self.client.publish(TRACKING_TOPIC, encode_message("std_msgs/String", data=text))

    def on_status(self, payload: bytes) -> None:
        status = status_from_json(deserialize(payload, TOPIC_TYPES[STATUS_TOPIC]).data)
        self.status = status if status.phase in ("moving", "at_rest") else None
        if status.phase == "to_start" and status.index in ANNOUNCED_AT:
            self.announce(ANNOUNCED_AT[status.index])
        elif status.phase == "ready":
            self.client.publish(GO_TOPIC, encode_message(TOPIC_TYPES[GO_TOPIC]))
        elif status.phase == "moving":
            stamp = time_msg(status.motion_start + PRESS_AFTER)
            source = PROTOCOL.stop_source(status.condition)
            stop = encode_message(TOPIC_TYPES[STOP_TOPIC], seq=0, stamp=stamp, frame_id=source)
            self.client.publish(STOP_TOPIC, stop)
            self.poses(status, status.motion_start)
        elif status.phase == "preference":
            self.client.publish(PREFERENCE_TOPIC, encode_message(TOPIC_TYPES[PREFERENCE_TOPIC], data="1"))
        elif status.phase == "done":
            self.done.set()

    def on_joint_state(self, payload: bytes) -> None:
        status = self.status
        if status is not None:
            self.poses(status, to_seconds(deserialize(payload, JOINT_STATE).header.stamp))

    def poses(self, status: Any, stamp: float) -> None:
        withdrawn = min(max(stamp - status.motion_start - PRESS_AFTER, 0.0) * WITHDRAWAL_SPEED, WITHDRAWAL)
        world = {"head": HEAD, "right_hand": SCENE.hand.top - np.array([0.0, withdrawn, 0.0]), "left_hand": LEFT_HAND}
        for body, position in world.items():
            self.client.publish(POSE_TOPICS[body], encode_pose_stamped(stamp, POSE_FRAME, position, IDENTITY))


def test_the_headset_worn_in_reality_and_a_source_changing_mid_session_are_named_trial_by_trial(
    roscore, endpoint, tmp_path: Path
) -> None:
    assert PAGE["conditions"] == ["vr"] and PAGE_IN_BOTH["conditions"] == ["vr", "reality"]
    assert PAGE["calibration"] is None and PAGE_IN_BOTH["calibration"] is None
    plan = write_plan(
        tmp_path / "plan.yaml",
        6,
        "vr",
        [
            trial(1, "vr", 2, "straight", ON_TOP, 0.3, "fast", 1),
            trial(2, "reality", 2, "straight", ON_TOP, 0.3, "fast", 1),
            trial(3, "reality", 2, "straight", ON_TOP, 0.3, "fast", 1),
        ],
    )
    out = tmp_path / "out"
    engine = start_engine(roscore, tmp_path, "panda", endpoint.port, "--no-auto-simulate")
    page = SourcesChanging(endpoint.port)
    runner = None
    try:
        page.client.connect(timeout=30)
        page.announce(json.dumps(PAGE))
        runner = start(Runner(plan, out), roscore.env, tmp_path, "runner")
        finish(runner, 120)
        assert page.done.wait(10)
    finally:
        if runner is not None:
            runner.stop()
        page.done.set()
        page.client.close()
        engine.stop()
    with open(out / "participant_06.csv", newline="") as source:
        rows = list(csv.DictReader(source))
    assert all(row["tracked_hand"] == "right_hand" for row in rows), rows
    mocap_id = calibration_id(MOCAP_FIT)
    assert [(row["condition"], row["pose_source"], row["calibration_id"]) for row in rows] == [
        ("vr", "headset", ""),
        ("reality", "mocap_sim", mocap_id),  # its trial's, though reality's source changed after it
        ("reality", "headset (uncalibrated)", ""),  # the headset's own tracking, not calibrated to the real table
    ]
    # the session's record keeps each condition's latest source: by it alone, both conditions had the headset
    record = json.loads((out / "tracking" / "participant_06.json").read_text())
    assert record["conditions"]["vr"]["source"] == "headset"
    assert record["conditions"]["reality"]["source"] == "headset (uncalibrated)"
    # the report's caveat follows from the rows
    assert main(["analyse", str(out)]) == 0
    report = (out / "report.md").read_text()
    assert "**Caveat on every VR − reality contrast here**" in report, report
    assert (
        "for 1 of 1 participants, by their trials' records (vr: headset (1 participant, 1 trial); reality: headset "
        f"(uncalibrated) (1 participant, 1 trial), mocap_sim (calibration {mocap_id}) (1 participant, 1 trial))"
    ) in report, report
