"""The game-engine stand-in: what Unity does in the thesis's set-up, as a TCP client of the endpoint. Imports no rospy.

Online: subscribes `<robot>/arm_controller/command` (JointTrajectory), `/clock` and `<robot>/pose` through the
endpoint, steps the pybullet physics, and publishes `<robot>/joint_states` after every step.
  auto-simulate on  (default): steps on its own wall clock (x `--time-scale`); stamps follow /clock if it runs.
  auto-simulate off (--no-auto-simulate): steps only as /clock advances (lockstep with the commander); when it
      (re)anchors its step grid on a /clock value it publishes its current joint state stamped with that value.
An endpoint that wants a token (--auth-token) gets it from the environment variable ROS_TCP_AUTH_TOKEN.
Offline (`--csv`): replays desired joint positions from a CSV without ROS or TCP and logs the achieved ones.

CSV formats (both): a header row `time,<joint name>,...` then one row per sample, time in s, positions in rad/m.
The input may name a subset of the joints (the others hold their start position); rows must be in time order.

One concern: the stand-in program, online and offline, with its pictures (--render) and its command line; the thesis's
use cases are switches of one program, not programs. The physics is sim.engine.physics'.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bridge.client import TcpClient
from sim.engine.clock import ClockAdvance, StepClock
from sim.engine.commands import CommandBuffer, command_is_due
from sim.engine.physics import Mode, PhysicsError, PhysicsWorld, SimulatedJointState, render_gif
from sim.entry import EXIT_BAD_INPUT, EXIT_NO_CONNECTION, EXIT_OK, fail, log_to_stderr
from sim.errors import SimError
from sim.geometry import frames
from sim.robots import RobotSpec, add_robot_arguments, robot_from_args
from sim.wire import rosmsgs
from sim.wire.contract import STAMP_TOLERANCE_S, STEP_S, PoseConvention, add_pose_convention_argument
from sim.wire.joint_csv import read_joint_csv, write_joint_csv

__all__ = [
    "EngineError",
    "EngineOptions",
    "make_world",
    "TargetMarker",
    "pose_to_marker",
    "FrameRecorder",
    "EngineStandIn",
    "path_velocity",
    "replay_csv",
    "argument_parser",
    "options_from_args",
    "main",
]

log = logging.getLogger(__name__)


class EngineError(SimError, ValueError):
    """Bad engine input: a CSV that cannot be replayed, an impossible option."""


@dataclass
class EngineOptions:
    mode: Mode = Mode.PHYSICS
    dt: float = STEP_S
    auto_simulate: bool = True
    time_scale: float = 1.0
    max_clock_jump_s: float = 1.0
    command_grace_s: float = 0.25
    pose_convention: PoseConvention = PoseConvention.QUATERNION
    stiffness: float | None = None
    damping: float | None = None
    force_limit: float | None = None
    gravity_feedforward: bool = True


def make_world(robot: RobotSpec, options: EngineOptions, shapes: bool = False) -> PhysicsWorld:
    """The engine's physics world; `shapes` for pictures (--render)."""
    world = PhysicsWorld(
        robot, mode=options.mode, dt=options.dt, gravity_feedforward=options.gravity_feedforward, shapes=shapes
    )
    try:
        world.set_drive(
            world.drive.with_overrides(
                stiffness=options.stiffness, damping=options.damping, force_limit=options.force_limit
            )
        )
    except PhysicsError:
        world.close()
        raise
    return world


@dataclass(frozen=True)
class TargetMarker:
    """The end-effector goal from the pose topic, as Unity would place it (left-handed, y up)."""

    position_unity: np.ndarray
    orientation_unity: np.ndarray  # x, y, z, w


def pose_to_marker(position: np.ndarray, orientation_fields: np.ndarray, convention: PoseConvention) -> TargetMarker:
    """Where Unity shows the goal pose; MessageError when the fields carry no orientation in `convention`."""
    quaternion = convention.decode(orientation_fields)
    return TargetMarker(frames.ros_to_unity_point(position), frames.ros_to_unity_quat(quaternion))


class FrameRecorder:
    """Pictures of the robot for --render (pybullet's headless TinyRenderer): the final pose as a PNG, or a frame
    every `interval_s` of sim time as an animated GIF (at most `max_frames`; a frame costs ~10-30 ms, so GIFs slow
    the run down and are opt-in)."""

    def __init__(
        self, path: Path, dt: float, interval_s: float = 0.2, max_frames: int = 300, size: tuple[int, int] = (320, 240)
    ) -> None:
        suffix = path.suffix.lower()
        if suffix not in (".png", ".gif"):
            raise EngineError(f"--render {path}: the file name must end in .png (final pose) or .gif (animation)")
        self.path = path
        self.animated = suffix == ".gif"
        self.every = max(1, round(interval_s / dt))
        self.frame_duration_s = self.every * dt
        self.max_frames = max_frames
        self.size = size
        self.frames: list[np.ndarray] = []

    def after_step(self, world: PhysicsWorld, step: int) -> None:
        if self.animated and step % self.every == 0 and len(self.frames) < self.max_frames:
            self.frames.append(world.capture(*self.size))

    def finish(self, world: PhysicsWorld) -> Path:
        if not self.animated:
            return world.render(self.path)
        self.frames.append(world.capture(*self.size))
        return render_gif(self.frames, self.path, self.frame_duration_s)


class EngineStandIn:
    """Physics + the endpoint connection. Callbacks (TCP reader thread) only store; `run` (its own thread) steps."""

    def __init__(
        self, robot: RobotSpec, client: TcpClient, options: EngineOptions, recorder: FrameRecorder | None = None
    ) -> None:
        self.robot = robot
        self.recorder = recorder
        self.client = client
        self.options = options
        self.world = make_world(robot, options, shapes=recorder is not None)
        self.commands = CommandBuffer(self.world.state().positions)
        self.clock = StepClock(options.dt, options.auto_simulate, options.time_scale, options.max_clock_jump_s)
        self.marker: TargetMarker | None = None
        self.rejected_commands = 0
        self.steps = 0
        self._clock_changed = threading.Condition()  # a new /clock value (clock-driven stepping waits for it)
        self._stop = threading.Event()
        self._seq = 0
        self._streaming = False  # True once a command stamped exactly at a step's end has arrived for it
        self._first_step_after_anchor = False  # the next clock-driven step is the first on a (re)anchored grid

    # --- TCP side ---------------------------------------------------------------------------------------------
    def attach(self) -> None:
        robot = self.robot
        self.client.subscribe(robot.command_topic, rosmsgs.JOINT_TRAJECTORY, self._on_command)
        self.client.subscribe("/clock", rosmsgs.CLOCK, self._on_clock)
        self.client.subscribe(robot.pose_topic, rosmsgs.POSE, self._on_pose)
        self.client.register_publisher(robot.joint_states_topic, rosmsgs.JOINT_STATE, queue_size=100)

    def _on_command(self, payload: bytes) -> None:
        try:
            command = rosmsgs.decode_joint_trajectory(payload, self.robot.joint_names)
        except rosmsgs.MessageError as error:
            self.rejected_commands += 1
            log.error("command rejected on %s: %s", self.robot.command_topic, error)
            return
        self.commands.store(command)

    def _on_clock(self, payload: bytes) -> None:
        try:
            value = rosmsgs.decode_clock(payload)
        except rosmsgs.MessageError as error:
            log.error("/clock message rejected: %s", error)
            return
        with self._clock_changed:
            self.clock.observe_clock(value, time.monotonic())
            self._clock_changed.notify_all()

    def _on_pose(self, payload: bytes) -> None:
        try:
            position, orientation = rosmsgs.decode_pose(payload)
            self.marker = pose_to_marker(position, orientation, self.options.pose_convention)
        except rosmsgs.MessageError as error:
            log.error("pose rejected on %s: %s", self.robot.pose_topic, error)

    # --- stepping ---------------------------------------------------------------------------------------------
    def step_to(self, t_end: float) -> None:
        """One fixed physics step whose end is `t_end`, then publish the resulting joint state."""
        target = self.commands.target_at(t_end)
        self.world.set_targets(target.positions, target.velocities)
        self.steps += 1
        self._publish_state(t_end, self.world.step())
        if self.recorder is not None:
            self.recorder.after_step(self.world, self.steps)

    def _publish_state(self, stamp: float, sample: SimulatedJointState) -> None:
        self._seq += 1
        self.client.publish(
            self.robot.joint_states_topic,
            rosmsgs.encode_joint_state(
                self._seq, stamp, self.robot.joint_names, sample.positions, sample.velocities, sample.efforts
            ),
        )

    def run(self, duration_s: float | None = None) -> None:
        """Step until `stop()` (or `duration_s` of sim time)."""
        if self.options.auto_simulate:
            self._run_auto(duration_s)
        else:
            self._run_clock_driven(duration_s)

    def stop(self) -> None:
        self._stop.set()
        with self._clock_changed:
            self._clock_changed.notify_all()

    def _run_auto(self, duration_s: float | None) -> None:
        clock = self.clock
        clock.poll(time.monotonic())  # anchors the step grid: the first step ends one step from now
        while not self._stop.is_set() and (duration_s is None or clock.time < duration_s - 1e-9):
            next_step = clock.next_step_wall()
            assert next_step is not None
            delay = next_step - time.monotonic()
            if delay > 0 and self._stop.wait(delay):
                return
            advance = clock.poll(time.monotonic())
            self._log_resync(advance)
            for step_end in advance.step_ends:
                self.step_to(step_end)

    def _run_clock_driven(self, duration_s: float | None) -> None:
        clock = self.clock
        while not self._stop.is_set():
            with self._clock_changed:
                self._clock_changed.wait_for(lambda: self._stop.is_set() or clock.pending() > 0, timeout=0.5)
                if self._stop.is_set():
                    return
                advance = clock.advance()
            self._log_resync(advance)
            if advance.anchored_at is not None:
                # The step grid is (re)anchored on this /clock value: say where the robot is, stamped with it.
                # This is the controller's cue that its clock has been taken (no steps were run).
                self._publish_state(advance.anchored_at, self.world.state())
                self._first_step_after_anchor = True
            for step_end in advance.step_ends:
                self._await_lockstep_command(step_end, clock.dt, self._first_step_after_anchor)
                self._first_step_after_anchor = False
                self.step_to(step_end)
            if duration_s is not None and clock.time >= duration_s - 1e-9:
                return

    @staticmethod
    def _log_resync(advance: ClockAdvance) -> None:
        if advance.resynced:
            log.warning(
                "the clock jumped by %.3f s: paused and resumed at %.3f without catching up",
                advance.jump,
                advance.anchored_at,
            )

    def _await_lockstep_command(self, step_end: float, dt: float, first_after_anchor: bool) -> None:
        """Wait briefly for this step's command when one is due (see `command_is_due`): it may arrive just after
        the /clock tick."""
        received, newest = self.commands.received, self.commands.newest_stamp
        if command_is_due(newest, step_end, dt, self._streaming, first_after_anchor):
            if not self.commands.wait_for_stamp(step_end, self.options.command_grace_s, received_after=received):
                self._streaming = False  # the controller stopped streaming per step, or never did
                log.info("no command for t=%.3f s; holding the last target", step_end)
                return
        newest = self.commands.newest_stamp
        if newest is not None and abs(newest - step_end) < STAMP_TOLERANCE_S:
            self._streaming = True

    def close(self) -> None:
        self.stop()
        self.world.close()


# ---------------------------------------------------------------------------------------------------------------
# Offline CSV mode (the thesis's Manual_Test): no ROS, no TCP.


def path_velocity(times: np.ndarray, positions: np.ndarray, t: float) -> np.ndarray:
    """Velocity of the piecewise-linear path through (times, positions) at t: the slope of the segment holding t;
    exactly at a sample, the mean of the slopes on either side (for a densely sampled smooth path, the central
    difference; a one-sided slope would lag by half a sample); 0 outside the samples, where the path holds."""
    slopes = np.diff(positions, axis=0) / np.diff(times)[:, None]
    slopes = np.vstack([np.zeros(positions.shape[1]), slopes, np.zeros(positions.shape[1])])  # held outside
    after = int(np.searchsorted(times, t))  # first sample at or after t
    if after < len(times) and abs(times[after] - t) < 1e-9:
        return 0.5 * (slopes[after] + slopes[after + 1])
    return slopes[after]


def replay_csv(
    robot: RobotSpec, csv_in: Path, log_out: Path, options: EngineOptions, recorder: FrameRecorder | None = None
) -> int:
    """Drive the physics through the CSV's positions: linear in time, the path's velocity as feed-forward."""
    times, names, desired = read_joint_csv(csv_in, robot)
    columns = [robot.joint_names.index(name) for name in names]
    with make_world(robot, options, shapes=recorder is not None) as world:
        start = world.state().positions.copy()
        if times[0] <= 0:
            start[columns] = desired[0]
            world.reset(start)
        step_ends = np.arange(1, int(np.floor(times[-1] / options.dt + 1e-9)) + 1) * options.dt
        achieved = np.empty((step_ends.size, robot.dof))
        for k, t_end in enumerate(step_ends):
            positions, velocities = start.copy(), np.zeros(robot.dof)
            positions[columns] = [np.interp(t_end, times, desired[:, j]) for j in range(len(names))]
            velocities[columns] = path_velocity(times, desired, t_end)
            world.set_targets(positions, velocities)
            achieved[k] = world.step().positions
            if recorder is not None:
                recorder.after_step(world, k + 1)
        if recorder is not None:
            recorder.finish(world)
    write_joint_csv(log_out, robot.joint_names, step_ends, achieved)
    return int(step_ends.size)


# ---------------------------------------------------------------------------------------------------------------


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m sim.engine", description=__doc__.splitlines()[0])
    add_robot_arguments(parser)
    parser.add_argument("--host", default="127.0.0.1", help="endpoint address")
    parser.add_argument("--port", type=int, default=10000, help="endpoint port")
    parser.add_argument("--mode", choices=[m.value for m in Mode], default=Mode.PHYSICS.value)
    parser.add_argument(
        "--dt", type=float, default=STEP_S, help=f"fixed physics step in s (Unity's FixedUpdate; default {STEP_S})"
    )
    parser.add_argument("--no-auto-simulate", action="store_true", help="step only as /clock advances")
    parser.add_argument("--time-scale", type=float, default=1.0, help="sim seconds per wall second (auto-simulate)")
    parser.add_argument("--max-clock-jump", type=float, default=1.0, help="larger /clock jumps pause and resume")
    parser.add_argument(
        "--command-grace",
        type=float,
        default=EngineOptions.command_grace_s,
        help="--no-auto-simulate: how long (s) a step waits for its command after its /clock tick "
        f"(default {EngineOptions.command_grace_s:g})",
    )
    add_pose_convention_argument(parser)
    parser.add_argument("--stiffness", type=float, help="drive stiffness for every joint (N·m/rad or N/m)")
    parser.add_argument("--damping", type=float, help="drive damping for every joint (N·m·s/rad or N·s/m)")
    parser.add_argument("--force-limit", type=float, help="drive force limit for every joint")
    parser.add_argument(
        "--no-gravity-feedforward",
        action="store_true",
        help="physics mode: the drives do not add the gravity torque (Unity's drives do not)",
    )
    parser.add_argument("--duration", type=float, help="stop after this much sim time (s)")
    parser.add_argument("--csv", type=Path, help="offline: replay desired positions from this CSV (no ROS, no TCP)")
    parser.add_argument("--log", type=Path, default=Path("logged_test_data.csv"), help="offline: achieved positions")
    parser.add_argument(
        "--render", type=Path, help="out.png: a picture of the final pose; out.gif: an animation (a frame every 0.2 s)"
    )
    return parser


def options_from_args(args: argparse.Namespace) -> EngineOptions:
    """The engine's options from `argument_parser()`'s arguments (shared with the rospy physics node)."""
    if not (args.dt > 0 and args.time_scale > 0 and args.max_clock_jump > 0):
        raise EngineError(
            f"--dt, --time-scale and --max-clock-jump must be > 0, got {args.dt}, {args.time_scale} "
            f"and {args.max_clock_jump}"
        )
    if not 0 <= args.command_grace < float("inf"):
        raise EngineError(f"--command-grace must be a finite number of seconds >= 0, got {args.command_grace}")
    return EngineOptions(
        mode=Mode(args.mode),
        dt=args.dt,
        auto_simulate=not args.no_auto_simulate,
        time_scale=args.time_scale,
        max_clock_jump_s=args.max_clock_jump,
        command_grace_s=args.command_grace,
        pose_convention=PoseConvention(args.pose_convention),
        stiffness=args.stiffness,
        damping=args.damping,
        force_limit=args.force_limit,
        gravity_feedforward=not args.no_gravity_feedforward,
    )


PROG = "sim.engine"


def main(argv: list[str] | None = None) -> int:
    args = argument_parser().parse_args(argv)
    log_to_stderr(logging.INFO)
    try:
        robot = robot_from_args(args)
        options = options_from_args(args)
        recorder = FrameRecorder(args.render, options.dt) if args.render is not None else None
        if args.csv is not None:
            steps = replay_csv(robot, args.csv, args.log, options, recorder)
            print(f"replayed {args.csv} in {steps} steps of {args.dt} s; achieved positions in {args.log}")
            return EXIT_OK
    except (SimError, ValueError) as error:  # ValueError: numbers numpy or the CSV reader could not take
        return fail(PROG, error, EXIT_BAD_INPUT)
    return _run_online(robot, options, args, recorder)


def _run_online(
    robot: RobotSpec, options: EngineOptions, args: argparse.Namespace, recorder: FrameRecorder | None
) -> int:
    import signal

    # an endpoint started with --auth-token: its token from the environment, as the page server takes it (not in ps)
    client = TcpClient(args.host, args.port, auth_token=os.environ.get("ROS_TCP_AUTH_TOKEN") or None)
    engine = EngineStandIn(robot, client, options, recorder)
    engine.attach()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: engine.stop())
    try:
        client.connect(timeout=30.0)
    except Exception as error:
        engine.close()
        return fail(PROG, error, EXIT_NO_CONNECTION)
    mode = "auto-simulate" if options.auto_simulate else "/clock-driven"
    print(
        f"engine: {robot.name} in {options.mode.value} mode, {mode}, dt {options.dt} s, "
        f"connected to {args.host}:{args.port}",
        flush=True,
    )
    try:
        engine.run(args.duration)
    finally:
        if recorder is not None:
            print(f"engine: picture in {recorder.finish(engine.world)}", flush=True)
        client.close()
        engine.close()
        print(
            f"engine: stopped after {engine.steps} steps; {engine.commands.received} commands, "
            f"{engine.rejected_commands} rejected",
            flush=True,
        )
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
