"""sim.robots.derive: the end effector a URDF alone gives. A gripper's fingers make it the hand (its tool frame when
it has one), said in one note; any other tie stays an error that lists the candidates."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from sim.robots import RobotError, load_robot
from sim.robots.derive import end_effector
from sim.robots.urdf_model import parse_urdf
from tests.robot_files import LIFT_ARM, PANDA_WITH_HAND, gripper_arm_urdf


def test_an_arm_with_a_gripper_ends_at_the_tool_frame_of_the_flange_its_fingers_hang_from() -> None:
    notes: list[str] = []
    assert end_effector(parse_urdf(gripper_arm_urdf()), "base_link", notes=notes) == "tool0"
    assert notes == [
        "end effector 'tool0': the tool frame of 'flange', from which the gripper's fingers hang "
        "(left_finger_joint, right_finger_joint, held where they start); choose another with --ee-link"
    ]


def test_without_a_tool_frame_it_ends_at_the_hand_itself() -> None:
    notes: list[str] = []
    assert end_effector(parse_urdf(gripper_arm_urdf(tool_frame=False)), "base_link", notes=notes) == "flange"
    assert len(notes) == 1 and notes[0].startswith("end effector 'flange': the hand, from which")


def test_the_panda_with_its_hand_from_its_urdf_alone() -> None:
    panda = load_robot(str(PANDA_WITH_HAND))
    assert panda.ee_link == "panda_grasptarget"
    assert panda.joint_names == tuple(f"panda_joint{k}" for k in range(1, 8))
    assert "the tool frame of 'panda_hand'" in " ".join(panda.notes)


def test_the_lift_arm_alone_ends_at_its_tool_tip_as_its_yaml_says(tmp_path: Path) -> None:
    alone = load_robot(str(shutil.copy(LIFT_ARM, tmp_path / "lift_arm.urdf")))
    assert alone.ee_link == load_robot(str(LIFT_ARM)).ee_link == "tool_tip"
    assert alone.joint_names == ("lift", "shoulder", "elbow", "wrist")


def _two_arms() -> str:
    """Two equal arms on one torso: no hand in common, so no end effector can be derived."""
    limit = '<limit lower="-1" upper="1" velocity="1" effort="10"/>'
    parts = ['<link name="torso"/>']
    for side in ("left", "right"):
        parent = "torso"
        for k in (1, 2):
            child = f"{side}_link{k}"
            parts.append(f'<link name="{child}"/>')
            parts.append(
                f'<joint name="{side}_joint{k}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
                f'<axis xyz="0 0 1"/>{limit}</joint>'
            )
            parent = child
    return '<robot name="twins">' + "".join(parts) + "</robot>"


def test_two_arms_stay_ambiguous_and_the_error_lists_them() -> None:
    with pytest.raises(RobotError, match="ambiguous, 2 leaves end a chain of 2 moving joints: left_link2, right_link2"):
        end_effector(parse_urdf(_two_arms()), "torso")


def test_arms_straight_on_the_base_are_no_gripper() -> None:
    # One joint each: both hang from the torso, but no arm carries them, so they are two arms, not two fingers.
    text = _two_arms().replace('<parent link="left_link1"/>', '<parent link="torso"/>')
    text = text.replace('<parent link="right_link1"/>', '<parent link="torso"/>')
    with pytest.raises(RobotError, match="ambiguous, 4 leaves end a chain of 1 moving joints"):
        end_effector(parse_urdf(text), "torso")


def test_a_finger_with_two_leaves_is_still_one_finger() -> None:
    text = gripper_arm_urdf().replace(
        "</robot>",
        '<link name="left_pad"/><joint name="left_pad_fixed" type="fixed"><parent link="left_finger"/>'
        '<child link="left_pad"/></joint></robot>',
    )
    notes: list[str] = []
    assert end_effector(parse_urdf(text), "base_link", notes=notes) == "tool0"
    assert "(left_finger_joint, right_finger_joint, held" in notes[0]
