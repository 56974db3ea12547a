"""sim.robots.identity: a robot's cache key is its content (URDF, the bytes of its meshes, what its overrides make of
it), not where its files lie."""

from __future__ import annotations

import shutil
from pathlib import Path

from sim.robots import load_robot
from sim.robots.examples import STUDY_ARMS, write_arm, write_lab_arm
from sim.robots.identity import derived_fields, robot_identity, shape_filenames

MESHED = next(design for design in STUDY_ARMS if design.overlapping_meshes)  # relative meshes/... paths


def no_ros(_name: str) -> Path | None:
    return None  # package:// found beside the URDF (in its description package), as without ROS


def test_the_shape_files_named_are_every_mesh_and_texture_once_in_order() -> None:
    urdf = """<robot name="r">
      <link name="a"><visual><geometry><mesh filename="package://p/a.dae"/></geometry>
        <material name="m"><texture filename="skin.png"/></material></visual>
        <collision><geometry><mesh filename="meshes/a.stl"/></geometry></collision>
        <collision><geometry><box size="1 1 1"/></geometry></collision></link>
      <link name="b"><collision><geometry><mesh filename="meshes/a.stl"/></geometry></collision></link>
    </robot>"""
    assert shape_filenames(urdf) == ["package://p/a.dae", "skin.png", "meshes/a.stl"]


def test_the_same_arm_in_two_folders_is_one_identity_and_an_edited_mesh_another(tmp_path: Path) -> None:
    first = load_robot(str(write_arm(tmp_path / "one", MESHED)))
    second = load_robot(str(write_arm(tmp_path / "two", MESHED)))
    assert first.urdf_path != second.urdf_path and first.cli_args != second.cli_args
    assert robot_identity(first, no_ros) == robot_identity(second, no_ros)
    mesh = second.urdf_path.parent / "meshes" / "link3.stl"
    mesh.write_bytes(mesh.read_bytes() + b"\0")  # same name, same URDF: other bytes
    assert robot_identity(first, no_ros) != robot_identity(second, no_ros)
    mesh.unlink()  # a mesh found nowhere is another arm again
    assert robot_identity(second, no_ros) not in (robot_identity(first, no_ros), "")


def test_package_uris_count_by_the_files_they_resolve_to(tmp_path: Path) -> None:
    first = load_robot(str(write_lab_arm(tmp_path / "one", "scara_like")))
    copy = tmp_path / "two" / "scara_like_description"
    shutil.copytree(first.urdf_path.parents[1], copy)
    second = load_robot(str(copy / "urdf" / "scara_like.urdf"))
    assert robot_identity(first, no_ros) == robot_identity(second, no_ros)
    collision = sorted((copy / "meshes" / "collision").glob("*.stl"))[0]
    collision.write_bytes(collision.read_bytes()[:-1] + b"\1")
    assert robot_identity(first, no_ros) != robot_identity(second, no_ros)


def test_an_override_is_part_of_the_identity_and_the_command_line_path_is_not(tmp_path: Path) -> None:
    urdf = write_arm(tmp_path, MESHED)
    plain, named = load_robot(str(urdf)), load_robot(str(urdf), ee_link="link6")
    assert named.ee_link != plain.ee_link and "--ee-link" in named.cli_args
    assert robot_identity(plain, no_ros) != robot_identity(named, no_ros)
    homed = load_robot(str(urdf), home=tuple(0.1 for _ in plain.joint_names))
    assert derived_fields(homed)["home"] != derived_fields(plain)["home"]
    assert not {"urdf_path", "cli_args"} & set(derived_fields(plain))
