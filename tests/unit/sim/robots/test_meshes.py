"""sim.robots.meshes: the files a URDF's shapes name are found as ROS finds them, and a robot whose meshes are
nowhere still loads into the physics (which needs only <inertial>)."""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from sim.engine.physics import PhysicsWorld
from sim.robots import load_robot
from sim.robots.meshes import resolve_shapes
from tests.robot_files import THIRD_PARTY_URDFS

URDF = """<robot name="r">
  <link name="base">
    <visual><geometry><mesh filename="package://my_description/meshes/base.stl"/></geometry>
      <material name="m"><texture filename="package://my_description/textures/skin.png"/></material></visual>
    <collision><geometry><mesh filename="meshes/base_collision.stl"/></geometry></collision>
    <collision><geometry><box size="1 1 1"/></geometry></collision>
  </link>
  <link name="tip">
    <visual><geometry><mesh filename="package://gone/meshes/tip.stl"/></geometry></visual>
  </link>
</robot>"""


def touch(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("solid x\nendsolid x\n")
    return path


def test_package_uris_resolve_through_ros_and_beside_the_urdf_and_missing_shapes_are_dropped(tmp_path):
    package = tmp_path / "share" / "my_description"
    base_mesh, skin = touch(package / "meshes" / "base.stl"), touch(package / "textures" / "skin.png")
    collision = touch(tmp_path / "robot" / "meshes" / "base_collision.stl")
    found = {"my_description": package}
    text, missing = resolve_shapes(URDF, tmp_path / "robot", found.get)
    root = ET.fromstring(text)
    filenames = [element.get("filename") for element in root.iter() if element.get("filename")]
    assert filenames == [str(base_mesh), str(skin), str(collision)]
    assert missing == ["package://gone/meshes/tip.stl"]
    assert root.find("link[@name='tip']/visual") is None  # the shape is gone, the link stays
    assert len(root.findall("link[@name='base']/collision")) == 2


def test_without_ros_a_description_package_beside_or_above_the_urdf_is_found(tmp_path):
    mesh = touch(tmp_path / "my_description" / "meshes" / "base.stl")
    text, missing = resolve_shapes(URDF, tmp_path / "my_description" / "urdf", lambda name: None)
    assert str(mesh) in text and "package://gone/meshes/tip.stl" in missing


def test_a_robot_whose_meshes_are_nowhere_still_loads_moves_and_is_pictured(tmp_path, caplog):
    alone = Path(shutil.copy(THIRD_PARTY_URDFS["xarm6"], tmp_path / "xarm6.urdf"))  # its meshes stay behind
    robot = load_robot(str(alone))
    with PhysicsWorld(robot, shapes=True) as pictured:
        assert pictured.capture(32, 24).shape == (24, 32, 3)
    assert "14 mesh or texture file(s) named in" in caplog.text
    with PhysicsWorld(robot) as world, PhysicsWorld(load_robot(str(THIRD_PARTY_URDFS["xarm6"]))) as original:
        for world_ in (world, original):
            world_.set_targets(robot.home + 0.1)
        for _ in range(50):
            moved, reference = world.step(), original.step()
    np.testing.assert_allclose(moved.positions, reference.positions, atol=1e-12)  # meshes never touch the dynamics
    assert np.abs(moved.positions - robot.home).max() > 0.05
