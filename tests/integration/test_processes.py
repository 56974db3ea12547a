"""sim.processes: a session's roscore leaves nothing behind but the logs asked for; a publisher's own word on whom
it writes to. And the two gaps in rospy's publishing that a loaded machine opens: a subscriber counted before it
connects, and a queued message dropped when its publisher goes away."""

from __future__ import annotations

import os
import shutil
import threading
from pathlib import Path

import pytest

from sim.control import controller_node
from sim.processes import RosCore, wait_for, writes_to
from sim.robots import load_robot

pytestmark = pytest.mark.lane("beside", on=("project",))


def test_a_roscore_removes_its_own_temp_dir_unless_its_logs_are_kept() -> None:
    core = RosCore()
    assert (core.tmp / "log").is_dir() or any(core.tmp.iterdir())
    core.stop()
    assert not core.tmp.exists()
    kept = RosCore()
    try:
        kept.stop(keep_logs=True)
        assert any(kept.tmp.glob("roscore-*.log"))
    finally:
        shutil.rmtree(kept.tmp, ignore_errors=True)


def test_a_dir_that_was_given_is_left_alone_and_no_master_outlives_its_roscore(tmp_path) -> None:
    core = RosCore(tmp=tmp_path / "core")
    master_pid = core._master_pid()
    assert master_pid is not None
    core.stop()
    assert (tmp_path / "core").is_dir()
    assert gone(master_pid)


def gone(pid: int) -> bool:
    """No such process, or only its zombie (waiting for its parent to reap it)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"
    except FileNotFoundError:
        return True


def test_a_subscriber_counts_a_publisher_before_it_connects_and_only_the_publisher_knows(ros_node, monkeypatch):
    """rospy adds the connection to its subscriber before the thread that opens the socket has run: held here, as a
    CPU-starved machine can hold it. What is published meanwhile is lost (a lockstep engine's first joint state once
    was), so the controllers wait for the publisher's word (its getBusInfo)."""
    from rospy.core import get_node_uri
    from rospy.impl import tcpros_pubsub
    from std_msgs.msg import String

    connect = tcpros_pubsub.robust_connect_subscriber
    release = threading.Event()

    def held_connect(*args) -> None:
        release.wait(10)
        connect(*args)

    monkeypatch.setattr(tcpros_pubsub, "robust_connect_subscriber", held_connect)
    topic = f"/held_connection_{os.getpid()}"
    publisher = ros_node.Publisher(topic, String, queue_size=1)
    subscriber = ros_node.Subscriber(topic, String, lambda message: None)
    me, uri = ros_node.get_name(), get_node_uri()
    try:
        wait_for(lambda: subscriber.impl.has_connection(uri), 10, "the subscriber to count the publisher")
        assert publisher.get_num_connections() == 0 and not writes_to(uri, topic, me)
        release.set()
        wait_for(lambda: writes_to(uri, topic, me), 10, "the publisher to write to the subscriber")
    finally:
        release.set()
        subscriber.unregister()
        publisher.unregister()


def test_a_controller_closes_only_once_every_subscriber_has_what_it_published(ros_node, monkeypatch):
    """rospy's queued publisher writes to each subscriber from a thread of its own, and unregistering drops what that
    thread still holds: the last commands of a run once missed a busy recorder. The thread's write is held here, as
    a CPU-starved machine holds it, and let go only once close() is waiting for it; without that wait, close()
    would unregister first and the subscriber would get nothing."""
    from rospy.core import get_node_uri
    from rospy.impl.tcpros_base import TCPROSTransport
    from trajectory_msgs.msg import JointTrajectory

    robot = load_robot("igt")
    topic = robot.command_topic
    release = threading.Event()
    write = TCPROSTransport.write_data

    def held_write(transport, data) -> bool:
        if transport.name == topic:
            release.wait(10)
        return write(transport, data)

    unwritten = controller_node.unwritten_subscribers

    def release_once_asked(publisher) -> list[str]:
        behind = unwritten(publisher)
        release.set()
        return behind

    monkeypatch.setattr(TCPROSTransport, "write_data", held_write)
    monkeypatch.setattr(controller_node, "unwritten_subscribers", release_once_asked)
    received: list[float] = []
    subscriber = ros_node.Subscriber(topic, JointTrajectory, lambda m: received.append(m.header.stamp.to_sec()))
    node = controller_node.ControllerNode(robot, threading.Event())
    try:
        me, uri = ros_node.get_name(), get_node_uri()
        wait_for(lambda: writes_to(uri, topic, me), 10, "the command publisher to write to the subscriber")
        for step in range(1, 6):
            node.publish_command(step * 0.02, [0.0] * robot.dof, [0.0] * robot.dof)
        assert me in unwritten(node.command_pub)
        node.close()
        wait_for(lambda: len(received) == 5, 10, f"the five commands (have {len(received)})")
        assert received == [0.02, 0.04, 0.06, 0.08, 0.1]
    finally:
        release.set()
        subscriber.unregister()
