"""`python -m sim.robots --robot ROBOT`: what the toolkit derives from a robot (links, joints, limits, home,
topics, the notes on what it assumed), or with --urdf the robot's URDF text (for roslaunch's
`<param name="robot_description" command="...">`). A robot that cannot be loaded: one line, exit 2."""

from __future__ import annotations

import argparse
import sys

from sim.entry import EXIT_BAD_INPUT, EXIT_OK, fail
from sim.robots import RobotError, RobotSpec, add_robot_arguments, robot_from_args

__all__ = ["summary", "main"]


def summary(robot: RobotSpec) -> str:
    lines = [
        f"robot {robot.name}: {robot.urdf_path}",
        f"  base link {robot.base_link}, end effector {robot.ee_link}",
        f"  topics {robot.command_topic}, {robot.joint_states_topic}, {robot.pose_topic}",
        "  joint                       type         lower      upper   velocity     effort       home",
    ]
    for j, name in enumerate(robot.joint_names):
        lines.append(
            f"  {name:<27} {robot.joint_types[j]:<10} {robot.lower[j]:>8.4f} {robot.upper[j]:>10.4f} "
            f"{robot.max_velocity[j]:>10.4f} {robot.max_effort[j]:>10.4g} {robot.home[j]:>10.4f}"
        )
    lines += [f"  note: {note}" for note in robot.notes]
    if robot.default_inertia_links:
        lines.append(f"  note: no <inertial> (pybullet gives 1 kg): {', '.join(robot.default_inertia_links)}")
    if robot.zeroed_inertia_links:
        lines.append(f"  note: inertia not physical (pybullet zeroes it): {', '.join(robot.zeroed_inertia_links)}")
    lines.append(f"  load it again with: {' '.join(robot.cli_args)}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sim.robots", description=__doc__.splitlines()[0])
    add_robot_arguments(parser)
    parser.add_argument("--urdf", action="store_true", help="print the robot's URDF text instead of the summary")
    args = parser.parse_args(argv)
    try:
        robot = robot_from_args(args)
    except RobotError as error:
        return fail("sim.robots", error, EXIT_BAD_INPUT)
    if args.urdf:  # exactly the file: robot_description is then the same text as the URDF
        sys.stdout.write(robot.urdf_path.read_text(encoding="utf-8"))
    else:
        print(summary(robot))
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
