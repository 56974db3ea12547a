"""sim.wire.rosmsgs: joint states as the engine writes them, read back by name in a robot's joint order."""

from __future__ import annotations

import numpy as np
import pytest

from sim.wire.rosmsgs import (
    _T,
    POSE_STAMPED,
    MessageError,
    decode_joint_state,
    encode_joint_state,
    encode_message,
    encode_pose_stamped,
    time_msg,
)


def test_a_joint_state_is_read_by_name_whatever_its_order_and_extra_joints() -> None:
    data = encode_joint_state(3, 12.34, ["finger", "j2", "j1"], np.array([0.04, -0.5, 1.25]), np.zeros(3), np.zeros(3))
    sample = decode_joint_state(data, ["j1", "j2"])
    assert sample.stamp_s == pytest.approx(12.34, abs=1e-9)
    assert sample.positions.tolist() == [1.25, -0.5]
    assert sample.seq == 3


@pytest.mark.parametrize("names, positions", [(["j1"], [0.1]), (["j1", "j2"], [0.1])])
def test_a_joint_state_that_does_not_cover_the_joints_is_a_message_error(names, positions) -> None:
    data = encode_joint_state(0, 0.0, names, np.array(positions), np.zeros(len(positions)), np.zeros(len(positions)))
    with pytest.raises(MessageError, match="not covering"):
        decode_joint_state(data, ["j1", "j2"])


def test_a_pose_is_packed_as_encode_message_makes_it() -> None:
    place, turn = np.array([0.55, -0.012, 0.035]), np.array([0.0, 0.0, 0.3826834323650898, 0.9238795325112867])
    for stamp in (0.0, 12.34, 1234.999999999):
        made = encode_message(
            POSE_STAMPED,
            header=_T["std_msgs/msg/Header"](seq=0, stamp=time_msg(stamp), frame_id="world"),
            pose=_T["geometry_msgs/msg/Pose"](
                position=_T["geometry_msgs/msg/Point"](x=place[0], y=place[1], z=place[2]),
                orientation=_T["geometry_msgs/msg/Quaternion"](x=turn[0], y=turn[1], z=turn[2], w=turn[3]),
            ),
        )
        assert encode_pose_stamped(stamp, "world", place, turn) == made
