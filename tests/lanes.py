"""Which lane of launch_scripts/test.sh runs each test, and on which of the suite's Pythons (pure; conftest uses it).

An integration test file says it itself, next to its imports:

    pytestmark = pytest.mark.lane("alone", on=("project",))

and a test that differs from its file says so with the same decorator. Unit tests are laned by their folder. The
marker's arguments are literals, so a file's lanes are read from its source without importing it: a Python that
runs none of a file's tests never imports it (the 3.10 venv has no rospy, for example).
"""

from __future__ import annotations

import ast
from dataclasses import dataclass

__all__ = ["LANES", "PYTHONS", "Lane", "declared_lanes", "lane_from_marker", "unit_lane"]

# The lanes (test.sh runs the alone lanes at the normal priority, and the others at the same time under SCHED_IDLE,
# on the CPU the alone lanes leave):
#   endpoint  the endpoint's integration tests, which mostly wait on sockets and timers
#   unit      unit tests, pure logic, CPU only
#   beside    command lines and nodes that need CPU but no timing
#   alone     one run at a time, with nothing beside it at its priority: a robot through ROS (the study's lockstep
#             sessions, the lockstep campaigns and their bags, the engine, the physics node, the commander), the
#             endpoint timed on a slow link or beside
#             CPU burners of its own; the realtime lane beside them
#   realtime  a real arm's stand-in driven on wall time (the reality condition, its faults, the trajectory
#             controller): light on CPU but needing it when it wakes; under SCHED_RR, beside the alone lanes
#   quiet     with nothing beside it at its priority or above, after the realtime lane: what the wall clock paces
#             and measures to a fine bound (the catkin demo's tracking, the VR page's clock, the base case's
#             campaign) and the browsers' software rendering (about a core each, which beside the realtime lane
#             would leave the idle lanes none)
LANES = ("endpoint", "unit", "beside", "alone", "realtime", "quiet")
# The suite's Pythons: the project's venv (Debian's), ROS Noetic's 3.8 with Debian's rospy, Ubuntu 22.04's 3.10.
PYTHONS = ("project", "noetic", "jammy")

# Unit tests by folder, the most specific first: which Pythons run them.
_UNIT_FOLDERS = (
    ("tests/unit/bridge", ("project", "noetic")),
    ("tests/unit/measuring", ("project", "noetic")),
    ("tests/unit/sim", ("project", "noetic", "jammy")),
    ("tests/unit", ("project",)),
)


@dataclass(frozen=True)
class Lane:
    name: str
    on: tuple[str, ...]

    def runs(self, lanes: tuple[str, ...], python: str) -> bool:
        return self.name in lanes and python in self.on


def unit_lane(relative_path: str) -> Lane | None:
    """The lane of a test under tests/unit, by its folder; None elsewhere."""
    for folder, pythons in _UNIT_FOLDERS:
        if relative_path.startswith(folder + "/"):
            return Lane("unit", pythons)
    return None


def lane_from_marker(args: tuple[object, ...], kwargs: dict[str, object]) -> Lane:
    """A lane marker's arguments as a Lane; ValueError names what is wrong."""
    if len(args) != 1 or set(kwargs) != {"on"}:
        raise ValueError('a lane marker is lane("NAME", on=("PYTHON", ...))')
    name, on = args[0], kwargs["on"]
    if name not in LANES:
        raise ValueError(f"no lane {name!r}; the lanes are {', '.join(LANES)}")
    if not isinstance(on, tuple) or not on or any(python not in PYTHONS for python in on):
        raise ValueError(f"on={on!r}: a tuple of the suite's Pythons ({', '.join(PYTHONS)})")
    return Lane(str(name), on)


def declared_lanes(source: str) -> tuple[Lane | None, list[Lane]]:
    """A test file's own lane (its pytestmark's) and the lanes its tests declare, read from its source."""
    tree = ast.parse(source)
    own = None
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "pytestmark" for t in node.targets):
            marks = node.value.elts if isinstance(node.value, (ast.List, ast.Tuple)) else [node.value]
            found = [lane for lane in map(_lane_call, marks) if lane is not None]
            own = found[0] if found else own
    tests = [
        lane
        for node in ast.walk(tree)
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
        for lane in map(_lane_call, node.decorator_list)
        if lane is not None
    ]
    return own, tests


def _lane_call(node: ast.expr) -> Lane | None:
    """`pytest.mark.lane(...)` as a Lane; None for any other expression."""
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "lane"):
        return None
    args = tuple(ast.literal_eval(arg) for arg in node.args)
    kwargs = {keyword.arg or "": ast.literal_eval(keyword.value) for keyword in node.keywords}
    return lane_from_marker(args, kwargs)
