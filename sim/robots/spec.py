"""What the toolkit knows of a robot once it is loaded: `RobotSpec`, plus the scenario defaults a robot's YAML may
fix. Pure data."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["ScenarioDefaults", "RobotSpec"]


@dataclass(frozen=True)
class ScenarioDefaults:
    """The scenario defaults a robot's YAML fixes (`scenario_defaults:`); None = computed from the robot
    (sim.control.scenarios.defaults). The Panda and the igt keep the motions the README documents this way."""

    one_joint: str | None = None  # a joint name
    one_joint_waypoints: tuple[float, ...] | None = None
    ik_goal_position: tuple[float, ...] | None = None  # ik_joints, ik_cartesian, fk_confirm
    ik_goal_rpy: tuple[float, ...] | None = None  # None: position only
    orientation_goal_position: tuple[float, ...] | None = None  # ik_orientation
    orientation_goal_rpy: tuple[float, ...] | None = None
    sweep_centres: tuple[float, ...] | None = None
    sweep_amplitudes: tuple[float, ...] | None = None


@dataclass(frozen=True, eq=False)
class RobotSpec:
    name: str
    urdf_path: Path
    joint_names: tuple[str, ...]  # the controlled joints, in command order
    joint_types: tuple[str, ...]  # "revolute" | "continuous" | "prismatic"
    lower: np.ndarray  # position limits [rad or m]
    upper: np.ndarray
    max_velocity: np.ndarray  # [rad/s or m/s]
    max_effort: np.ndarray  # [N·m or N]; inf where the URDF states none
    base_link: str
    ee_link: str
    topic_prefix: str  # e.g. "/panda"; topics are <prefix>/joint_states etc.
    home: np.ndarray  # a comfortable start configuration inside the limits
    scenario_defaults: ScenarioDefaults = field(default_factory=ScenarioDefaults)
    default_inertia_links: tuple[str, ...] = ()  # moving links without <inertial>: pybullet gives them 1 kg
    zeroed_inertia_links: tuple[str, ...] = ()  # moving links whose inertia is not physical: pybullet zeroes it
    notes: tuple[str, ...] = ()  # what was assumed while loading (missing limits, ...), for the user to read
    cli_args: tuple[str, ...] = ()  # the command-line arguments that load this robot again (for child processes)

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
