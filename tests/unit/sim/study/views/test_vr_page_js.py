"""The VR page's JavaScript without a browser: node runs its unit tests (tests/js), and its ROS-TCP frames and ROS 1
messages are checked byte for byte against Python's (rosbags, and the endpoint's own framing)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from bridge.protocol.framing import FrameDecoder, encode_frame, encode_syscommand
from sim.study.run.protocol import input_delay_from_seq
from sim.wire.rosmsgs import TYPESTORE, Header, deserialize, encode_joint_state, encode_message, time_msg

Pose, Point, Quaternion = (TYPESTORE.types[f"geometry_msgs/msg/{name}"] for name in ("Pose", "Point", "Quaternion"))

JS_TESTS = Path(__file__).resolve().parents[4] / "js"
WEB = Path(__file__).resolve().parents[5] / "sim" / "study" / "views" / "vr" / "web"
NODE = shutil.which("node") or "/usr/bin/node"


def test_the_page_logic_passes_its_node_tests() -> None:
    done = subprocess.run([NODE, "--test", str(JS_TESTS)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    declared = sum(len(re.findall(r"^test\(", test.read_text(), re.M)) for test in JS_TESTS.glob("*.test.mjs"))
    assert declared > 0 and "# fail 0" in done.stdout and f"# pass {declared}\n" in done.stdout, done.stdout[-1000:]


def test_the_page_types_no_rule_of_the_trial_protocol() -> None:
    """The phases, the stop sources, the topics, the poses' frame and the limits are the protocol's table
    (sim/study/run/protocol.json), which the page gets with its settings: none of them is written into the page's own
    scripts. The inputs' and the bodies' names are the table's keys, by which the page reads it."""
    from sim.study.run.protocol import INPUTS, PROTOCOL

    # the inputs' names are the table's keys, by which the page reads it; a phase may share its input's name
    names = ({phase.name for phase in PROTOCOL.phases} - set(INPUTS)) | set(PROTOCOL.stop_sources)
    names |= {
        part for topic in (PROTOCOL.status, *PROTOCOL.inputs.values(), *PROTOCOL.poses.values()) for part in topic
    }
    names.add(PROTOCOL.pose_frame)
    limits = {name.upper() for name in PROTOCOL.data["limits"]} | {"MAX_PERCEIVED_DISTANCE", "LONGEST_MOTION_S"}
    typed = {}
    for script in sorted(WEB.glob("*.js")):
        text = re.sub(r"(?m)(^|\s)//.*$", "", script.read_text())  # comments: their apostrophes pair no quotes
        strings = set(re.findall(r"'([^'\\]*)'", text)) | set(re.findall(r'"([^"\\]*)"', text))
        found = sorted(strings & names) + sorted(name for name in limits if name in text)
        if found:
            typed[script.name] = found
    assert typed == {}
    assert "protocol" in (WEB / "study.js").read_text()


def test_the_page_reads_and_writes_what_ros_does() -> None:
    names = ["panda_joint1", "panda_joint2", "jöint_ü"]
    positions, velocities = np.array([0.1, -1.25, 3.5]), np.array([0.0, 2.0, -0.5])
    joint_state = encode_joint_state(7, 12.345678901, names, positions, velocities, np.zeros(3))
    frames = encode_frame("/panda/joint_states", joint_state) + encode_frame("", b"") + encode_syscommand("__ping", {})
    given = {
        "joint_state": joint_state.hex(),
        "frames": frames.hex(),
        "header": {"seq": 4, "stamp": 1.16, "frame_id": "vr_trigger"},
        "stop": {"stamp": 12.25, "input_delay": 0.0123456, "frame_id": "button"},
        "float32": 0.12,
        "pose": {
            "seq": 41,
            "stamp": 1234.5678,
            "frame_id": "world",
            "position": [0.55, -0.65, 0.45],
            "orientation": [0.7071067811865476, 0.0, 0.0, 0.7071067811865476],
        },
        "string": "lateral_arc",
        "frame": ["/study/stop", "0102"],
    }
    done = subprocess.run(
        [NODE, str(JS_TESTS / "codec_cli.mjs")], input=json.dumps(given), capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    state = out["joint_state"]
    assert state["names"] == names and state["stamp"] == pytest.approx(12.345678901, abs=1e-9)
    assert state["positions"] == positions.tolist() and state["velocities"] == velocities.tolist()
    assert out["frames"] == [["/panda/joint_states", joint_state.hex()], ["", ""], ["__ping", b"{}".hex()]]
    header = deserialize(bytes.fromhex(out["header"]), "std_msgs/Header")
    assert (header.seq, header.stamp.sec, header.stamp.nanosec, header.frame_id) == (4, 1, 160_000_000, "vr_trigger")
    assert bytes.fromhex(out["header"]) == encode_message(
        "std_msgs/Header", seq=4, stamp=time_msg(1.16), frame_id="vr_trigger"
    )
    stop = deserialize(bytes.fromhex(out["stop"]), "std_msgs/Header")  # the runner reads its input delay from seq
    assert (stop.stamp.sec, stop.stamp.nanosec, stop.frame_id) == (12, 250_000_000, "button")
    assert input_delay_from_seq(stop.seq) == pytest.approx(0.012346, abs=1e-12)
    assert deserialize(bytes.fromhex(out["float32"]), "std_msgs/Float32").data == pytest.approx(0.12, abs=1e-7)
    pose = deserialize(bytes.fromhex(out["pose"]), "geometry_msgs/PoseStamped")  # as the runner's bag holds it
    assert (pose.header.seq, pose.header.stamp.sec, pose.header.frame_id) == (41, 1234, "world")
    assert pose.header.stamp.nanosec == pytest.approx(567_800_000, abs=1)
    position, orientation = pose.pose.position, pose.pose.orientation
    assert [position.x, position.y, position.z] == given["pose"]["position"]
    assert [orientation.x, orientation.y, orientation.z, orientation.w] == given["pose"]["orientation"]
    assert bytes.fromhex(out["pose"]) == encode_message(
        "geometry_msgs/PoseStamped",
        header=Header(seq=41, stamp=time_msg(1234.5678), frame_id="world"),
        pose=Pose(position=Point(x=0.55, y=-0.65, z=0.45), orientation=Quaternion(*given["pose"]["orientation"])),
    )
    assert bytes.fromhex(out["string"]) == encode_message("std_msgs/String", data="lateral_arc")
    assert bytes.fromhex(out["frame"]) == encode_frame("/study/stop", b"\x01\x02")
    (command,), failure = FrameDecoder().feed_raw(bytes.fromhex(out["command"]))  # as the endpoint frames it
    assert failure is None and bytes(command[0]) == b"__subscribe"
    assert json.loads(bytes(command[1])) == {"topic": "/study/trial", "message_name": "std_msgs/String"}
