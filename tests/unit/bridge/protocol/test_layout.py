"""bridge.protocol.layout: a payload passes exactly when it is one whole message of the type (no truncation, no trailing
bytes), checked against genpy's own serialization of populated messages of many shapes."""

from __future__ import annotations

import io

import genpy
import pytest
from geometry_msgs.msg import Point, Pose, PoseArray, Quaternion, TransformStamped
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Empty, Header, String
from tf2_msgs.msg import TFMessage  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from bridge.protocol.layout import Layout, LayoutError  # noqa: E402


def resolve(name: str):
    return genpy.message.get_message_class(name)


def serialize(message) -> bytes:
    buffer = io.BytesIO()
    message.serialize(buffer)
    return buffer.getvalue()


def header(frame: str = "base_link") -> Header:
    return Header(seq=7, stamp=genpy.Time(1, 2), frame_id=frame)


def samples() -> list:
    point = JointTrajectoryPoint(positions=[1.0, 2.0], velocities=[0.5], time_from_start=genpy.Duration(1))
    return [
        String("hello"),
        String(""),
        Empty(),
        Header(),
        JointState(header=header(), name=["a", "bb", "ccc"], position=[1.0, 2.0, 3.0], velocity=[], effort=[4.0]),
        JointState(),
        PoseArray(header=header(), poses=[Pose(Point(1, 2, 3), Quaternion(0, 0, 0, 1))] * 3),
        JointTrajectory(header=header("map"), joint_names=["j1", "j2"], points=[point, JointTrajectoryPoint()]),
        Image(header=header(), height=2, width=3, encoding="mono8", step=3, data=bytes(range(6))),
        CameraInfo(header=header(), distortion_model="plumb_bob", D=[0.1, 0.2], K=[1.0] * 9),
        TFMessage(),
        TFMessage(transforms=[TransformStamped(header=header("odom"), child_frame_id="base")] * 2),
    ]


@pytest.mark.parametrize("message", samples(), ids=lambda m: m._type)
def test_whole_message_passes_and_every_truncation_or_extension_fails(message) -> None:
    layout = Layout(type(message), resolve)
    payload = serialize(message)
    layout.check(payload)
    for cut in range(len(payload)):
        with pytest.raises(LayoutError, match="truncated"):
            layout.check(payload[:cut])
    for extra in (b"\0", b"\0" * 4, b"junk"):
        with pytest.raises(LayoutError, match=f"{len(extra)} trailing byte"):
            layout.check(payload + extra)


def test_empty_message_is_zero_bytes() -> None:
    layout = Layout(Empty, resolve)
    layout.check(b"")
    with pytest.raises(LayoutError):
        layout.check(b"\0")


def test_huge_counts_fail_fast() -> None:
    # 2**32 - 1 strings announced in a few bytes: rejected after walking what is there, not 4 billion times
    layout = Layout(JointState, resolve)
    payload = serialize(JointState(header=header()))
    name_count_at = len(serialize(header()))
    forged = payload[:name_count_at] + b"\xff\xff\xff\xff" + payload[name_count_at + 4 :]
    with pytest.raises(LayoutError, match="truncated"):
        layout.check(forged)


def test_fixed_size_types_collapse_to_one_number() -> None:
    assert Layout(Pose, resolve).fixed_size == 56
