"""The robots that are not ours, which the tests run everything on: two third-party arms from pybullet_data and
one URDF written for the tests (a prismatic lift, fixed joints, a two-finger gripper and an inertia-less link); and
the arms with a gripper, named by their URDF alone: the Panda with its hand (pybullet_data's) and a six-joint arm
the tests write themselves (prismatic fingers under a flange with a fixed tool frame)."""

from __future__ import annotations

from pathlib import Path

import pybullet_data

__all__ = [
    "FIXTURE_ROBOTS",
    "THIRD_PARTY_URDFS",
    "LIFT_ARM",
    "PANDA_WITH_HAND",
    "gripper_arm_urdf",
    "write_gripper_arm",
]

FIXTURE_ROBOTS = Path(__file__).resolve().parent / "fixtures" / "robots"
LIFT_ARM = FIXTURE_ROBOTS / "lift_arm.urdf"  # with lift_arm.yaml beside it (ee_link: tool_tip)
_DATA = Path(pybullet_data.getDataPath())
THIRD_PARTY_URDFS: dict[str, Path] = {
    "lbr_iiwa": _DATA / "kuka_iiwa" / "model.urdf",  # KUKA LBR iiwa 14, 7 revolute joints
    "xarm6": _DATA / "xarm" / "xarm6_robot.urdf",  # UFactory xArm 6: a world link, meshes, transmissions
    "lift_arm": LIFT_ARM,
}
PANDA_WITH_HAND = _DATA / "franka_panda" / "panda.urdf"  # fingers under panda_hand, its tool frame panda_grasptarget

_INERTIAL = (
    '<inertial><origin xyz="0 0 {half}"/><mass value="{mass}"/>'
    '<inertia ixx="{i}" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{i}"/></inertial>'
)


def _link(name: str, mass: float, length: float = 0.1) -> str:
    return f'<link name="{name}">{_INERTIAL.format(half=length / 2, mass=mass, i=mass * length**2 / 12 + 1e-4)}</link>'


def _joint(name: str, kind: str, parent: str, child: str, xyz: str, axis: str = "0 0 1", limit: str = "") -> str:
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>{limit}</joint>'
    )


def gripper_arm_urdf(tool_frame: bool = True) -> str:
    """A six-joint arm ending in a flange that carries two prismatic fingers and (`tool_frame`) a fixed tool0."""
    revolute = '<limit lower="-2.5" upper="2.5" velocity="2.0" effort="150"/>'
    finger = '<limit lower="0.0" upper="0.04" velocity="0.2" effort="20"/>'
    links = [_link("base_link", 4.0)]
    joints = []
    parent = "base_link"
    for k, axis in enumerate(("0 0 1", "0 1 0", "0 1 0", "0 0 1", "0 1 0", "0 0 1"), start=1):
        child = f"link{k}" if k < 6 else "flange"
        links.append(_link(child, 2.0 if k < 4 else 1.0, 0.3 if k in (2, 3) else 0.1))
        joints.append(
            _joint(f"joint{k}", "revolute", parent, child, "0 0 0.3" if k in (3, 4) else "0 0 0.1", axis, revolute)
        )
        parent = child
    for side, y in (("left", "0.02"), ("right", "-0.02")):
        links.append(_link(f"{side}_finger", 0.05, 0.05))
        direction = "0 1 0" if side == "left" else "0 -1 0"
        joints.append(
            _joint(f"{side}_finger_joint", "prismatic", "flange", f"{side}_finger", f"0 {y} 0.1", direction, finger)
        )
    if tool_frame:
        links.append('<link name="tool0"/>')
        joints.append(_joint("flange_to_tool0", "fixed", "flange", "tool0", "0 0 0.15"))
    body = "\n".join(links + joints)
    return f'<?xml version="1.0"?>\n<robot name="gripper_arm">\n{body}\n</robot>\n'


def write_gripper_arm(directory: Path) -> Path:
    """The gripper arm as `directory`/gripper_arm.urdf, with nothing beside it."""
    path = directory / "gripper_arm.urdf"
    path.write_text(gripper_arm_urdf())
    return path
