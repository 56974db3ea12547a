"""Any robot the ROS way: vr_sim's description.launch (robot_description set by `python -m sim.robots --urdf`, the
description node, Debian's robot_state_publisher) turns /<robot>/joint_states into the TF of every link, which
matches our FK; the end-effector goal from /<robot>/pose is a TF frame too. Real roslaunch, real roscore."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from measuring.procfs import command_lines
from sim.geometry.frames import quat_to_matrix
from sim.geometry.kinematics import chain_for, pose_matrix
from sim.robots import RobotSpec, load_robot
from tests.robot_files import THIRD_PARTY_URDFS
from tests.rosenv import PYTHON, REPO, ManagedProcess, wait_for

pytestmark = pytest.mark.lane("beside", on=("noetic",))

WORKSPACE_SETUP = REPO / "catkin_ws" / "devel" / "setup.bash"


class TfListener:
    """Every transform seen on /tf and /tf_static, the latest per child frame."""

    def __init__(self, rospy) -> None:
        from tf2_msgs.msg import TFMessage

        self._lock = threading.Lock()
        self.transforms: dict[str, tuple[str, np.ndarray]] = {}
        self._subscribers = [
            rospy.Subscriber(topic, TFMessage, self._on_tf, queue_size=1000) for topic in ("/tf", "/tf_static")
        ]

    def _on_tf(self, message) -> None:
        with self._lock:
            for transform in message.transforms:
                t, r = transform.transform.translation, transform.transform.rotation
                pose = pose_matrix((t.x, t.y, t.z), quat_xyzw=(r.x, r.y, r.z, r.w))
                self.transforms[transform.child_frame_id] = (transform.header.frame_id, pose)

    def lookup(self, target: str, source: str = "world") -> np.ndarray | None:
        """Pose of `source`→`target` composed from the parents' chain, or None while a link is missing."""
        with self._lock:
            pose, frame = np.eye(4), target
            while frame != source:
                if frame not in self.transforms:
                    return None
                parent, local = self.transforms[frame]
                pose, frame = local @ pose, parent
            return pose

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()


def interpreters_of(script: str) -> set[str]:
    """The programs running `script` (a path's end), from /proc: an interpreter's path, or the script's own."""
    ending = os.fsencode(script)
    return {os.fsdecode(argv[0]) for argv in command_lines().values() if any(arg.endswith(ending) for arg in argv)}


def node_pids(ros_node, names: list[str]) -> list[int]:
    """The PIDs of the named nodes, from their own slave API (roslaunch starts each node in a session of its own,
    so stopping roslaunch's process group does not reach them)."""
    import xmlrpc.client

    from rosgraph.masterapi import Master, MasterError

    pids = []
    for name in names:
        try:
            uri = Master("/pytest").lookupNode(name)
            code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/pytest")
        except (MasterError, OSError):
            continue
        if code == 1:
            pids.append(int(pid))
    return pids


@pytest.fixture
def described(roscore, ros_node, tmp_path: Path) -> Iterator:
    started: list[ManagedProcess] = []
    listeners: list[TfListener] = []

    names: list[str] = []

    def launch(robot: RobotSpec) -> TfListener:
        names.append(robot.name)
        command = (
            f"source {WORKSPACE_SETUP} && exec roslaunch vr_sim description.launch "
            f"robot:={robot.cli_args[1]} python:={PYTHON}"
        )
        process = ManagedProcess(["bash", "-c", command], roscore.env, tmp_path, f"{robot.name}_description")
        started.append(process)
        process.wait_for_output("description node: ", timeout=60)
        assert PYTHON in interpreters_of("vr_sim/description_node")  # python:= is the Python the node runs on
        listener = TfListener(ros_node)
        listeners.append(listener)
        return listener

    yield launch
    for listener in listeners:
        listener.close()
    nodes = node_pids(ros_node, ["/robot_state_publisher"] + [f"/{name}_description" for name in names])
    for process in started:
        process.stop(timeout=20)  # roslaunch escalates SIGINT to SIGTERM after 15 s
    for pid in nodes:  # whatever roslaunch left behind, by PID (and only if it is still that node)
        with contextlib.suppress(OSError):
            if (
                b"robot_state_publisher" in Path(f"/proc/{pid}/cmdline").read_bytes()
                or b"sim.description_node" in Path(f"/proc/{pid}/cmdline").read_bytes()
            ):
                os.kill(pid, signal.SIGKILL)


def publish_until(ros_node, topic: str, message, done, what: str) -> None:
    publisher = ros_node.Publisher(topic, type(message), queue_size=10)
    try:

        def published_and_done():
            publisher.publish(message)
            return done()

        wait_for(published_and_done, timeout=20, what=what, interval=0.1)
    finally:
        publisher.unregister()


@pytest.mark.parametrize("name", sorted(THIRD_PARTY_URDFS))
def test_robot_state_publisher_gives_the_tf_of_every_link_and_it_matches_our_fk(described, ros_node, name):
    from geometry_msgs.msg import Pose
    from sensor_msgs.msg import JointState

    robot = load_robot(str(THIRD_PARTY_URDFS[name]))
    tf = described(robot)
    assert ros_node.get_param("/robot_description") == robot.urdf_path.read_text()
    q = np.clip(robot.home + np.linspace(0.1, 0.4, robot.dof), robot.lower, robot.upper)
    state = JointState(name=list(robot.joint_names), position=list(q))
    expected = chain_for(robot).fk(q)

    def ee_matches() -> bool:
        pose = tf.lookup(robot.ee_link)
        return pose is not None and np.allclose(pose, expected, atol=1e-6)

    publish_until(ros_node, robot.joint_states_topic, state, ee_matches, f"TF of {robot.ee_link} at FK(q)")
    for link in ("left_finger", "right_finger") if name == "lift_arm" else ():  # held by the sim, still in TF
        assert tf.lookup(link) is not None
    if name == "lbr_iiwa":  # the root link is not "world": the description node links them
        parent, pose = tf.transforms["lbr_iiwa_link_0"]
        assert parent == "world" and np.allclose(pose, np.eye(4))

    goal = Pose()
    goal.position.x, goal.position.y, goal.position.z = 0.4, -0.1, 0.5
    goal.orientation.z, goal.orientation.w = np.sin(0.3), np.cos(0.3)
    target = f"{robot.name}_ee_target"

    def goal_shown() -> bool:
        return target in tf.transforms

    publish_until(ros_node, robot.pose_topic, goal, goal_shown, f"the {target} frame")
    parent, pose = tf.transforms[target]
    assert parent == robot.base_link
    np.testing.assert_allclose(pose[:3, 3], [0.4, -0.1, 0.5], atol=1e-9)
    np.testing.assert_allclose(pose[:3, :3], quat_to_matrix([0.0, 0.0, np.sin(0.3), np.cos(0.3)]), atol=1e-9)


def test_a_robot_that_cannot_be_loaded_ends_the_launch_with_one_clear_line(roscore, tmp_path):
    command = (
        f"source {WORKSPACE_SETUP} && exec roslaunch vr_sim description.launch robot:=/no/such/arm.urdf "
        f"python:={PYTHON}"
    )
    process = ManagedProcess(["bash", "-c", command], roscore.env, tmp_path, "bad_description")
    try:
        assert process.wait(60) != 0
    finally:
        process.stop()
    assert "URDF not found: /no/such/arm.urdf" in process.output()
