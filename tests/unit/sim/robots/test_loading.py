"""sim.robots: a robot is its URDF plus optional overrides; everything else is derived, and bad robots are one
clear RobotError naming the file and the value."""

from __future__ import annotations

import argparse
import logging
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from sim.robots import ROBOT_NAMES, RobotError, add_robot_arguments, load_robot, robot_from_args
from sim.robots.derive import ros_name
from sim.robots.urdf_model import parse_urdf
from tests.robot_files import LIFT_ARM, THIRD_PARTY_URDFS


def urdf(body: str, name: str = "probe") -> str:
    return f'<?xml version="1.0"?>\n<robot name="{name}">\n{body}\n</robot>\n'


def link(name: str, mass: float | None = 1.0) -> str:
    inertial = (
        ""
        if mass is None
        else (
            f'<inertial><mass value="{mass}"/><inertia ixx="0.01" ixy="0" ixz="0" '
            f'iyy="0.01" iyz="0" izz="0.01"/></inertial>'
        )
    )
    return f'<link name="{name}">{inertial}</link>'


def joint(
    name: str,
    kind: str,
    parent: str,
    child: str,
    limit: str = 'lower="-1" upper="1" velocity="1" effort="10"',
    axis: str = "0 0 1",
) -> str:
    limit_tag = f"<limit {limit}/>" if limit else ""
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="{axis}"/>{limit_tag}</joint>'
    )


def write(tmp_path: Path, text: str, name: str = "arm.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def two_link(tmp_path: Path, **joint_options: str) -> Path:
    return write(
        tmp_path,
        urdf(
            link("base")
            + link("a")
            + link("b")
            + joint("j1", "revolute", "base", "a")
            + joint("j2", "revolute", "a", "b", **joint_options)
        ),
    )


# ------------------------------------------------------------------------------------------- named robots
def test_the_panda_is_its_urdf_with_frankas_datasheet_limits():
    panda = load_robot("panda")
    assert panda.urdf_path.name == "panda.urdf" and panda.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    np.testing.assert_allclose(panda.lower, [-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
    np.testing.assert_allclose(panda.upper, [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
    np.testing.assert_allclose(panda.max_velocity, [2.175] * 4 + [2.61] * 3)
    np.testing.assert_allclose(panda.max_effort, [87.0] * 4 + [12.0] * 3)
    assert (panda.base_link, panda.ee_link, panda.topic_prefix) == ("panda_link0", "panda_link8", "/panda")
    np.testing.assert_allclose(panda.home, [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


def test_the_igt_takes_everything_but_home_from_its_urdf():
    igt = load_robot("igt")
    assert igt.joint_names == ("igt_rail", "igt_shoulder", "igt_wrist")
    assert igt.joint_types == ("prismatic", "revolute", "revolute")
    np.testing.assert_allclose(igt.lower, [-0.25, -2.6, -2.6])
    np.testing.assert_allclose(igt.max_velocity, [0.25, 1.5, 2.0])
    np.testing.assert_allclose(igt.max_effort, [400.0, 60.0, 20.0])
    assert (igt.base_link, igt.ee_link, igt.topic_prefix) == ("igt_base", "igt_tool_tip", "/igt")
    assert not igt.notes and not igt.default_inertia_links


# ------------------------------------------------------------------------------------------- derivation
def test_a_third_party_arm_is_derived_from_its_urdf_alone():
    iiwa = load_robot(str(THIRD_PARTY_URDFS["lbr_iiwa"]))
    assert iiwa.name == "lbr_iiwa" and iiwa.topic_prefix == "/lbr_iiwa"
    assert iiwa.joint_names == tuple(f"lbr_iiwa_joint_{i}" for i in range(1, 8))
    assert (iiwa.base_link, iiwa.ee_link) == ("lbr_iiwa_link_0", "lbr_iiwa_link_7")
    np.testing.assert_allclose(iiwa.home, (iiwa.lower + iiwa.upper) / 2)
    assert iiwa.within_limits(iiwa.home)


def test_transmission_joints_are_not_joints_of_the_tree():
    xarm = load_robot(str(THIRD_PARTY_URDFS["xarm6"]))  # its <transmission>s hold <joint name=...> without a type
    assert xarm.joint_names == tuple(f"joint{i}" for i in range(1, 7))
    assert (xarm.base_link, xarm.ee_link) == ("world", "link6")


def test_the_yaml_beside_the_urdf_and_the_command_line_choose_the_end_effector(tmp_path):
    arm = load_robot(str(LIFT_ARM))  # lift_arm.yaml beside it: ee_link: tool_tip
    assert arm.ee_link == "tool_tip" and arm.joint_names == ("lift", "shoulder", "elbow", "wrist")
    assert arm.joint_types == ("prismatic", "revolute", "revolute", "continuous")
    alone = shutil.copy(LIFT_ARM, tmp_path / "lift_arm.urdf")
    assert load_robot(str(alone), ee_link="left_finger").joint_names[-1] == "left_finger_joint"


def test_continuous_joints_get_a_full_turn_each_way_and_missing_limits_are_stated():
    arm = load_robot(str(LIFT_ARM))
    assert arm.lower[3] == pytest.approx(-2 * math.pi) and arm.upper[3] == pytest.approx(2 * math.pi)
    assert arm.home[3] == 0.0
    partial = parse_urdf(urdf(link("base") + link("a") + joint("j", "revolute", "base", "a", limit='effort="5"')))
    assert partial.joints[0].limit is not None and partial.joints[0].limit.velocity is None


def test_missing_limits_get_stated_defaults_with_a_note(tmp_path):
    robot = load_robot(str(two_link(tmp_path, limit="")))
    assert robot.lower[1] == pytest.approx(-math.pi) and robot.upper[1] == pytest.approx(math.pi)
    assert robot.max_velocity[1] == 1.0 and math.isinf(robot.max_effort[1])
    assert any("'j2' has no position range" in note for note in robot.notes)
    assert any("'j2' has no effort limit; its drive force is unlimited" in note for note in robot.notes)


def test_links_pybullet_would_give_a_default_inertia_are_listed():
    assert load_robot(str(LIFT_ARM)).default_inertia_links == ("camera",)
    assert load_robot("panda").default_inertia_links == ()  # its massless links do state <inertial>


def test_command_line_overrides_win_over_the_yaml_and_round_trip_through_cli_args(tmp_path):
    parser = argparse.ArgumentParser()
    add_robot_arguments(parser)
    args = parser.parse_args(["--robot", str(LIFT_ARM), "--name", "my-arm", "--home", "0.2", "0", "0", "pi/4"])
    robot = robot_from_args(args)
    assert robot.name == "my_arm" and robot.topic_prefix == "/my_arm" and robot.home[3] == pytest.approx(math.pi / 4)
    again = robot_from_args(parser.parse_args(list(robot.cli_args)))
    assert again.name == robot.name and np.array_equal(again.home, robot.home) and again.ee_link == "tool_tip"
    assert load_robot("igt").cli_args == ("--robot", "igt")


def test_empty_overrides_are_not_given_as_a_launch_file_passes_its_empty_defaults():
    parser = argparse.ArgumentParser()
    add_robot_arguments(parser)
    args = parser.parse_args(["--robot", str(LIFT_ARM), "--name", "", "--ee-link", "", "--base-link", "", "--home", ""])
    robot = robot_from_args(args)
    derived = load_robot(str(LIFT_ARM))
    assert (robot.name, robot.ee_link, robot.base_link) == (derived.name, derived.ee_link, derived.base_link)
    assert np.array_equal(robot.home, derived.home)
    # A launch argument holds the home as one string.
    home = robot_from_args(parser.parse_args(["--robot", str(LIFT_ARM), "--home", "0.1 0 0 pi/2"])).home
    assert home[3] == pytest.approx(math.pi / 2)
    with pytest.raises(RobotError, match="not a number: 'x'"):
        robot_from_args(parser.parse_args(["--robot", str(LIFT_ARM), "--home", "0 x"]))


def test_a_robot_yaml_can_name_its_urdf(tmp_path):
    shutil.copy(LIFT_ARM, tmp_path / "arm_model.urdf")
    yaml_path = write(
        tmp_path,
        "urdf: arm_model.urdf\nname: lifter\nee_link: hand\nlimits:\n  lift: {upper: 0.4, velocity: 0.2}\n",
        "lifter.yaml",
    )
    robot = load_robot(str(yaml_path))
    assert (robot.name, robot.ee_link, robot.upper[0], robot.max_velocity[0]) == ("lifter", "hand", 0.4, 0.2)
    assert robot.cli_args == ("--robot", str(yaml_path.resolve()))


@pytest.mark.parametrize("text, expected", [("lbr_iiwa", "lbr_iiwa"), ("my arm-2", "my_arm_2"), ("6dof", "robot_6dof")])
def test_names_become_ros_names(text, expected):
    assert ros_name(text) == expected


# ----------------------------------------------------------------------------------------------- bad robots
BAD_URDFS = [
    ("not xml <", "is not XML"),
    ('<?xml version="1.0"?><sdf/>', "root element is <sdf>, not <robot>"),
    (urdf(link("base")), "has no moving joint"),
    (urdf(link("base") + link("a") + joint("j", "fixed", "base", "a")), "has no moving joint"),
    (
        urdf(
            link("world")
            + link("body")
            + joint("free", "floating", "world", "body")
            + link("a")
            + joint("j", "revolute", "body", "a")
        ),
        "joint 'free' is floating, which a position drive cannot",
    ),
    (urdf(link("base") + link("a") + joint("j", "screw", "base", "a")), "type 'screw'"),
    (urdf(link("base") + link("a") + joint("j", "revolute", "base", "nowhere")), "names link 'nowhere'"),
    (urdf(link("base") + link("a") + joint("j", "revolute", "base", "a", axis="0 0 0")), "zero axis"),
    (
        urdf(link("base") + link("a") + joint("j", "revolute", "base", "a", limit='lower="x"')),
        "lower='x' is not a number",
    ),
    (
        urdf(
            link("base")
            + link("a")
            + link("b")
            + joint("j1", "revolute", "base", "a")
            + joint("j2", "revolute", "a", "b")
            + joint("j3", "revolute", "b", "a")
        ),
        "child of two joints",
    ),
    (
        urdf(link("r") + link("a") + link("b") + joint("j1", "revolute", "a", "b") + joint("j2", "revolute", "b", "a")),
        "in a cycle|exactly one root",
    ),
    (
        urdf(link("base") + link("a") + joint("j", "revolute", "base", "a", limit='lower="1" upper="-1"')),
        "lower above upper",
    ),
]


def test_a_urdf_with_a_byte_order_mark_or_a_default_namespace_is_still_a_urdf(tmp_path):
    body = link("base") + link("a") + joint("j", "revolute", "base", "a")
    for text in (
        "\ufeff" + urdf(body),
        urdf(body).replace('<robot name="probe">', '<robot xmlns="http://www.ros.org" name="probe">'),
    ):
        assert load_robot(str(write(tmp_path, text))).joint_names == ("j",)


@pytest.mark.parametrize("text, message", BAD_URDFS)
def test_a_bad_urdf_is_one_clear_error_naming_the_file(tmp_path, text, message):
    path = write(tmp_path, text)
    with pytest.raises(RobotError, match=message) as error:
        load_robot(str(path))
    assert str(path) in str(error.value)


@pytest.mark.parametrize(
    "yaml_text, message",
    [
        ("ee_link: [1]\n", "ee_link must be a non-empty string"),
        ("colour: red\n", r"unknown key\(s\) \['colour'\]"),
        ("home: [0.1]\n", "home needs 2 finite numbers"),
        ("home: [0.0, 5.0]\n", "outside the limits of j2"),
        ("ee_link: nowhere\n", "no link 'nowhere' for the end effector"),
        ("limits:\n  j9: {upper: 1}\n", "joint 'j9', which is not a controlled joint"),
        ("limits:\n  j1: {top: 1}\n", "limit 'top' is not one of"),
        ("limits:\n  j1: {lower: 2}\n", "lower < upper"),
        (
            "scenario_defaults:\n  sweep: {centres: [0.1], amplitudes: [0.1, 0.1]}\n",
            "sweep.centres needs 2 numbers",
        ),
        ("scenario_defaults:\n  dance: {}\n", "unknown scenario default 'dance'"),
        ("scenario_defaults: {}\nscenarios: {}\n", "give scenario_defaults only"),
        ("urdf: other.urdf\n", "names URDF .*other.urdf, but"),
        ("{: bad\n", "is not valid YAML"),
    ],
)
def test_a_bad_robot_yaml_is_one_clear_error(tmp_path, yaml_text, message):
    path = two_link(tmp_path)
    write(tmp_path, yaml_text, "arm.yaml")
    with pytest.raises(RobotError, match=message):
        load_robot(str(path))


def test_the_old_name_of_scenario_defaults_is_read_with_a_warning(tmp_path, caplog):
    path = two_link(tmp_path)
    write(tmp_path, "scenarios:\n  trial: {centres: [0.3, 0.4], amplitudes: [0.1, 0.2]}\n", "arm.yaml")
    with caplog.at_level(logging.WARNING, logger="sim.robots.loading"):
        robot = load_robot(str(path))
    assert robot.scenario_defaults.sweep_centres == (0.3, 0.4)
    assert "'scenarios:' is deprecated; rename it 'scenario_defaults:'" in caplog.text


@pytest.mark.parametrize(
    "reference, message",
    [
        ("nobody", "unknown robot 'nobody': give a URDF path"),
        ("/no/such/arm.urdf", "URDF not found: /no/such/arm.urdf"),
        ("/no/such/arm.yaml", "robot YAML not found"),
        ("arm.urdf.xacro", "is a xacro file; expand it first"),
    ],
)
def test_a_missing_or_unknown_robot_is_named(reference, message):
    with pytest.raises(RobotError, match=message):
        load_robot(reference)


def test_every_bundled_robot_loads():
    for name in ROBOT_NAMES:
        assert load_robot(name).name == name


def test_inertias_pybullet_would_zero_are_listed():
    # xArm 6's link2 and link3 state tensors whose principal moments break the triangle inequality
    assert load_robot(str(THIRD_PARTY_URDFS["xarm6"])).zeroed_inertia_links == ("link2", "link3")
    assert load_robot("panda").zeroed_inertia_links == ()
