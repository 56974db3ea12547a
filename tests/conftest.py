"""Session fixtures: one real roscore per test session and the pytest process as one rospy test node; and the test
lanes (tests/lanes.py): `--lane NAME --on PYTHON` keeps the tests of those lanes that run on that Python."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.lanes import LANES, PYTHONS, Lane, declared_lanes, lane_from_marker, unit_lane
from tests.rosenv import EndpointProcess, RosCore

TESTS = Path(__file__).resolve().parent
REPO = TESTS.parent


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("lanes", "launch_scripts/test.sh's lanes (tests/lanes.py)")
    group.addoption("--lane", action="append", choices=LANES, help="run the tests of this lane (repeatable)")
    group.addoption("--on", choices=PYTHONS, help="which of the suite's Pythons this run is (with --lane)")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "lane(name, on=(python, ...)): the lane of test.sh that runs it, and where")
    if config.getoption("--lane") and not config.getoption("--on"):
        raise pytest.UsageError("--lane needs --on: which of the suite's Pythons this run is")


def _selected(config: pytest.Config) -> tuple[tuple[str, ...], str] | None:
    lanes = config.getoption("--lane")
    return (tuple(lanes), config.getoption("--on")) if lanes else None


def _relative(path: Path) -> str:
    return path.resolve().relative_to(REPO).as_posix()


def pytest_ignore_collect(collection_path: Path, config: pytest.Config) -> bool | None:
    """Not even import a test file none of whose tests the selected lanes run on this Python."""
    selected = _selected(config)
    if selected is None or not collection_path.name.startswith("test_") or collection_path.suffix != ".py":
        return None
    unit = unit_lane(_relative(collection_path))
    own, tests = (unit, []) if unit else declared_lanes(collection_path.read_text(encoding="utf-8"))
    return not any(lane.runs(*selected) for lane in [own, *tests] if lane is not None) or None


def _lane(item: pytest.Item) -> Lane | None:
    marker = item.get_closest_marker("lane")
    if marker is not None:
        return lane_from_marker(marker.args, marker.kwargs)
    return unit_lane(_relative(item.path))


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    unlaned = sorted({_relative(item.path) for item in items if _lane(item) is None})
    if unlaned:
        raise pytest.UsageError(f"no test lane for {', '.join(unlaned)}: see tests/lanes.py")
    selected = _selected(config)
    if selected is None:
        return
    runs = {item.nodeid: _lane(item).runs(*selected) for item in items}  # type: ignore[union-attr]
    config.hook.pytest_deselected(items=[item for item in items if not runs[item.nodeid]])
    items[:] = [item for item in items if runs[item.nodeid]]


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
