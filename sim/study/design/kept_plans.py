"""A combination's plan kept in the cache (sim.cache) for the next process of the same input and code.

A simulated study plans the design's combinations in `simulate`, then again in every session's runner and simulated
participant: the same robot, scene, combinations and step, so the same plans, a few seconds of IK and contact checks
each time. The first planner keeps each plan in the cache under its verdict_key (the robot's content, the scene, the
combination, the step) and the fingerprint of the code that planned it (every source file of the `sim` package, and
the Python, NumPy and pybullet it ran on): any edit of the code, or another library, is another entry, planned
afresh. A plan is written as JSON whose floats read back to the same bits (float's repr), so a plan read is the plan
made: the same commands, the same report.

`plan_to_data` and `plan_from_data` are pure; `read_plan` and `keep_plan` touch the cache.
"""

from __future__ import annotations

import functools
import hashlib
import json
import platform
from pathlib import Path
from typing import Any

import numpy as np

from sim import cache
from sim.study.design.paths import ApproachPath
from sim.study.design.planned import PlannedApproach

__all__ = ["code_fingerprint", "keep_plan", "plan_from_data", "plan_to_data", "read_plan"]

_SIM = Path(__file__).resolve().parents[2]  # the sim package


def _array(values: np.ndarray) -> dict[str, Any]:
    return {"dtype": values.dtype.str, "shape": list(values.shape), "values": values.ravel().tolist()}


def _from_array(data: dict[str, Any]) -> np.ndarray:
    return np.array(data["values"], dtype=np.dtype(data["dtype"])).reshape(data["shape"])


def plan_to_data(plan: PlannedApproach) -> dict[str, Any]:
    """The plan as JSON-ready data: every field, arrays with their dtype and shape."""
    path = plan.path
    return {
        "path": {
            "name": path.name,
            "standoff": path.standoff,
            "peak_speed": path.peak_speed,
            "dt": path.dt,
            "times": _array(path.times),
            "positions": _array(path.positions),
            "speeds": _array(path.speeds),
            "length": path.length,
        },
        "positions": _array(plan.positions),
        "velocities": _array(plan.velocities),
        "reached_standoff": plan.reached_standoff,
        "min_clearance": dict(plan.min_clearance),
        "distances": _array(plan.distances),
        "problems": list(plan.problems),
        "unreachable": plan.unreachable,
        "remedies": list(plan.remedies),
        "constraints": plan.constraints,
    }


def plan_from_data(data: dict[str, Any]) -> PlannedApproach:
    """The plan plan_to_data made the data of. KeyError, TypeError or ValueError where it is not one."""
    path = data["path"]
    return PlannedApproach(
        ApproachPath(
            str(path["name"]),
            float(path["standoff"]),
            float(path["peak_speed"]),
            float(path["dt"]),
            _from_array(path["times"]),
            _from_array(path["positions"]),
            _from_array(path["speeds"]),
            float(path["length"]),
        ),
        _from_array(data["positions"]),
        _from_array(data["velocities"]),
        float(data["reached_standoff"]),
        {str(name): float(value) for name, value in data["min_clearance"].items()},
        _from_array(data["distances"]),
        [str(problem) for problem in data["problems"]],
        int(data["unreachable"]),
        [str(remedy) for remedy in data["remedies"]],
        str(data["constraints"]),
    )


def _version(distribution: str) -> str:
    try:
        from importlib.metadata import version

        return version(distribution)
    except Exception:  # not installed as a distribution (a system package): its module's file tells it apart
        return "unknown"


@functools.lru_cache(maxsize=None)
def code_fingerprint() -> str:
    """The SHA-256 of every source file of the `sim` package (by its path in it) and of the versions of the Python,
    NumPy and pybullet this process runs: what a plan's bits depend on besides its input."""
    digest = hashlib.sha256()
    for source in sorted(_SIM.rglob("*.py")):
        digest.update(source.relative_to(_SIM).as_posix().encode("utf-8") + b"\0")
        digest.update(source.read_bytes() + b"\0")
    libraries = [platform.python_version(), np.__version__, _version("pybullet")]
    digest.update(json.dumps(libraries).encode("utf-8"))
    return digest.hexdigest()


def _entry(key: str) -> Path:
    return cache.entry_path("plans", json.dumps([code_fingerprint(), key]), ".json")


def read_plan(key: str) -> PlannedApproach | None:
    """The plan kept under verdict_key `key` by this code; None where there is none, or it cannot be read."""
    try:
        return plan_from_data(json.loads(_entry(key).read_text(encoding="utf-8")))
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None  # not kept yet, or unreadable: planned again


def keep_plan(key: str, plan: PlannedApproach) -> None:
    """Keep `plan` under verdict_key `key`, whole or not at all (a warning where the cache cannot be written)."""
    cache.keep(_entry(key), json.dumps(plan_to_data(plan), allow_nan=True))
