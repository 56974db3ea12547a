"""ROS 1 (de)serialization of the sim's messages without rospy, via rosbags' typestore.

The engine stand-in speaks to the endpoint in plain ROS 1 bytes, like Unity does, and must not import rospy.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore

from sim.wire.contract import MessageError, positions_by_name

__all__ = [
    "TYPESTORE",
    "Header",
    "Time",
    "JointStateMsg",
    "JOINT_STATE",
    "JOINT_TRAJECTORY",
    "CLOCK",
    "POSE",
    "MessageError",
    "serialize",
    "deserialize",
    "encode_message",
    "time_msg",
    "to_seconds",
    "encode_joint_state",
    "POSE_STAMPED",
    "encode_pose_stamped",
    "JointStateSample",
    "decode_joint_state",
    "decode_clock",
    "TrajectoryCommand",
    "decode_joint_trajectory",
    "decode_pose",
]

TYPESTORE = get_typestore(Stores.ROS1_NOETIC)
_T = TYPESTORE.types
Header = _T["std_msgs/msg/Header"]
Time = _T["builtin_interfaces/msg/Time"]
JointStateMsg = _T["sensor_msgs/msg/JointState"]

# protocol names (ROS 1 spelling) of the messages the sim exchanges
JOINT_STATE = "sensor_msgs/JointState"
JOINT_TRAJECTORY = "trajectory_msgs/JointTrajectory"
CLOCK = "rosgraph_msgs/Clock"
POSE = "geometry_msgs/Pose"
POSE_STAMPED = "geometry_msgs/PoseStamped"


def _store_name(ros1_name: str) -> str:
    package, type_name = ros1_name.split("/")
    return f"{package}/msg/{type_name}"


def serialize(message: object, ros1_name: str) -> bytes:
    return bytes(TYPESTORE.serialize_ros1(message, _store_name(ros1_name)))


def encode_message(ros1_name: str, **fields: Any) -> bytes:
    """A message of type `ros1_name` (e.g. "std_msgs/Header") made from its fields, serialized."""
    return serialize(_T[_store_name(ros1_name)](**fields), ros1_name)


def deserialize(data: bytes, ros1_name: str) -> object:
    try:
        return TYPESTORE.deserialize_ros1(data, _store_name(ros1_name))
    except Exception as error:  # rosbags raises assorted errors on short or corrupt input
        raise MessageError(f"{len(data)} bytes are not a valid {ros1_name}: {error}") from None


def time_msg(seconds: float) -> Any:
    sec = int(np.floor(seconds))
    nanosec = int(round((seconds - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return Time(sec=sec, nanosec=nanosec)


def to_seconds(stamp: object) -> float:
    return stamp.sec + stamp.nanosec * 1e-9  # type: ignore[attr-defined]


def encode_pose_stamped(
    stamp_s: float, frame_id: str, position: Iterable[float], orientation: Iterable[float]
) -> bytes:
    """A PoseStamped (seq 0) serialized: the bytes encode_message makes, packed directly (the Header's seq, stamp and
    frame_id, then the position's x, y, z and the orientation's x, y, z, w). A simulated participant sends three a
    step, and encode_message took 5-15 us for one on a 2-core machine (the typestore builds the message's objects
    first), this 1.5 us."""
    frame = frame_id.encode()
    stamp = time_msg(stamp_s)
    return struct.pack(f"<4I{len(frame)}s7d", 0, stamp.sec, stamp.nanosec, len(frame), frame, *position, *orientation)


def encode_joint_state(
    seq: int,
    stamp_s: float,
    names: Sequence[str],
    positions: np.ndarray,
    velocities: np.ndarray,
    efforts: np.ndarray,
) -> bytes:
    message = JointStateMsg(
        header=Header(seq=seq, stamp=time_msg(stamp_s), frame_id=""),
        name=list(names),
        position=np.asarray(positions, dtype=np.float64),
        velocity=np.asarray(velocities, dtype=np.float64),
        effort=np.asarray(efforts, dtype=np.float64),
    )
    return serialize(message, JOINT_STATE)


@dataclass(frozen=True)
class JointStateSample:
    """What the controller side reads of a JointState: its stamp, positions in a robot's joint order, and seq."""

    stamp_s: float
    positions: np.ndarray
    seq: int


def decode_joint_state(data: bytes, joint_order: Sequence[str]) -> JointStateSample:
    """A JointState, which may name more joints in any order, read by joint name (contract.positions_by_name);
    MessageError when it is no JointState or lacks one of `joint_order`."""
    message: Any = deserialize(data, JOINT_STATE)
    positions = positions_by_name(message.name, message.position, joint_order)
    return JointStateSample(to_seconds(message.header.stamp), positions, int(message.header.seq))


def decode_clock(data: bytes) -> float:
    return to_seconds(deserialize(data, CLOCK).clock)  # type: ignore[attr-defined]


@dataclass(frozen=True)
class TrajectoryCommand:
    """The first point of a JointTrajectory, reordered into a robot's joint order."""

    stamp_s: float
    positions: np.ndarray
    velocities: np.ndarray | None


def decode_joint_trajectory(data: bytes, joint_order: Sequence[str]) -> TrajectoryCommand:
    """Positions (and velocities when given) of the command's first point, by joint name, in `joint_order`.

    The command may name the joints in any order, and may name a subset; joints it does not name keep NaN so
    the caller can hold them. Unknown joint names raise MessageError.
    """
    message = deserialize(data, JOINT_TRAJECTORY)
    names = list(message.joint_names)  # type: ignore[attr-defined]
    points = message.points  # type: ignore[attr-defined]
    if not points:
        raise MessageError("JointTrajectory has no points")
    index = {name: i for i, name in enumerate(joint_order)}
    unknown = [name for name in names if name not in index]
    if unknown:
        raise MessageError(f"JointTrajectory names unknown joint(s) {unknown}; this robot has {list(joint_order)}")
    if len(set(names)) != len(names):
        raise MessageError(f"JointTrajectory names a joint twice: {names}")
    point = points[0]
    if len(point.positions) != len(names):
        raise MessageError(f"JointTrajectory has {len(names)} joint names but {len(point.positions)} positions")
    positions = np.full(len(joint_order), np.nan)
    velocities = None
    order = [index[name] for name in names]
    positions[order] = point.positions
    if len(point.velocities):
        if len(point.velocities) != len(names):
            raise MessageError(f"JointTrajectory has {len(names)} joint names but {len(point.velocities)} velocities")
        velocities = np.full(len(joint_order), np.nan)
        velocities[order] = point.velocities
    if not np.all(np.isfinite(positions[order])):
        raise MessageError(f"JointTrajectory positions must be finite, got {list(point.positions)}")
    return TrajectoryCommand(to_seconds(message.header.stamp), positions, velocities)  # type: ignore[attr-defined]


def decode_pose(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """(position xyz, orientation as the raw x, y, z, w fields)."""
    pose = deserialize(data, POSE)
    p, q = pose.position, pose.orientation  # type: ignore[attr-defined]
    return np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w])
