"""The arms the study's tests run on, by name: the example arms (sim.robots.examples: STUDY_ARMS and LAB_ARMS) and
the third-party ones (tests.robot_files.THIRD_PARTY_URDFS)."""

from __future__ import annotations

from pathlib import Path

from sim.robots.examples import write_example_arm
from tests.robot_files import THIRD_PARTY_URDFS

__all__ = ["study_arm"]


def study_arm(directory: Path, name: str) -> Path:
    """The URDF of arm `name`: a third-party one where it lies, an example arm written into `directory`."""
    if name in THIRD_PARTY_URDFS:
        return THIRD_PARTY_URDFS[name]
    return write_example_arm(directory, name)
