"""The contract between the game engine and the controller, each rule once.

Both sides of every run keep it: the engine stand-in, the physics node, the commander, the study runner and the
analysis of their recordings. A rule changed here changes for all of them.
"""

from __future__ import annotations

import argparse
import enum
import sys
from collections.abc import Sequence

import numpy as np

from sim.errors import SimError
from sim.geometry.frames import euler_xyz_to_quat, quat_to_euler_xyz

__all__ = [
    "STEP_S",
    "STAMP_TOLERANCE_S",
    "MessageError",
    "PoseConvention",
    "add_pose_convention_argument",
    "positions_by_name",
]

# The control step: Unity's FixedUpdate period by default, the thesis's controller rate (50 Hz).
STEP_S = 0.02
# Two stamps closer than this are the same instant: stamps travel as whole nanoseconds and rospy's Time.from_sec
# truncates (1.16 s arrives as 1.159999999 s); steps are never closer than a millisecond.
STAMP_TOLERANCE_S = 1e-6


class MessageError(SimError, ValueError):
    """Bytes that are not the expected ROS 1 message, or a message the sim cannot use."""


class PoseConvention(enum.Enum):
    """How the goal pose's orientation travels in a geometry_msgs/Pose.

    QUATERNION: a real quaternion (ROS's meaning of the fields). EULER: the thesis's set-up (Vissers, TU/e 2023),
    whose Simulink model wrote fixed-axis XYZ Euler angles (roll, pitch, yaw) into x, y, z and 0 into w.
    """

    QUATERNION = "quaternion"
    EULER = "euler"

    def encode(self, quaternion: Sequence[float] | np.ndarray) -> tuple[float, float, float, float]:
        """The orientation fields (x, y, z, w) that carry the unit `quaternion` (x, y, z, w)."""
        if self is PoseConvention.EULER:
            roll, pitch, yaw = quat_to_euler_xyz(quaternion)
            return float(roll), float(pitch), float(yaw), 0.0
        x, y, z, w = (float(value) for value in quaternion)
        return x, y, z, w

    def decode(self, fields: Sequence[float] | np.ndarray) -> np.ndarray:
        """The unit quaternion (x, y, z, w) that the orientation `fields` (x, y, z, w) carry; MessageError when they
        carry none (a quaternion of zero length, or not finite)."""
        values = np.asarray(fields, dtype=float)
        if values.shape != (4,) or not np.all(np.isfinite(values)):
            raise MessageError(f"pose orientation {values.tolist()} is not 4 finite numbers")
        if self is PoseConvention.EULER:
            return euler_xyz_to_quat(*values[:3])
        norm = float(np.linalg.norm(values))
        if norm < 1e-9:
            raise MessageError(f"pose orientation {values.tolist()} is not a quaternion")
        return values / norm


class _OldPoseEulerFlag(argparse.Action):
    """`--pose-euler`, the commander's old name for `--pose-convention euler`: still accepted, with a warning on
    stderr (one line, as a command's user reads it, where warnings.warn would show argparse's source line)."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: object,
        option_string: str | None = None,
    ) -> None:
        print(f"{parser.prog}: warning: --pose-euler is deprecated; use --pose-convention euler", file=sys.stderr)
        namespace.pose_convention = PoseConvention.EULER.value


def add_pose_convention_argument(parser: argparse.ArgumentParser, accept_old_flag: bool = False) -> None:
    """The one flag every command that reads or writes the goal pose takes (`pose_convention`: a PoseConvention
    value); `accept_old_flag` also takes the commander's old `--pose-euler`."""
    parser.add_argument(
        "--pose-convention",
        choices=[c.value for c in PoseConvention],
        default=PoseConvention.QUATERNION.value,
        help="orientation fields of the goal pose: a quaternion (default), or the thesis's XYZ Euler "
        "angles in x, y, z with w = 0",
    )
    if accept_old_flag:
        parser.add_argument("--pose-euler", nargs=0, action=_OldPoseEulerFlag, help=argparse.SUPPRESS)


def positions_by_name(names: Sequence[str], positions: Sequence[float], joint_order: Sequence[str]) -> np.ndarray:
    """A JointState's positions in `joint_order`. The message may name more joints, in any order; MessageError when
    it lacks one of `joint_order`, or its positions do not match its names."""
    names = list(names)
    missing = [name for name in joint_order if name not in names]
    if missing or len(positions) != len(names):
        raise MessageError(
            f"JointState names {names} with {len(positions)} positions, not covering {list(joint_order)}"
        )
    index = {name: i for i, name in enumerate(names)}
    return np.array([positions[index[name]] for name in joint_order], dtype=float)
