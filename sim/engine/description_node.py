"""The simulated robot the ROS way, for RViz, Foxglove and robot_state_publisher: any robot, from its URDF.

`python -m sim.description_node --robot ROBOT` (or vr_sim's description.launch, which adds Debian's
robot_state_publisher and, with rviz:=true, RViz):
  robot_description   the robot's URDF, as a parameter (relative to the node's namespace, like every name here)
  joint_states        /<robot>/joint_states with the joints the simulation holds still (those off the controlled
                      chain, e.g. a gripper's fingers, locked at 0) added, so robot_state_publisher has every joint
                      and publishes the TF of every link. Restamped with this node's ROS time (the wall clock
                      unless /use_sim_time): the engine stamps with simulated time, which TF listeners on the wall
                      clock (RViz) would drop as long expired
  /tf_static          world → the URDF's root link (identity: the physics places the root link at the world
                      origin), unless the root link is itself called "world"
  /tf                 <base link> → <robot>_ee_target: the end-effector goal from /<robot>/pose (the commander's
                      marker), so the goal shows next to the end-effector link's own frame
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading

import numpy as np
import rospy
from geometry_msgs.msg import Pose, TransformStamped
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from sim.entry import EXIT_BAD_INPUT, EXIT_OK, fail, without_ros_arguments
from sim.errors import SimError
from sim.robots import RobotSpec, add_robot_arguments, robot_from_args
from sim.robots.urdf_model import parse_urdf
from sim.wire.contract import MessageError, PoseConvention, add_pose_convention_argument
from sim.wire.rosnode import init_node

__all__ = ["WORLD_FRAME", "target_frame", "locked_joints", "DescriptionNode", "main"]

WORLD_FRAME = "world"


def target_frame(robot: RobotSpec) -> str:
    return f"{robot.name}_ee_target"


def locked_joints(robot: RobotSpec, urdf_text: str) -> list[str]:
    """The URDF's moving joints the simulation does not control (held at 0)."""
    model = parse_urdf(urdf_text, str(robot.urdf_path))
    return [joint.name for joint in model.joints if joint.moving and joint.name not in robot.joint_names]


class DescriptionNode:
    def __init__(self, robot: RobotSpec, pose_convention: PoseConvention) -> None:
        self.robot = robot
        self.pose_convention = pose_convention
        urdf_text = robot.urdf_path.read_text(encoding="utf-8")
        self.root_link = parse_urdf(urdf_text, str(robot.urdf_path)).root
        self.locked = locked_joints(robot, urdf_text)
        rospy.set_param("robot_description", urdf_text)
        self._joint_states = rospy.Publisher("joint_states", JointState, queue_size=100, tcp_nodelay=True)
        self._tf = rospy.Publisher("/tf", TFMessage, queue_size=100)
        self._tf_static = rospy.Publisher("/tf_static", TFMessage, queue_size=1, latch=True)
        if self.root_link != WORLD_FRAME:
            self._tf_static.publish(
                TFMessage(
                    [
                        self._transform(
                            WORLD_FRAME, self.root_link, rospy.Time(0), np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
                        )
                    ]
                )
            )
        self._subscribers = [
            rospy.Subscriber(robot.joint_states_topic, JointState, self._on_joint_state, tcp_nodelay=True),
            rospy.Subscriber(robot.pose_topic, Pose, self._on_pose),
        ]

    @staticmethod
    def _transform(
        parent: str, child: str, stamp: rospy.Time, position: np.ndarray, quat_xyzw: np.ndarray
    ) -> TransformStamped:
        transform = TransformStamped()
        transform.header.stamp = stamp
        transform.header.frame_id = parent
        transform.child_frame_id = child
        transform.transform.translation.x, transform.transform.translation.y, transform.transform.translation.z = (
            float(v) for v in position
        )
        rotation = transform.transform.rotation
        rotation.x, rotation.y, rotation.z, rotation.w = (float(v) for v in quat_xyzw)
        return transform

    def _on_joint_state(self, message: JointState) -> None:
        message.header.stamp = rospy.Time.now()
        if not self.locked:
            self._joint_states.publish(message)
            return
        full = JointState(
            header=message.header,
            name=list(message.name) + self.locked,
            position=list(message.position) + [0.0] * len(self.locked),
        )
        if len(message.velocity) == len(message.name):
            full.velocity = list(message.velocity) + [0.0] * len(self.locked)
        if len(message.effort) == len(message.name):
            full.effort = list(message.effort) + [0.0] * len(self.locked)
        self._joint_states.publish(full)

    def _on_pose(self, message: Pose) -> None:
        fields = [message.orientation.x, message.orientation.y, message.orientation.z, message.orientation.w]
        try:
            quaternion = self.pose_convention.decode(fields)
        except MessageError as error:
            rospy.logerr_throttle(1.0, f"pose on {self.robot.pose_topic}: {error}")
            return
        position = np.array([message.position.x, message.position.y, message.position.z])
        self._tf.publish(
            TFMessage(
                [
                    self._transform(
                        self.robot.base_link, target_frame(self.robot), rospy.Time.now(), position, quaternion
                    )
                ]
            )
        )

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m sim.description_node", description=__doc__.splitlines()[0])
    add_robot_arguments(parser)
    add_pose_convention_argument(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(without_ros_arguments(sys.argv[1:] if argv is None else argv))
    try:
        robot = robot_from_args(args)
    except SimError as error:
        return fail("sim.description_node", error, EXIT_BAD_INPUT)
    init_node(f"{robot.name}_description")
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    node = DescriptionNode(robot, PoseConvention(args.pose_convention))
    locked = f"; locked at 0: {', '.join(node.locked)}" if node.locked else ""
    print(
        f"description node: {robot.name} on {rospy.resolve_name('robot_description')}, joint states on "
        f"{rospy.resolve_name('joint_states')}{locked}",
        flush=True,
    )
    while not stop.is_set() and not rospy.is_shutdown():
        stop.wait(0.2)
    node.close()
    rospy.signal_shutdown("description node stopped")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
