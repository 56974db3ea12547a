"""Session fixtures: one real roscore per test session and the pytest process as one rospy test node."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.rosenv import EndpointProcess, RosCore


@pytest.fixture(scope="session")
def roscore(request: pytest.FixtureRequest) -> Iterator[RosCore]:
    core = RosCore()
    # The test process itself talks to this master (as the single rospy node of the process).
    for key in ("ROS_MASTER_URI", "ROS_HOME", "ROS_LOG_DIR", "ROS_HOSTNAME"):
        os.environ[key] = core.env[key]
    try:
        yield core
    finally:
        failed = request.session.testsfailed > 0
        core.stop(keep_logs=failed)  # a failed session's roscore and node logs stay for reading
        if failed:
            print(f"\nroscore and node logs kept in {core.tmp}")


@pytest.fixture(scope="session")
def ros_node(roscore: RosCore):
    """rospy, initialised once for the whole session (init_node works once per process)."""
    import rospy

    rospy.init_node("pytest_probe", anonymous=True, disable_signals=True)
    yield rospy
    rospy.signal_shutdown("test session over")


@pytest.fixture
def log_dir(tmp_path: Path) -> Path:
    return tmp_path


@pytest.fixture
def endpoint(roscore: RosCore, ros_node, tmp_path: Path) -> Iterator[EndpointProcess]:
    process = EndpointProcess(roscore.env, tmp_path, name=f"endpoint_{os.getpid()}_{id(tmp_path) % 100000}")
    try:
        yield process
    finally:
        process.stop()
