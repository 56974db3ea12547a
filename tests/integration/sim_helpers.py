"""Helpers for the engine / physics-node integration tests: start the processes, and drive one robot from rospy.

`Controller` is the test process acting as the commander (Simulink stand-in) for one robot: it publishes the
command, /clock and pose topics and records every joint state. `Controller.lockstep` runs the commander's
lockstep protocol: publish the command stamped t, then /clock = t, then wait for the joint state stamped t.
Every wait has a deadline (tests.rosenv.wait_for); nothing sleeps blindly.
"""

from __future__ import annotations

import subprocess
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.engine.physics import Mode, PhysicsWorld
from sim.launchers import Engine, PhysicsNode, start
from sim.processes import writes_to
from sim.robots import RobotSpec
from sim.wire.contract import STAMP_TOLERANCE_S, STEP_S
from tests.rosenv import PYTHON, REPO, ManagedProcess, RosCore, wait_for

DT = STEP_S


def start_engine(
    roscore: RosCore, log_dir: Path, robot: str, port: int, *extra: str, name: str = "engine"
) -> ManagedProcess:
    """`python -m sim.engine --robot R --port P ...`, returned once it reports the connection to the endpoint."""
    return start(Engine(("--robot", robot), port=port, extra=extra), roscore.env, log_dir, name, timeout=30)


def start_physics_node(roscore: RosCore, log_dir: Path, robot: str, *extra: str) -> ManagedProcess:
    return start(PhysicsNode(("--robot", robot), extra=extra), roscore.env, log_dir, f"{robot}_physics", timeout=30)


def ros_time(rospy, seconds: float):
    """Exact to the nanosecond (rospy.Time.from_sec truncates: 1.16 s would become 1.159999999 s)."""
    nanoseconds = int(round(seconds * 1e9))
    return rospy.Time(nanoseconds // 1_000_000_000, nanoseconds % 1_000_000_000)


@dataclass
class Run:
    """What a lockstep run sent and got back, one row per step (robot joint order)."""

    times: np.ndarray
    commanded: np.ndarray
    commanded_velocities: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    efforts: np.ndarray
    stamps: np.ndarray
    seqs: np.ndarray


class Controller:
    """The test process as the controller of one robot served by the ROS node `peer` (endpoint or physics node)."""

    def __init__(self, rospy, robot: RobotSpec, peer: str, dt: float = DT) -> None:
        from geometry_msgs.msg import Pose
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import JointState
        from trajectory_msgs.msg import JointTrajectory

        self.rospy = rospy
        self.robot = robot
        self.peer = peer if peer.startswith("/") else f"/{peer}"
        self.dt = dt
        self.states: list = []
        self.arrivals: list[float] = []  # time.monotonic() of each state's arrival
        self._lock = threading.Lock()
        self.command_pub = rospy.Publisher(robot.command_topic, JointTrajectory, queue_size=100, tcp_nodelay=True)
        self.clock_pub = rospy.Publisher("/clock", Clock, queue_size=100, tcp_nodelay=True)
        self.pose_pub = rospy.Publisher(robot.pose_topic, Pose, queue_size=10, tcp_nodelay=True)
        self.state_sub = rospy.Subscriber(robot.joint_states_topic, JointState, self._on_state, tcp_nodelay=True)
        self.clock_time: float | None = None  # the last /clock value published

    def _on_state(self, message) -> None:
        with self._lock:
            self.states.append(message)
            self.arrivals.append(time.monotonic())

    def snapshot(self) -> list:
        with self._lock:
            return list(self.states)

    def snapshot_with_arrivals(self) -> tuple[list, list[float]]:
        with self._lock:
            return list(self.states), list(self.arrivals)

    def close(self) -> None:
        for handle in (self.command_pub, self.clock_pub, self.pose_pub, self.state_sub):
            handle.unregister()

    def __enter__(self) -> Controller:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- connections ------------------------------------------------------------------------------------------
    def wait_ready(self, timeout: float = 15.0, publishers: Sequence[str] = ("command", "clock", "pose")) -> None:
        """The peer subscribes our topics, and our joint-state subscriber is connected to the peer's publisher."""
        import rosgraph

        pubs = {"command": self.command_pub, "clock": self.clock_pub, "pose": self.pose_pub}
        wait_for(
            lambda: all(pubs[name].impl.has_connection(self.peer) for name in publishers),
            timeout,
            f"{self.peer} to subscribe {list(publishers)}",
        )
        master = rosgraph.Master(self.rospy.get_name())
        uri = wait_for(lambda: _lookup(master, self.peer), timeout, f"{self.peer} registered")
        wait_for(
            lambda: writes_to(uri, self.robot.joint_states_topic, self.rospy.get_name()),
            timeout,
            f"{self.peer} writing {self.robot.joint_states_topic} to us",
        )

    # --- publishing -------------------------------------------------------------------------------------------
    def command(
        self,
        stamp: float,
        positions: Sequence[float],
        velocities: Sequence[float] | None = None,
        names: Sequence[str] | None = None,
    ) -> None:
        from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

        message = JointTrajectory()
        message.header.stamp = ros_time(self.rospy, stamp)
        message.joint_names = list(self.robot.joint_names if names is None else names)
        message.points = [
            JointTrajectoryPoint(
                positions=[float(x) for x in positions],
                velocities=[] if velocities is None else [float(x) for x in velocities],
            )
        ]
        self.command_pub.publish(message)

    def clock(self, t: float) -> None:
        from rosgraph_msgs.msg import Clock

        self.clock_pub.publish(Clock(clock=ros_time(self.rospy, t)))
        self.clock_time = t

    def pose(self, position: Sequence[float], orientation_xyzw: Sequence[float]) -> None:
        from geometry_msgs.msg import Point, Pose, Quaternion

        self.pose_pub.publish(Pose(position=Point(*position), orientation=Quaternion(*orientation_xyzw)))

    # --- joint states -----------------------------------------------------------------------------------------
    def wait_state(self, stamp: float, timeout: float = 5.0):
        """The joint state stamped `stamp` (within 1 µs)."""

        def found():
            with self._lock:
                for message in reversed(self.states):
                    if abs(message.header.stamp.to_sec() - stamp) < STAMP_TOLERANCE_S:
                        return message
            return None

        try:
            return wait_for(found, timeout, f"{self.robot.joint_states_topic} stamped {stamp:.3f} s", interval=0.0005)
        except TimeoutError as error:
            last = self.snapshot()[-1:]
            detail = f"; latest stamped {last[0].header.stamp.to_sec():.6f} s" if last else "; none received"
            raise TimeoutError(f"{error}{detail}") from None

    def wait_count(self, count: int, timeout: float = 10.0) -> list:
        return wait_for(
            lambda: (lambda s: s if len(s) >= count else None)(self.snapshot()),
            timeout,
            f"{count} joint states on {self.robot.joint_states_topic}",
        )

    # --- lockstep ---------------------------------------------------------------------------------------------
    def start_lockstep(self, priming_steps: int = 3):
        """Anchor the engine's step grid at /clock = 0, then run priming steps that hold the start (home) pose.

        The engine answers the anchoring with its joint state stamped 0; /clock may only move on after that (the
        engine keeps just the newest /clock value, so a quick second value would become the anchor instead).
        A command may lose its race against its /clock tick (two topics, two connections); the engine waits for it
        (`sim.engine.commands.command_is_due`). Returns the anchor state.
        """
        self.clock(0.0)
        anchor = self.wait_state(0.0, timeout=10.0)
        home = self.robot.home
        for k in range(1, priming_steps + 1):
            self.step(k * self.dt, home, np.zeros(self.robot.dof))
        return anchor

    def step(
        self,
        t: float,
        positions: Sequence[float],
        velocities: Sequence[float] | None = None,
        names: Sequence[str] | None = None,
        timeout: float = 5.0,
    ):
        self.command(t, positions, velocities, names)
        self.clock(t)
        return self.wait_state(t, timeout)

    def lockstep(self, positions: np.ndarray, velocities: np.ndarray, timeout: float = 5.0) -> Run:
        """One step per row after the current /clock time (the run's rows), commands stamped at the step ends."""
        assert self.clock_time is not None, "start_lockstep() first"
        start = round(self.clock_time / self.dt)
        times = (start + 1 + np.arange(len(positions))) * self.dt
        states = [self.step(t, q, v, timeout=timeout) for t, q, v in zip(times, positions, velocities)]
        return Run(
            times=times,
            commanded=np.asarray(positions, dtype=float),
            commanded_velocities=np.asarray(velocities, dtype=float),
            positions=np.array([s.position for s in states]),
            velocities=np.array([s.velocity for s in states]),
            efforts=np.array([s.effort for s in states]),
            stamps=np.array([s.header.stamp.to_sec() for s in states]),
            seqs=np.array([s.header.seq for s in states]),
        )


def _lookup(master, node: str) -> str | None:
    import rosgraph

    try:
        return master.lookupNode(node)
    except rosgraph.MasterError:
        return None


# --- commanded motions and the in-process reference -----------------------------------------------------------


def sine_motion(
    robot: RobotSpec, steps: int, dt: float = DT, amplitude: float = 0.2, period_s: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """(positions, velocities) for `steps` steps of dt: every joint swings away from home and back, from rest.

    q_j = home_j ± a·(1 − cos ωt) (signs alternate over the joints); prismatic joints swing a tenth as far (m).
    """
    t = dt * np.arange(1, steps + 1)[:, None]
    signs = np.where(np.arange(robot.dof) % 2 == 0, 1.0, -1.0)
    scale = np.array([0.1 if kind == "prismatic" else 1.0 for kind in robot.joint_types]) * amplitude * signs
    omega = 2 * np.pi / period_s
    positions = robot.home + scale * (1.0 - np.cos(omega * t))
    velocities = scale * omega * np.sin(omega * t)
    return positions, velocities


def reference_run(
    robot: RobotSpec, mode: Mode, positions: np.ndarray, velocities: np.ndarray, priming_steps: int = 3, dt: float = DT
) -> np.ndarray:
    """The joint positions an in-process PhysicsWorld reaches for the same targets (priming steps hold home)."""
    with PhysicsWorld(robot, mode=mode, dt=dt) as world:
        for _ in range(priming_steps):
            world.set_targets(robot.home, np.zeros(robot.dof))
            world.step()
        out = []
        for q, v in zip(positions, velocities):
            world.set_targets(q, v)
            out.append(world.step().positions)
    return np.array(out)


def report_rows(report: Path) -> dict[tuple[str, str, str], dict[str, str]]:
    lines = [line for line in report.read_text().splitlines() if line.startswith("| ")]
    headers = [cell.strip() for cell in lines[0].strip("|").split("|")]
    rows = {}
    for line in lines[1:]:
        cells = dict(zip(headers, (cell.strip() for cell in line.strip("|").split("|"))))
        rows[(cells["robot"], cells["use case"], cells["joint"])] = cells
    return rows


def mean_of(cell: str) -> float:
    return float(cell.split("±")[0])


def run_campaign(
    robots: Sequence[str],
    use_cases: Sequence[str],
    out: Path,
    trials: int = 1,
    env: dict[str, str] | None = None,
    timeout: float = 600,
    extra: Sequence[str] = (),
) -> subprocess.CompletedProcess[str]:
    """`python -m sim.trials` over `robots` (names or paths) and `use_cases` into `out`, with `extra` options; it
    must succeed."""
    done = subprocess.run(
        [PYTHON, "-m", "sim.trials", "--robots", *robots, "--use-cases", *use_cases, "--trials", str(trials)]
        + ["--out", str(out), "--no-progress", *extra],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done
