"""control_msgs' types generated from the carried definitions: the published md5sums, and messages that round-trip."""

from __future__ import annotations

import io

import numpy as np
import pytest

from sim.wire.control_types import ControlTypesError, action_messages, control_types, joint_trajectory

# The md5sums of control_msgs 1.5 (ROS Noetic), as its generated code (rosserial's headers among others) publishes
# them: a client of a real ros_control controller agrees on these or rospy refuses the connection.
PUBLISHED_MD5SUMS = {
    "control_msgs/FollowJointTrajectoryAction": "bc4f9b743838566551c0390c65f1a248",
    "control_msgs/FollowJointTrajectoryActionGoal": "cff5c1d533bf2f82dd0138d57f4304bb",
    "control_msgs/FollowJointTrajectoryActionResult": "c4fb3b000dc9da4fd99699380efcc5d9",
    "control_msgs/FollowJointTrajectoryActionFeedback": "d8920dc4eae9fc107e00999cce4be641",
    "control_msgs/FollowJointTrajectoryGoal": "69636787b6ecbde4d61d711979bc7ecb",
    "control_msgs/FollowJointTrajectoryResult": "493383b18409bfb604b4e26c676401d2",
    "control_msgs/FollowJointTrajectoryFeedback": "10817c60c2486ef6b33e97dcd87f4474",
    "control_msgs/JointTolerance": "f544fe9c16cf04547e135dd6063ff5be",
    "control_msgs/JointTrajectoryControllerState": "10817c60c2486ef6b33e97dcd87f4474",
    "control_msgs/QueryTrajectoryState": "ec93cdecbd8062d761aa52b7c90cd44b",
    "control_msgs/QueryTrajectoryStateRequest": "556a4fb76023a469987922359d08a844",
    "control_msgs/QueryTrajectoryStateResponse": "1f1a6554ad060f44d013e71868403c1a",
}


def test_every_generated_type_has_the_published_md5sum() -> None:
    types = control_types()
    assert types.md5sums == PUBLISHED_MD5SUMS
    assert types.action._md5sum == PUBLISHED_MD5SUMS["control_msgs/FollowJointTrajectoryAction"]
    assert types.query_state._md5sum == PUBLISHED_MD5SUMS["control_msgs/QueryTrajectoryState"]
    assert types.controller_state._type == "control_msgs/JointTrajectoryControllerState"


def test_a_goal_round_trips_with_its_constants() -> None:
    types = control_types()
    goal = types.goal()
    goal.trajectory.joint_names = ["a", "b"]
    goal.path_tolerance = [types.joint_tolerance(name="a", position=0.1)]
    goal.goal_time_tolerance.secs = 2
    buffer = io.BytesIO()
    goal.serialize(buffer)
    back = types.goal().deserialize(buffer.getvalue())
    assert back.trajectory.joint_names == ["a", "b"] and back.path_tolerance[0].position == 0.1
    assert back.goal_time_tolerance.secs == 2
    assert types.result.INVALID_JOINTS == -2 and types.result.PATH_TOLERANCE_VIOLATED == -4


def test_an_action_expands_into_its_seven_messages() -> None:
    texts = action_messages("Move", "float64 x\n---\nint32 code\n---\nfloat64 done\n")
    assert texts["MoveGoal"] == "float64 x" and texts["MoveResult"] == "int32 code"
    assert "MoveGoal goal" in texts["MoveActionGoal"] and "actionlib_msgs/GoalID goal_id" in texts["MoveActionGoal"]
    assert texts["MoveAction"].split("\n")[0] == "MoveActionGoal action_goal"
    assert len(texts) == 7


def test_an_action_without_three_sections_is_refused() -> None:
    with pytest.raises(ControlTypesError, match="Move.action has 2 sections"):
        action_messages("Move", "float64 x\n---\nint32 code\n")


def test_a_joint_trajectory_carries_every_sample_and_its_stamp() -> None:
    times = np.array([0.01, 0.02])
    q = np.array([[0.1, 0.2], [0.3, 0.4]])
    message = joint_trajectory(("a", "b"), times, q, 2 * q, 3 * q, stamp=12.5)
    buffer = io.BytesIO()
    message.serialize(buffer)  # the wire's form: what a controller receives
    back = type(message)().deserialize(buffer.getvalue())
    assert back.joint_names == ["a", "b"] and back.header.stamp.to_sec() == 12.5
    assert [p.time_from_start.to_sec() for p in back.points] == [0.01, 0.02]
    assert [list(p.positions) for p in back.points] == q.tolist()
    assert [list(p.velocities) for p in back.points] == (2 * q).tolist()
    assert [list(p.accelerations) for p in back.points] == (3 * q).tolist()


def test_a_joint_trajectory_stamped_zero_or_empty_or_of_positions_only() -> None:
    hold = joint_trajectory(("a",), np.zeros(0), np.zeros((0, 1)))
    assert hold.header.stamp.is_zero() and hold.points == []  # "hold": start at the next update, no points
    (point,) = joint_trajectory(("a",), [1.0], [[0.5]]).points
    assert list(point.positions) == [0.5] and list(point.velocities) == [] and list(point.accelerations) == []


@pytest.mark.parametrize(
    ("arguments", "said"),
    [
        ((("a", "b"), [1.0], [[0.1]]), "positions must be 1 points of 2 joints, got shape (1, 1)"),
        ((("a",), [1.0, 2.0], [[0.1], [0.2]], [[0.0]]), "velocities must be 2 points of 1 joints"),
        ((("a",), [1.0], [[float("nan")]]), "must be finite"),
        ((("a",), [1.0], [[0.1]], None, None, -1.0), "stamp >= 0), got -1.0"),
    ],
)
def test_a_joint_trajectory_of_the_wrong_shape_or_not_finite_is_refused(arguments: tuple, said: str) -> None:
    with pytest.raises(ControlTypesError, match=said.replace("(", r"\(").replace(")", r"\)")):
        joint_trajectory(*arguments)
