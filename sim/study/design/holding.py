"""Whether the arm's drives can hold it still against gravity, along a planned approach: each joint's static load
(the torque, or a prismatic joint's force, that holds the arm at rest where it is) against that joint's effort limit.
Pure logic: the loads come from the scene's world (SceneWorld.gravity_loads, pybullet's inverse dynamics at zero
velocity and acceleration from the URDF's masses).

The limit is the URDF's `effort` (RobotSpec.max_effort), which is also the force limit of the engine stand-in's
drives (sim.engine.physics.DriveParams.for_robot; a drive's force is clamped to it, gravity feed-forward included):
a joint whose load exceeds it cannot hold the arm, which then sinks (a lift that cannot carry what hangs on it
fell 15.7 m in the engine's physics) and on a real robot faults or falls. An approach at rest and every point it
brakes to on a press lie on its path, so its samples cover them."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Shortfall", "holding_line", "shortfalls", "unit"]


@dataclass(frozen=True)
class Shortfall:
    """A joint that cannot hold the arm: the most it must exert, where (the sample's index), and its limit."""

    joint: str
    unit: str  # "N·m" or "N"
    needed: float  # the largest |static load| over the samples
    limit: float
    sample: int


def unit(joint_type: str) -> str:
    """The unit of a joint's effort: a force for a prismatic joint, a torque for a turning one."""
    return "N" if joint_type == "prismatic" else "N·m"


def shortfalls(
    joint_names: Sequence[str], joint_types: Sequence[str], loads: np.ndarray, limits: np.ndarray
) -> list[Shortfall]:
    """Each joint whose static load (N, dof) exceeds its effort limit (dof,) at any sample, at its worst sample, in
    the joints' order; [] when every joint holds the arm everywhere. An unlimited joint (inf) always holds."""
    loads = np.abs(np.asarray(loads, dtype=float))
    limits = np.asarray(limits, dtype=float)
    if loads.ndim != 2 or loads.shape[1] != len(joint_names) or limits.shape != (len(joint_names),):
        raise ValueError(f"loads {loads.shape} and limits {limits.shape} do not match {len(joint_names)} joints")
    found = []
    for j, name in enumerate(joint_names):
        if loads.shape[0] == 0:
            break
        worst = int(np.argmax(loads[:, j]))
        if loads[worst, j] > limits[j]:
            found.append(Shortfall(name, unit(joint_types[j]), float(loads[worst, j]), float(limits[j]), worst))
    return found


def holding_line(shortfall: Shortfall, where: str) -> str:
    """One line: which joint, `where` (a path and its time, or home), what holding the arm takes and the limit."""
    return (
        f"{shortfall.joint} cannot hold the arm {where}: it needs {shortfall.needed:.1f} {shortfall.unit}, its effort "
        f"limit is {shortfall.limit:g} {shortfall.unit}"
    )
