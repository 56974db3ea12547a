"""The commander: the stand-in for the Simulink models that drove the robot. A rospy node.

    python -m sim.commander --robot panda --scenario NAME [options]     (--help lists them all)

Streams a scenario of sim.control.scenarios as `<prefix>/arm_controller/command` (trajectory_msgs/JointTrajectory: the
registry's joint names, ONE point with positions and velocities, header.stamp = the time the target is for), drives
`/clock` (rosgraph_msgs/Clock), publishes the end-effector goal on `<prefix>/pose` (geometry_msgs/Pose, latched,
IK scenarios only; a real quaternion, or with --pose-convention euler the thesis's: XYZ Euler angles in the
quaternion's x, y, z fields and w = 0) and logs desired vs achieved (`<prefix>/joint_states`) for every step.

Timing (the contract with the engine, sim.control.stepper): fixed steps of dt; the target of step k (t_k -> t_k+1)
is for its END. Lockstep (default): the engine steps once per /clock value and answers each with its joint state, so
a 40 s motion takes seconds (--lockstep-rate caps the steps per wall second). --realtime: /clock and the commands are
paced by the wall clock (x --time-scale) and nothing is waited for.
Start-up: wait (at most --connect-timeout s) until a partner node (one that publishes joint_states and
subscribes the command topic) is connected to our command, /clock and pose publishers and our joint_states
subscriber, and so is every node named with --wait-for (e.g. a rosbag recorder); publish /clock = 0. In lockstep,
wait for the engine's answer to it: the joint state it publishes, stamped 0, when it anchors its step grid.
Approach (default, --approach MIN_S, 0 = off): the robot may not be at the scenario's first sample (the engine
starts at home, or where a previous run left it). In lockstep, step 0 -> dt is a priming step with no new command
(the engine holds its target) whose joint state tells where the robot is; in realtime the first joint state does.
A quintic approach then brings it to the scenario's start; approach rows are logged (phase "approach") but left out
of the metrics. Without the approach the scenario starts at t = 0 at once, as in the thesis's set-up.

Output: a CSV log (time, scenario_time, phase, desired_<j>, achieved_<j>, achieved_stamp and, for IK scenarios,
the reference pose ref_* at the achieved state's stamp, FK of the achieved joints ee_* and their errors
ee_pos_err, ee_rot_err), its path, and a
summary (per-joint MAPE/WAPE/NRMSE/max |error|/lag via sim.control.metrics; for IK scenarios the goal errors; for
fk_confirm
the end-effector error over time). `--export-csv PATH` writes the desired joints as the engine's CSV (`python -m
sim.engine --csv PATH`); with `--export-only` nothing touches ROS.

Through a trajectory controller (--trajectory-controller NS, a real arm's interface; sim.control.trajectory_client):
the schedule goes as NS/follow_joint_trajectory goals on wall time, no /clock and no stream. Each goal carries
--horizon s of it (positions and velocities, stamped with the wall time of the schedule's start), goes out --lead s
before it starts and every --resend s, replacing the one before without a seam (sim.control.horizon). The joint
states come from --joint-states-topic at the driver's rate; the achieved joints are read at the schedule's times
from them. The goal pose is not published in this mode.

Exit codes: 0 done, 2 bad input, 3 unreachable IK goal (the residual is printed), 4 ROS failure (no partner,
a joint state that does not come), 130 interrupted.

One concern, and a long one: the commander's command, its options (the thesis's switches) and its two ways of driving an
arm (the /clock stream, a trajectory controller's goals); the stepping, the horizon and the metrics are modules of their
own.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time
from dataclasses import dataclass, replace
from datetime import datetime
from pathlib import Path

import numpy as np

from sim.cli_values import parse_numbers
from sim.control.controller_node import ControllerError, ControllerNode
from sim.control.run_log import RunResult, write_log
from sim.control.run_summary import format_fk_confirm, format_summary
from sim.control.scenarios import (
    APPROACH_MIN_S,
    IK_HOLD_S,
    IK_MOVE_TIME_S,
    IK_RESTARTS,
    OLD_SCENARIO_NAMES,
    SCENARIOS,
    SPACES,
    Motion,
    ScenarioConfig,
    ScenarioError,
    Schedule,
    UnreachableGoalError,
    build_motion,
    build_schedule,
    write_engine_csv,
)
from sim.control.stepper import Pacing, Stepper
from sim.control.trajectory_client import ControllerLink
from sim.entry import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    EXIT_NO_CONNECTION,
    EXIT_OK,
    EXIT_UNREACHABLE_GOAL,
    fail,
    warn,
    without_ros_arguments,
)
from sim.errors import SimError
from sim.geometry.frames import matrix_to_quat
from sim.geometry.trajectory import ORDERS
from sim.robots import RobotSpec, add_robot_arguments, robot_from_args
from sim.wire.contract import STEP_S, PoseConvention, add_pose_convention_argument

__all__ = [
    "DEFAULT_LOG_DIR",
    "config_from_args",
    "CommanderOptions",
    "options_from_args",
    "Commander",
    "main",
]

# Relative to where the commander runs (roslaunch runs nodes in ROS_HOME): never into the installed package.
DEFAULT_LOG_DIR = Path("results") / "commander"
PROG = "sim.commander"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m sim.commander",
        description="The commander (Simulink stand-in): streams a scenario to a robot and logs desired vs achieved.",
        epilog="Lists: space- or comma-separated numbers; pi expressions allowed (pi/4). A list starting with a "
        "negative number: use spaces (--waypoints -2 1) or '=' (--waypoints=-2,1). Defaults of every scenario: "
        "see `python -c 'import sim.control.scenarios; help(sim.control.scenarios)'`.",
    )
    add_robot_arguments(parser)
    parser.add_argument("--scenario", required=True, help=f"one of {', '.join(SCENARIOS)}")
    group = parser.add_argument_group("scenario options")
    group.add_argument("--positions", nargs="+", metavar="Q", help="single: joint positions (default: home)")
    group.add_argument("--joint", help="one_joint: joint name or 1-based number (default: the first)")
    group.add_argument("--waypoints", nargs="+", metavar="Q", help="one_joint: waypoints of that joint (rad or m)")
    group.add_argument(
        "--times", nargs="+", metavar="T", help="one_joint: waypoint times in s (default: every 2 s from 0)"
    )
    group.add_argument("--order", default="quintic", help=f"polynomial order: {' | '.join(ORDERS)} (default quintic)")
    group.add_argument(
        "--start", nargs="+", metavar="X", help="IK: start position in m (default: the home end-effector position)"
    )
    group.add_argument(
        "--goal", nargs="+", metavar="X", help="IK: goal position in m (x y where z is not controlled, e.g. igt)"
    )
    group.add_argument(
        "--goal-rpy",
        nargs="+",
        metavar="A",
        help="IK: goal XYZ Euler angles in rad (IK on every axis the robot controls)",
    )
    group.add_argument(
        "--weights",
        nargs="+",
        metavar="W",
        help="IK: weights of x, y, z, roll, pitch, yaw (default: the axes the robot controls)",
    )
    group.add_argument(
        "--move-time", type=float, default=IK_MOVE_TIME_S, help=f"IK: motion time in s (default {IK_MOVE_TIME_S:g})"
    )
    group.add_argument(
        "--hold", type=float, default=IK_HOLD_S, help=f"IK: hold at the goal in s (default {IK_HOLD_S:g})"
    )
    group.add_argument("--space", help=f"ik_orientation / fk_confirm: {' | '.join(SPACES)}")
    group.add_argument(
        "--nearest", action="store_true", help="IK: command the nearest pose found if the goal is unreachable"
    )
    group.add_argument(
        "--ik-restarts", type=int, default=IK_RESTARTS, help=f"IK random restarts (default {IK_RESTARTS})"
    )
    group.add_argument("--duration", type=float, help="scenario length in s (cuts the motion or holds its end)")
    run = parser.add_argument_group("run options")
    run.add_argument("--dt", type=float, default=STEP_S, help=f"controller step in s (default {STEP_S})")
    run.add_argument("--realtime", action="store_true", help="pace by the wall clock instead of lockstep")
    run.add_argument(
        "--time-scale",
        type=float,
        default=1.0,
        help="realtime: sim seconds per wall second (default 1; the engine needs the same)",
    )
    run.add_argument(
        "--timeout", type=float, default=5.0, help="lockstep: max wait for each joint state in s (default 5)"
    )
    run.add_argument(
        "--lockstep-rate",
        type=float,
        help="lockstep: at most this many steps per wall second (default: each as soon as the engine answers); "
        "a rosbag recorder keeps 100 messages per topic, so at N steps a second it may fall 100 / N s behind",
    )
    run.add_argument(
        "--connect-timeout", type=float, default=30.0, help="max wait for the engine at start in s (default 30)"
    )
    run.add_argument(
        "--approach",
        type=float,
        default=APPROACH_MIN_S,
        help=f"min approach time in s from the robot's state to the scenario start; 0 = off "
        f"(default {APPROACH_MIN_S:g})",
    )
    link = parser.add_argument_group(
        "through a trajectory controller (a real arm's interface: ros_control's joint_trajectory_controller)"
    )
    link.add_argument(
        "--trajectory-controller",
        metavar="NS",
        help="send the schedule as NS/follow_joint_trajectory goals on wall time (no /clock, no stream)",
    )
    link.add_argument("--joint-states-topic", help="where the driver publishes joint states (default: the robot's)")
    link.add_argument("--horizon", type=float, default=1.0, help="s of the schedule in each goal (default 1)")
    link.add_argument("--resend", type=float, default=0.25, help="s between goals, each replacing the last (0.25)")
    link.add_argument("--lead", type=float, default=0.1, help="s a goal goes out before it starts (default 0.1)")
    add_pose_convention_argument(parser, accept_old_flag=True)
    run.add_argument("--log", type=Path, help=f"CSV log path (default {DEFAULT_LOG_DIR}/<robot>_<scenario>_<time>.csv)")
    run.add_argument("--export-csv", type=Path, help="write the desired joint trajectory as the engine's CSV")
    run.add_argument("--export-only", action="store_true", help="with --export-csv: only export, no ROS")
    run.add_argument("--node-name", help="ROS node name (default <robot>_commander)")
    run.add_argument(
        "--wait-for",
        action="append",
        default=[],
        metavar="NODE",
        help="also wait until NODE (e.g. a rosbag recorder) is connected to every topic of ours it "
        "subscribes, so it misses nothing (repeatable)",
    )
    return parser


def config_from_args(args: argparse.Namespace) -> ScenarioConfig:
    return ScenarioConfig(
        dt=args.dt,
        duration=args.duration,
        positions=parse_numbers(args.positions, "--positions"),
        joint=args.joint,
        waypoints=parse_numbers(args.waypoints, "--waypoints"),
        times=parse_numbers(args.times, "--times"),
        order=args.order,
        start=parse_numbers(args.start, "--start"),
        goal=parse_numbers(args.goal, "--goal"),
        goal_rpy=parse_numbers(args.goal_rpy, "--goal-rpy"),
        weights=parse_numbers(args.weights, "--weights"),
        move_time=args.move_time,
        hold=args.hold,
        space=args.space,
        nearest=args.nearest,
        ik_restarts=args.ik_restarts,
    )


@dataclass(frozen=True)
class CommanderOptions:
    """How the commander runs a motion (the motion itself is the scenario's: sim.control.scenarios)."""

    pacing: Pacing = Pacing()
    connect_timeout: float = 30.0  # s: the longest wait for the engine at the start
    approach: float = APPROACH_MIN_S  # s: the shortest approach to the scenario's start; 0 = off
    pose_convention: PoseConvention = PoseConvention.QUATERNION
    node_name: str | None = None  # default <robot>_commander
    log: Path | None = None  # default DEFAULT_LOG_DIR/<robot>_<scenario>_<time>.csv
    wait_for: tuple[str, ...] = ()  # further nodes (e.g. a rosbag recorder) that must be connected first
    controller: ControllerLink | None = None  # a trajectory controller instead of the stream


# ------------------------------------------------------------------------------------------------ the node
class Commander(ControllerNode):
    """The controller node (sim.control.controller_node) with the goal pose publisher; runs the motion through a
    Stepper."""

    def __init__(self, robot: RobotSpec, motion: Motion, options: CommanderOptions, stop: threading.Event) -> None:
        super().__init__(robot, stop)
        from geometry_msgs.msg import Pose

        self._pose_type = Pose
        self.motion = motion
        self.options = options
        self.pose_pub = None
        if motion.goal is not None:
            self.pose_pub = self.rospy.Publisher(robot.pose_topic, Pose, queue_size=1, latch=True)
            self.watched_publishers.append((robot.pose_topic, self.pose_pub))

    def publish_goal(self) -> None:
        if self.pose_pub is None or self.motion.goal is None:
            return
        pose = self._pose_type()
        position, quaternion = self.motion.goal[:3, 3], matrix_to_quat(self.motion.goal[:3, :3])
        pose.position.x, pose.position.y, pose.position.z = (float(v) for v in position)
        fields = self.options.pose_convention.encode(quaternion)
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = fields
        self.pose_pub.publish(pose)

    def run(self) -> tuple[Schedule, RunResult]:
        """The approach (when on) and the scenario, step by step; a failure mid-run ends it with what was logged."""
        options, pacing = self.options, self.options.pacing
        stepper = Stepper(self, pacing)
        self.publish_goal()
        approach_on = options.approach > 0
        state = stepper.start(options.connect_timeout, need_state=approach_on or not pacing.realtime)
        priming = 0
        if approach_on and not pacing.realtime:
            # Priming step: no new command; the engine's joint state tells where the robot is.
            priming = 1
            state = stepper.hold()
        q_start = None
        if approach_on and state is not None:
            q_start = state.positions
            self.rospy.loginfo("robot at %s; approaching the scenario start", np.round(q_start, 4).tolist())
        schedule = build_schedule(self.motion, q_start, options.approach)
        steps = len(schedule.positions) - 1
        times = (np.arange(1, steps + 1) + priming) * pacing.dt
        achieved = np.full((steps, self.robot.dof), np.nan)
        stamps = np.full(steps, np.nan)
        started = time.monotonic()
        done = 0
        failure: str | None = None
        for i in range(1, steps + 1):
            if self.stop.is_set():
                break
            try:
                state = stepper.step(schedule.positions[i], schedule.velocities[i])
            except ControllerError as error:
                failure = None if self.stop.is_set() else str(error)
                break
            if state is not None:
                achieved[i - 1], stamps[i - 1] = state.positions, state.stamp
            done = i
        if done == steps:
            try:
                stepper.finish()
            except ControllerError:  # stopped while waiting for the last step's end: the run is complete anyway
                pass
        result = RunResult(
            times,
            np.arange(1, steps + 1),
            schedule.positions[1:],
            achieved,
            stamps,
            time.monotonic() - started,
            priming,
            done == steps,
            failure,
        )
        return schedule, result


# ------------------------------------------------------------------------------------------------------ main
def _default_log_path(robot: str, scenario: str) -> Path:
    return DEFAULT_LOG_DIR / f"{robot}_{scenario}_{datetime.now().strftime('%Y%m%d-%H%M%S-%f')}.csv"


def options_from_args(args: argparse.Namespace) -> CommanderOptions:
    """The run options of the command line, checked (ScenarioError names the first bad one)."""
    for option in ("timeout", "connect_timeout", "time_scale"):
        value = getattr(args, option)
        if not (math.isfinite(value) and value > 0):
            raise ScenarioError(f"--{option.replace('_', '-')} must be > 0, got {value}")
    if args.lockstep_rate is not None and not (math.isfinite(args.lockstep_rate) and args.lockstep_rate > 0):
        raise ScenarioError(f"--lockstep-rate must be > 0 steps a second, got {args.lockstep_rate}")
    if args.lockstep_rate is not None and args.realtime:
        raise ScenarioError("--lockstep-rate paces lockstep: with --realtime the wall clock paces the steps")
    if not (math.isfinite(args.approach) and args.approach >= 0):
        raise ScenarioError(f"--approach must be >= 0 s, got {args.approach}")
    return CommanderOptions(
        controller=_controller_link(args),
        pacing=Pacing(args.dt, args.realtime, args.time_scale, args.timeout, args.lockstep_rate),
        connect_timeout=args.connect_timeout,
        approach=args.approach,
        pose_convention=PoseConvention(args.pose_convention),
        node_name=args.node_name,
        log=args.log,
        wait_for=tuple(args.wait_for),
    )


def _controller_link(args: argparse.Namespace) -> ControllerLink | None:
    if args.trajectory_controller is None:
        return None
    if args.time_scale != 1.0:
        raise ScenarioError(f"--trajectory-controller runs on wall time: --time-scale must be 1, got {args.time_scale}")
    for option in ("horizon", "resend", "lead"):
        value = getattr(args, option)
        if not (math.isfinite(value) and value > 0):
            raise ScenarioError(f"--{option} must be > 0 s, got {value}")
    return ControllerLink(
        args.trajectory_controller, args.joint_states_topic or "", args.horizon, args.resend, args.lead
    )


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(without_ros_arguments(sys.argv[1:] if argv is None else argv))
    try:
        robot = robot_from_args(args)
        if args.scenario in OLD_SCENARIO_NAMES:
            warn(PROG, f"scenario {args.scenario!r} is now {OLD_SCENARIO_NAMES[args.scenario]!r}")
            args.scenario = OLD_SCENARIO_NAMES[args.scenario]
        if args.scenario not in SCENARIOS:
            raise ScenarioError(f"unknown scenario {args.scenario!r}; known: {', '.join(SCENARIOS)}")
        if args.export_only and args.export_csv is None:
            raise ScenarioError("--export-only needs --export-csv PATH")
        options = options_from_args(args)
        if options.controller is not None and not options.controller.joint_states_topic:
            options = replace(
                options, controller=replace(options.controller, joint_states_topic=robot.joint_states_topic)
            )
        motion = build_motion(robot, args.scenario, config_from_args(args))
        if options.controller is not None:
            link = options.controller
            if round(link.resend / motion.dt) + 1 >= round(link.horizon / motion.dt):
                raise ScenarioError(
                    f"--horizon ({link.horizon:g} s) must exceed --resend ({link.resend:g} s) by two steps of "
                    f"{motion.dt:g} s: a goal must still hold samples to come when the next one goes out"
                )
    except UnreachableGoalError as error:
        return fail(PROG, error, EXIT_UNREACHABLE_GOAL, label="UNREACHABLE")
    except SimError as error:  # a robot, a scenario or a number that cannot be used
        return fail(PROG, error, EXIT_BAD_INPUT)
    for note in motion.warnings:
        warn(PROG, note)
    if args.export_csv is not None:
        write_engine_csv(args.export_csv, motion)
        print(f"desired trajectory ({len(motion.times)} samples, dt {motion.dt:g} s) exported to {args.export_csv}")
        if args.export_only:
            return EXIT_OK
    if options.controller is not None:
        return _run_through_controller(robot, motion, options, options.controller)
    return _run_node(robot, motion, options)


def _run_through_controller(robot: RobotSpec, motion: Motion, options: CommanderOptions, link: ControllerLink) -> int:
    """The schedule through a trajectory controller on wall time (sim.control.trajectory_client)."""
    import rospy

    from sim.control.trajectory_client import TrajectoryClient
    from sim.wire.rosnode import init_node

    stop = threading.Event()
    init_node(options.node_name or f"{robot.name}_commander")
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    client = TrajectoryClient(robot, link, stop)
    log_path = options.log or _default_log_path(robot.name, motion.scenario)
    try:
        q_start = client.wait(options.connect_timeout)
        schedule = build_schedule(motion, q_start if options.approach > 0 else None, options.approach)
        rospy.loginfo(
            "%s/follow_joint_trajectory: running %s for %s (%d steps of %g s, goals of %g s every %g s)",
            link.namespace,
            motion.scenario,
            robot.name,
            len(schedule.positions) - 1,
            motion.dt,
            link.horizon,
            link.resend,
        )
        result = client.run(schedule, motion.dt)
    except ControllerError as error:
        return fail(PROG, error, EXIT_INTERRUPTED if stop.is_set() else EXIT_NO_CONNECTION)
    finally:
        client.close()
        rospy.signal_shutdown("commander done")
    report = write_log(log_path, robot, motion, schedule, result)
    print(format_summary(robot, motion, result, report, log_path, True))
    if result.error is not None:
        return fail(PROG, result.error, EXIT_NO_CONNECTION)
    return EXIT_OK if result.complete else EXIT_INTERRUPTED


def _run_node(robot: RobotSpec, motion: Motion, options: CommanderOptions) -> int:
    import rospy

    from sim.wire.rosnode import init_node

    stop = threading.Event()
    init_node(options.node_name or f"{robot.name}_commander")
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    commander = Commander(robot, motion, options, stop)
    log_path = options.log or _default_log_path(robot.name, motion.scenario)
    code = EXIT_OK
    try:
        partner = commander.wait_for_partner(options.connect_timeout, options.wait_for)
        rospy.loginfo(
            "engine %s connected; running %s for %s (%d steps of %g s)",
            partner,
            motion.scenario,
            robot.name,
            motion.steps,
            motion.dt,
        )
        schedule, result = commander.run()
    except ControllerError as error:
        rospy.logerr("%s", error)
        return fail(PROG, error, EXIT_INTERRUPTED if stop.is_set() else EXIT_NO_CONNECTION)
    finally:
        commander.close()
        rospy.signal_shutdown("commander done")
    report = write_log(log_path, robot, motion, schedule, result)
    print(format_summary(robot, motion, result, report, log_path, options.pacing.realtime))
    if motion.scenario == "fk_confirm":
        print(format_fk_confirm(report))
    if result.error is not None:
        rospy.logerr("%s", result.error)
        return fail(PROG, result.error, EXIT_INTERRUPTED if stop.is_set() else EXIT_NO_CONNECTION)
    if not result.complete:
        code = EXIT_INTERRUPTED
    if motion.ik is not None and motion.ik.fallback:
        print("sim.commander: the goal was unreachable; the nearest pose found was commanded (see FALLBACK above)")
        code = code or EXIT_UNREACHABLE_GOAL
    return code


if __name__ == "__main__":
    sys.exit(main())
