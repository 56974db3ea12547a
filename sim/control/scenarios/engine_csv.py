"""A motion written as the engine's CSV (`python -m sim.engine --csv PATH`): the one scenario module that writes."""

from __future__ import annotations

from pathlib import Path

from sim.control.scenarios.motion import Motion
from sim.wire.joint_csv import write_joint_csv

__all__ = ["write_engine_csv"]


def write_engine_csv(path: Path, motion: Motion) -> None:
    """The desired joint positions as the engine's CSV (sim.wire.joint_csv), exact doubles."""
    write_joint_csv(path, motion.robot.joint_names, motion.times, motion.positions, exact=True)
