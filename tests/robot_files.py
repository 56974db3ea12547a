"""The robots that are not ours, which the tests run everything on: two third-party arms from pybullet_data and
one URDF written for the tests (a prismatic lift, fixed joints, a two-finger gripper and an inertia-less link)."""

from __future__ import annotations

from pathlib import Path

import pybullet_data

__all__ = ["FIXTURE_ROBOTS", "THIRD_PARTY_URDFS", "LIFT_ARM"]

FIXTURE_ROBOTS = Path(__file__).resolve().parent / "fixtures" / "robots"
LIFT_ARM = FIXTURE_ROBOTS / "lift_arm.urdf"  # with lift_arm.yaml beside it (ee_link: tool_tip)
_DATA = Path(pybullet_data.getDataPath())
THIRD_PARTY_URDFS: dict[str, Path] = {
    "lbr_iiwa": _DATA / "kuka_iiwa" / "model.urdf",  # KUKA LBR iiwa 14, 7 revolute joints
    "xarm6": _DATA / "xarm" / "xarm6_robot.urdf",  # UFactory xArm 6: a world link, meshes, transmissions
    "lift_arm": LIFT_ARM,
}
