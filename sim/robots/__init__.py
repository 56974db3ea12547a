"""Registry of the robots the toolkit knows, by name.

Adding a robot = dropping its URDF (here or anywhere on disk) and adding one `RobotSpec` to `_REGISTRY`.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["URDF_DIR", "RobotError", "RobotSpec", "ROBOT_NAMES", "get_robot"]

URDF_DIR = Path(__file__).resolve().parent / "urdf"


class RobotError(ValueError):
    """An unknown robot name or an inconsistent robot description."""


@dataclass(frozen=True)
class RobotSpec:
    name: str
    urdf_path: Path
    joint_names: tuple[str, ...]  # the controlled joints, in command order
    joint_types: tuple[str, ...]  # "revolute" | "prismatic"
    lower: np.ndarray  # position limits [rad or m]
    upper: np.ndarray
    max_velocity: np.ndarray  # [rad/s or m/s]
    max_effort: np.ndarray  # [N·m or N]
    base_link: str
    ee_link: str
    topic_prefix: str  # e.g. "/panda"; topics are <prefix>/joint_states etc.
    home: np.ndarray  # a comfortable start configuration inside the limits

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    @property
    def command_topic(self) -> str:
        return f"{self.topic_prefix}/arm_controller/command"

    @property
    def joint_states_topic(self) -> str:
        return f"{self.topic_prefix}/joint_states"

    @property
    def pose_topic(self) -> str:
        return f"{self.topic_prefix}/pose"

    def clip(self, q: np.ndarray) -> np.ndarray:
        return np.clip(q, self.lower, self.upper)

    def within_limits(self, q: np.ndarray, tol: float = 1e-9) -> bool:
        q = np.asarray(q, dtype=float)
        return bool(np.all(q >= self.lower - tol) and np.all(q <= self.upper + tol))


def _pybullet_data_dir() -> Path:
    import pybullet_data  # imported lazily: only the Panda needs it

    return Path(pybullet_data.getDataPath())


def _panda() -> RobotSpec:
    # pybullet_data's panda.urdf has wider <limit>s than the real robot; these are Franka's datasheet limits.
    return RobotSpec(
        name="panda",
        urdf_path=_pybullet_data_dir() / "franka_panda" / "panda.urdf",
        joint_names=tuple(f"panda_joint{i}" for i in range(1, 8)),
        joint_types=("revolute",) * 7,
        lower=np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]),
        upper=np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]),
        max_velocity=np.array([2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100]),
        max_effort=np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]),
        base_link="panda_link0",
        ee_link="panda_link8",  # the flange, as in Franka's DH table
        topic_prefix="/panda",
        home=np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]),
    )


def _igt() -> RobotSpec:
    # Stand-in for a confidential 3-joint medical robot: prismatic rail along x, two revolute joints about z,
    # so exactly the end effector's x, y and yaw are controllable. See urdf/igt.urdf.
    return RobotSpec(
        name="igt",
        urdf_path=URDF_DIR / "igt.urdf",
        joint_names=("igt_rail", "igt_shoulder", "igt_wrist"),
        joint_types=("prismatic", "revolute", "revolute"),
        lower=np.array([-0.25, -2.6, -2.6]),
        upper=np.array([0.25, 2.6, 2.6]),
        max_velocity=np.array([0.25, 1.5, 2.0]),
        max_effort=np.array([400.0, 60.0, 20.0]),
        base_link="igt_base",
        ee_link="igt_tool_tip",
        topic_prefix="/igt",
        home=np.array([0.0, 0.5, -1.0]),
    )


_REGISTRY = {"panda": _panda, "igt": _igt}
ROBOT_NAMES: tuple[str, ...] = tuple(_REGISTRY)


def get_robot(name: str) -> RobotSpec:
    """The registered robot `name` (e.g. "panda", "igt")."""
    try:
        factory = _REGISTRY[name]
    except KeyError:
        raise RobotError(f"unknown robot {name!r}; known robots: {', '.join(ROBOT_NAMES)}") from None
    spec = factory()
    if not os.path.exists(spec.urdf_path):
        raise RobotError(f"URDF of robot {name!r} not found at {spec.urdf_path}")
    return spec
