"""tests/lanes.py: every test file is in a lane of launch_scripts/test.sh, and a lane is read from a file's source."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.lanes import LANES, Lane, declared_lanes, lane_from_marker, unit_lane

TESTS = Path(__file__).resolve().parents[1]
REPO = TESTS.parent


def test_every_test_file_is_in_a_lane() -> None:
    files = sorted(TESTS.rglob("test_*.py"))
    assert len(files) > 50
    for path in files:
        relative = path.relative_to(REPO).as_posix()
        own, _ = declared_lanes(path.read_text(encoding="utf-8"))
        assert (unit_lane(relative) or own) is not None, f"{relative}: no lane (pytestmark = pytest.mark.lane(...))"


def test_test_sh_runs_every_lane_on_every_python_a_test_asks_for() -> None:
    script = (REPO / "launch_scripts/test.sh").read_text(encoding="utf-8")
    runs = {
        (lane, python)
        for python, lanes in re.findall(r"^\s*(?:if .* then )?run \S+ (\w+) ([\w ]+?) --", script, re.M)
        for lane in lanes.split()
    }
    asked = set()
    for path in TESTS.rglob("test_*.py"):
        own, tests = declared_lanes(path.read_text(encoding="utf-8"))
        for lane in [unit_lane(path.relative_to(REPO).as_posix()), own, *tests]:
            asked |= {(lane.name, python) for python in lane.on} if lane else set()
    assert {lane for lane, _ in asked} == set(LANES)
    assert asked <= runs, f"test.sh runs no {sorted(asked - runs)}"


def test_a_files_lane_and_its_tests_own_are_read_without_importing_it() -> None:
    source = """
import pytest
import module_that_does_not_exist

pytestmark = [pytest.mark.lane("alone", on=("project",)), pytest.mark.timeout(60)]


@pytest.mark.lane("alone", on=("noetic",))
def test_on_noetic() -> None: ...
"""
    assert declared_lanes(source) == (Lane("alone", ("project",)), [Lane("alone", ("noetic",))])
    assert declared_lanes("import pytest\npytestmark = pytest.mark.timeout(5)\n") == (None, [])


def test_unit_tests_are_laned_by_folder() -> None:
    assert unit_lane("tests/unit/bridge/test_config.py") == Lane("unit", ("project", "noetic"))
    assert unit_lane("tests/unit/sim/study/run/test_runner.py") == Lane("unit", ("project", "noetic", "jammy"))
    assert unit_lane("tests/unit/test_architecture.py") == Lane("unit", ("project",))
    assert unit_lane("tests/integration/test_engine.py") is None


@pytest.mark.parametrize(
    ("args", "kwargs", "problem"),
    [
        (("fast",), {"on": ("project",)}, "no lane 'fast'"),
        (("alone",), {"on": ("python2",)}, "a tuple of the suite's Pythons"),
        (("alone",), {"on": "project"}, "a tuple of the suite's Pythons"),
        (("alone",), {}, 'lane("NAME", on=('),
    ],
)
def test_a_wrong_lane_marker_is_named(args: tuple[object, ...], kwargs: dict[str, object], problem: str) -> None:
    with pytest.raises(ValueError, match=problem.replace("(", r"\(")):
        lane_from_marker(args, kwargs)
