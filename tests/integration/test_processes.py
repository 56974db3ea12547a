"""sim.processes: a session's roscore leaves nothing behind but the logs asked for; a publisher's own word on whom
it writes to."""

from __future__ import annotations

import os
import shutil
import threading
from pathlib import Path

from sim.processes import RosCore, wait_for, writes_to


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
