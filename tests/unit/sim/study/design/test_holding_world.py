"""The drives against gravity in the scene's world (SceneWorld.gravity_loads, sim.study.design.holding): the loads
are the URDF's masses' own, as the base is mounted; an approach on which a joint cannot hold the arm says which
joint, when, what it takes and the limit; an arm that cannot hold itself at home is refused before any planning.
And the robot's distance to the hand is a distance however far away the robot is, never inf."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sim.robots import RobotSpec, load_robot
from sim.robots.examples import SCARA_LIKE, write_lab_arm
from sim.study.design.errors import DesignError
from sim.study.design.feasibility import Approaches, plan_combination
from sim.study.design.scene import Box, load_scene, scene_robot
from sim.study.design.world import FAR, SceneWorld
from sim.wire.contract import STEP_S

SCENE = load_scene()
PANDA = scene_robot(SCENE)
G = 9.81
# what hangs on the SCARA's lift: its carriage, both arm links, the quill and pybullet's 1 kg for tool0 (no <inertial>)
SCARA_CARRIED = sum(part.mass for part in SCARA_LIKE[1:] if part.box is not None) + 1.0


def scara(folder: Path, lift_effort: float | None = None) -> RobotSpec:
    robot = load_robot(str(write_lab_arm(folder, "scara_like")))
    if lift_effort is None:
        return robot
    effort = robot.max_effort.copy()
    effort[list(robot.joint_names).index("lift")] = lift_effort
    return dataclasses.replace(robot, max_effort=effort)


def on_base(robot: RobotSpec, rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)):
    return dataclasses.replace(SCENE, robot=str(robot.urdf_path), ee_link=robot.ee_link, base_rpy=np.array(rpy))


def test_the_lift_carries_what_hangs_on_it_and_the_turning_joints_nothing_unless_the_base_is_tilted(tmp_path):
    robot = scara(tmp_path)
    lift = list(robot.joint_names).index("lift")
    with SceneWorld(robot, on_base(robot)) as world:
        upright = world.gravity_loads(robot.home)
    assert upright[lift] == pytest.approx(SCARA_CARRIED * G, rel=1e-6)
    assert np.abs(np.delete(upright, lift)).max() < 1e-9  # their axes are vertical: gravity does not turn them
    with SceneWorld(robot, on_base(robot, (np.pi / 2, 0.0, 0.0))) as world:  # the column lies level, across the arm
        tilted = world.gravity_loads(robot.home)
    assert abs(tilted[lift]) < 1e-6 and np.abs(np.delete(tilted, lift)).max() > 1.0


def test_an_arm_whose_lift_cannot_carry_it_is_refused_at_home_in_one_line(tmp_path):
    robot = scara(tmp_path, lift_effort=100.0)
    with pytest.raises(DesignError) as refused:
        Approaches(robot, on_base(robot), STEP_S)
    message = str(refused.value)
    assert message.startswith(
        f"scara_like: lift cannot hold the arm at home: it needs {SCARA_CARRIED * G:.1f} N, its effort limit is 100 N;"
    )
    assert "\n" not in message and "effort limits and masses" in message
    Approaches(scara(tmp_path, lift_effort=400.0), on_base(robot), STEP_S).close()  # the test arm's own holds


def test_an_approach_on_which_a_joint_cannot_hold_the_arm_names_it_at_its_worst_time():
    shoulder = 1  # panda_joint2, which carries the arm out over the table
    with SceneWorld(PANDA, SCENE) as world:
        strong = plan_combination(PANDA, SCENE, ("straight", 0.15, 0.3), STEP_S, world)
        loads = np.abs([world.gravity_loads(q)[shoulder] for q in strong.positions])
        limit = float(np.round((loads.min() + loads.max()) / 2, 1))  # it holds the arm at some samples, not at others
        effort = PANDA.max_effort.copy()
        effort[shoulder] = limit
        weak = plan_combination(
            dataclasses.replace(PANDA, max_effort=effort), SCENE, ("straight", 0.15, 0.3), STEP_S, world
        )
    assert strong.feasible and not weak.feasible
    worst = int(np.argmax(loads))
    assert weak.problems == [
        f"panda_joint2 cannot hold the arm at t = {strong.path.times[worst]:.2f} s: it needs {loads[worst]:.1f} N·m, "
        f"its effort limit is {limit:g} N·m"
    ]
    assert any("a joint that holds the arm" in remedy for remedy in weak.remedies)


def test_the_distance_to_a_hand_beyond_the_search_radius_is_a_distance_not_inf():
    def hand_at(x: float):
        hand = Box(SCENE.hand.size, np.array([x, 0.0, SCENE.hand.position[2]]), 0.0)
        return dataclasses.replace(SCENE, hand=hand)

    with SceneWorld(PANDA, hand_at(5.0)) as far, SceneWorld(PANDA, hand_at(6.0)) as farther:
        distance = far.hand_distance(PANDA.home)
        robot_point, hand_point = far.nearest_points(PANDA.home)
        assert FAR < distance < 5.0 and distance == pytest.approx(float(np.linalg.norm(robot_point - hand_point)))
        assert farther.hand_distance(PANDA.home) > distance + 0.9
