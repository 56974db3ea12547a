"""sim.study.run.poses: the poses kept per body, refused when not in the scene's frame, and waited for up to a time."""

from __future__ import annotations

import threading

import pytest

from sim.study.run.poses import COVERED_WITHIN, ReceivedPoses


def test_poses_are_kept_per_body_as_tracks_since_a_time_and_forgotten_before_one() -> None:
    poses = ReceivedPoses("world")
    for stamp in (1.0, 1.02, 0.98):  # as they arrive, not in order
        poses.add("head", stamp, "world", (stamp, 0.0, 1.0))
    poses.add("right_hand", 1.01, "world", (0.5, 0.0, 0.0))
    assert poses.sending(1.0) == ["head", "right_hand"] and poses.sending(1.015) == ["head"]
    tracks = poses.tracks(0.99)
    assert tracks["head"].stamps.tolist() == [1.0, 1.02] and len(tracks["left_hand"]) == 0
    poses.forget(before=1.01)
    assert poses.tracks(0.0)["head"].stamps.tolist() == [1.02]


def test_a_pose_in_another_frame_or_not_a_point_is_refused_and_why_is_kept() -> None:
    poses = ReceivedPoses("world")
    poses.add("head", 1.0, "optitrack", (0.0, 0.0, 1.0))
    poses.add("left_hand", float("nan"), "world", (0.0, 0.0, 1.0))
    assert poses.sending(0.0) == []
    assert "'optitrack', not the scene's 'world'" in poses.refused()["head"]
    assert "not a finite point" in poses.refused()["left_hand"]


def test_waiting_ends_once_every_sending_body_has_a_pose_at_the_time() -> None:
    poses = ReceivedPoses("world")
    stop = threading.Event()
    poses.add("head", 2.0, "world", (0, 0, 0))
    poses.add("right_hand", 2.0, "world", (0, 0, 0))
    assert poses.uncovered(1.0, 2.5) == ["head", "right_hand"]
    assert poses.wait_covered(1.0, 2.5, 0.05, stop) == ["head", "right_hand"]  # nothing more came: short of it
    late = threading.Timer(
        0.05, lambda: [poses.add(b, 2.5 - COVERED_WITHIN / 2, "world", (0, 0, 0)) for b in ("head", "right_hand")]
    )
    late.start()
    try:
        assert poses.wait_covered(1.0, 2.5, 30.0, stop) == []
    finally:
        late.cancel()
    assert poses.uncovered(2.6, 3.0) == []  # a body that has not sent since then is not waited for
    stop.set()
    assert poses.wait_covered(1.0, 9.0, 30.0, stop) == ["head", "right_hand"]


@pytest.mark.parametrize("body", ["head", "left_hand", "right_hand"])
def test_every_body_of_the_protocol_is_kept(body: str) -> None:
    poses = ReceivedPoses()
    poses.add(body, 1.0, poses.frame, (0, 0, 0))
    assert poses.sending(1.0) == [body]
