"""Braking through the stand-in's trajectory controller: press-to-braking latency and braking distance, over presses;
then presses and every injected fault through the study's runner: braked or not, separation, executed limits.

    .venv/bin/python -m bench.braking_bench [--presses 20] [--seconds 180] [--path diagonal] [--speed 0.5]
                                            [--dt 0.01] [--joint-states-rate 100] [--lead S] [--seed 0]
                                            [--only leads|sweep|faults ...] [--sweep 10] [--faults all|A,B]
                                            [--fault-runs 1] [--fault-at S] [--fault-seconds 900]

Three parts, all by default (--only picks some): the leads (below), the sweep of --sweep presses through the real
runner and each of --faults injected into it --fault-runs times (bench.fault_bench: its table and its last line,
"all faults braked; separation never under the floor" or what failed; the bench then exits 1).

The leads: what the study will do on a press with a real arm, without the study runner: a roscore, the physics node
as the Panda's driver (`--trajectory-controller /panda/position_joint_trajectory_controller`, on wall time, physics
step --dt, joint states at --joint-states-rate), and this process as the client, with actionlib's ActionClient. Each
press: the arm goes to the planned approach's start (a goal), the approach goes as one goal (positions, velocities and
accelerations of the planned samples), and at a random time while the planned speed is still rising (so that a fall
of the achieved speed is the braking's doing) the press:
  1. asks query_state for the desired state a lead ahead: the study link's own, measured on this connection
     (sim.study.run.links.lead: query_state's round trip, probed first and at each stop; the stop's planning, timed
     before each approach and at each stop; each goal's delivery, from send_goal to the controller's status of it),
     or --lead s fixed;
  2. builds the stop from it (sim.study.safety.braking.brake: along the path, jerk-limited, continuous in position,
     velocity and acceleration), and sends it as a replacement goal stamped at that time;
  3. waits for the stop's result and for the arm at rest.
Figures, per press and over all presses (median, p95, max):
  - the delays the lead covers: query_state's round trip, the stop's planning, a goal's delivery (every goal's), and
    the lead each stop was stamped with; how many stops were refused (all their points due on arrival: the approach
    went on) and how many the controller reported after their stamp (an upper bound: the report is a round trip);
  - press -> replacement sent (query_state, the stop's planning, send_goal returned), ms;
  - press -> achieved speed first falls: the first joint state (its stamp) after the press whose path speed (the
    achieved joint velocity projected on the path) is below the one before it, ms. It includes the look-ahead
    (--lead) and the stop's own ramp: the path acceleration goes from the plan's to braking at a bounded jerk, so
    the speed still rises a little before it falls;
  - braking distance, planned (along the path, from the desired state at the stamp to rest) and achieved (from the
    same start to where the arm rests, projected on the path), and the error achieved - planned, mm.
A replacement that goes out after its stamp is named: the controller drops its points already due and bridges from
its desired state then, and one whose points are all due is rejected and the approach carries on (ros_controllers
does the same); the figures are then also given for the presses sent in time.
The figures are not judged (the machine is shared: a loaded machine makes the physics steps late). Every loop is
bounded in count and time; roscore and the physics node are stopped by PID.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench import fault_bench
from sim.control.trajectory_client import wait_for_action_server
from sim.launchers import PhysicsNode, start
from sim.processes import RosCore
from sim.robots import load_robot
from sim.study.design.paths import ON_TOP, ApproachPath
from sim.study.design.scene import load_scene
from sim.study.run.links.lead import Leads, delivery_part
from sim.study.safety.braking import Braking, PathGeometry, PathState, arc_length, brake
from sim.study.safety.errors import SafetyError
from sim.study.safety.kinematic_plan import kinematic_plan

NS = "/panda/position_joint_trajectory_controller"
JOINT_STATES = "/franka_state_controller/joint_states"
PANDA = load_robot("panda")
TO_START_S = 1.5  # the goal that brings the arm back to the approach's start
REST_SPEED = 1e-3  # rad/s: every joint slower than this for REST_STATES joint states is at rest
REST_STATES = 10
WAIT_S = 20.0  # the longest wait for any one thing (a result, the arm at rest)
STOP_DT = 0.004  # s between the stop's samples
MAX_SWEEP = 40  # presses of the runner's sweep: one session, a trial each


def plan(name: str, speed: float) -> tuple[ApproachPath, np.ndarray]:
    """The study's approach `name` at `speed` for the Panda, tool pointing down, with the joints of every sample."""
    try:
        return kinematic_plan(PANDA, load_scene(), name, ON_TOP, speed, 0.02)
    except SafetyError as error:
        raise SystemExit(f"braking_bench: {error}") from None


QUERY_PROBES = 10  # query_state round trips before the first press, as the study's link measures at connect


@dataclass(frozen=True)
class Press:
    at_s: float  # into the approach
    lead_ms: float  # the stop's stamp after the press
    sent_ms: float
    acked_ms: float  # press -> the controller's status of the stop heard
    falls_ms: float
    planned_mm: float
    achieved_mm: float
    result: str


@dataclass
class Sent:
    """A goal sent: its handle, when (just before send_goal) and when the controller's first status of it came."""

    handle: Any
    at: float
    acked: float = float("nan")


class Client:
    """This process as the controller's client: joint states heard, the action, query_state."""

    def __init__(self) -> None:
        import actionlib
        import rospy
        from sensor_msgs.msg import JointState

        from sim.wire.control_types import control_types

        self.rospy = rospy
        self.types = control_types()
        self.states: list[tuple[float, np.ndarray, np.ndarray]] = []  # (stamp, positions, velocities)
        self._lock = threading.Lock()
        self._sub = rospy.Subscriber(JOINT_STATES, JointState, self._on_state, queue_size=1000, tcp_nodelay=True)
        self.client = actionlib.ActionClient(f"{NS}/follow_joint_trajectory", self.types.action)
        if not wait_for_action_server(self.client, f"{NS}/follow_joint_trajectory", 30):
            raise SystemExit("braking_bench: no action server")
        rospy.wait_for_service(f"{NS}/query_state", 30)
        self.query = rospy.ServiceProxy(f"{NS}/query_state", self.types.query_state, persistent=True)
        self._handles: list[Any] = []
        self.lead = Leads()  # the delays measured, as the study's link keeps them
        self.delays: dict[str, list[float]] = {"query": [], "planning": [], "delivery": [], "motion_delivery": []}
        for _ in range(QUERY_PROBES):
            self.query_at(time.time())

    def close(self) -> None:
        """Stop hearing the joint states (the fault bench's stand-in publishes on the same topic next)."""
        self._sub.unregister()
        self.query.close()

    def measured(self, part: str, seconds: float) -> None:
        with self._lock:
            self.lead.add(part, seconds)
            self.delays[part].append(seconds)

    def query_at(self, at: float) -> Any:
        """The controller's desired state at wall time `at`; its round trip measured."""
        asked = time.time()
        desired = self.query(self.types.query_state_request(time=self.rospy.Time.from_sec(at)))
        self.measured("query", time.time() - asked)
        return desired

    def _on_state(self, message: Any) -> None:
        with self._lock:
            self.states.append((message.header.stamp.to_sec(), np.array(message.position), np.array(message.velocity)))

    def since(self, stamp: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
        with self._lock:
            return [s for s in self.states if s[0] >= stamp]

    def trajectory(self, times: np.ndarray, q: np.ndarray, v: np.ndarray, a: np.ndarray, stamp: float = 0.0) -> Any:
        from sim.wire.control_types import joint_trajectory

        return joint_trajectory(PANDA.joint_names, times, q, v, a, stamp)

    def send(self, trajectory: Any, settle_s: float = 0.0) -> Sent:
        """The goal sent; `settle_s` > 0: the goal's time tolerance (else the controller's default). Its delivery
        (to the controller's first status of it) is measured."""
        from actionlib import CommState

        goal = self.types.goal()
        goal.trajectory = trajectory
        goal.goal_time_tolerance = self.rospy.Duration.from_sec(settle_s)
        sent = Sent(None, time.time())
        part = delivery_part(len(trajectory.points))  # a stop's, or a motion's (kept apart, as the link keeps them)

        def transition(handle: Any) -> None:
            if handle.get_comm_state() != CommState.WAITING_FOR_GOAL_ACK and sent.acked != sent.acked:  # NaN: not yet
                sent.acked = time.time()
                self.measured(part, sent.acked - sent.at)

        sent.handle = self.client.send_goal(goal, transition_cb=transition)
        self._handles = [h for h in self._handles[-4:]] + [sent.handle]  # actionlib tracks a goal while it lives
        return sent

    def outcome(self, handle: Any) -> str:
        from actionlib import CommState
        from actionlib_msgs.msg import GoalStatus

        deadline = time.monotonic() + WAIT_S
        while handle.get_comm_state() != CommState.DONE:
            if time.monotonic() > deadline:
                raise SystemExit("braking_bench: no result within the wait")
            time.sleep(0.005)
        names = {v: k for k, v in vars(GoalStatus).items() if isinstance(v, int) and k.isupper()}
        status = names.get(handle.get_goal_status(), str(handle.get_goal_status()))
        result = handle.get_result()
        return status if status == "SUCCEEDED" or result is None else f"{status} ({result.error_string})"

    def at_rest(self, after: float) -> tuple[float, np.ndarray]:
        """The first joint state after `after` that begins REST_STATES states all slower than REST_SPEED."""
        deadline = time.monotonic() + WAIT_S
        while time.monotonic() < deadline:
            states = self.since(after)
            for k in range(len(states) - REST_STATES + 1):
                window = states[k : k + REST_STATES]
                if max(np.abs(v).max() for _, _, v in window) < REST_SPEED:
                    return window[0][0], window[0][1]
            time.sleep(0.02)
        raise SystemExit("braking_bench: the arm did not come to rest")


def one_press(
    client: Client, geometry: PathGeometry, approach: Any, start: Any, press_at: float, fastest: Any, lead: float | None
) -> Press:
    reached = client.outcome(client.send(start, settle_s=WAIT_S / 2).handle)  # not measured: time to settle
    if reached != "SUCCEEDED":
        raise SystemExit(f"braking_bench: the arm did not reach the approach's start: {reached}")
    client.at_rest(time.time())
    planning = time.time()  # as the study's link does before each approach: this machine's planning time now
    fastest_q, fastest_v, fastest_a = fastest
    brake(geometry, fastest_q, fastest_v, fastest_a, STOP_DT)
    client.measured("planning", time.time() - planning)
    running = client.send(approach).handle
    begun = time.time()
    time.sleep(max(0.0, begun + press_at - time.time()))
    pressed = time.time()  # the press's stamp
    with client._lock:
        at = pressed + (client.lead.choose().lead if lead is None else lead)
    desired = client.query_at(at)
    planning = time.time()
    q, v, a = (np.array(x, dtype=float) for x in (desired.position, desired.velocity, desired.acceleration))
    stop: Braking | None = brake(geometry, q, v, a, STOP_DT)
    if stop is None:
        raise SystemExit(f"braking_bench: no stop at {press_at:.2f} s (the plan rests first)")
    replacement = client.trajectory(stop.times[1:], stop.positions[1:], stop.velocities[1:], stop.accelerations[1:], at)
    braking = client.send(replacement)
    client.measured("planning", braking.at - planning)
    sent = braking.at
    result = client.outcome(braking.handle)
    client.outcome(running)
    rest_stamp, rest = client.at_rest(at)
    speeds = [
        (stamp, geometry.project(q, v, np.zeros_like(v)).speed)
        for stamp, q, v in client.since(pressed)
        if stamp <= rest_stamp
    ]
    falls = next((b[0] for a, b in zip(speeds, speeds[1:]) if b[1] < a[1]), float("nan"))
    achieved_arc = geometry.project(rest, np.zeros_like(rest), np.zeros_like(rest)).arc
    return Press(
        at_s=press_at,
        lead_ms=(at - pressed) * 1e3,
        sent_ms=(sent - pressed) * 1e3,
        acked_ms=(braking.acked - pressed) * 1e3,
        falls_ms=(falls - pressed) * 1e3,
        planned_mm=stop.distance * 1e3,
        achieved_mm=(achieved_arc - stop.start.arc) * 1e3,
        result=result,
    )


def summary(label: str, values: np.ndarray, digits: int = 1) -> str:
    values = values[np.isfinite(values)]
    if not len(values):
        return f"{label}: none"
    return (
        f"{label}: median {np.median(values):.{digits}f}, p95 {np.percentile(values, 95):.{digits}f}, "
        f"max {values.max():.{digits}f}, min {values.min():.{digits}f}"
    )


def print_leads(presses: list[Press], delays: dict[str, np.ndarray]) -> None:
    """The figures of the presses through this process's own client, over all presses."""
    sent = np.array([p.sent_ms for p in presses])
    leads = np.array([p.lead_ms for p in presses])
    falls = np.array([p.falls_ms for p in presses])
    errors = np.array([p.achieved_mm - p.planned_mm for p in presses])
    succeeded = sum(p.result == "SUCCEEDED" for p in presses)
    refused = sum(p.result.startswith("REJECTED") for p in presses)
    late = int(np.sum(sent > leads))
    acked_late = int(np.sum(np.array([p.acked_ms for p in presses]) > leads))
    print(
        f"{len(presses)} presses ({succeeded} stops SUCCEEDED, {refused} refused; {late} replacements sent after "
        f"their stamp, {acked_late} reported by the controller after it)"
    )
    print("the delays a stop's lead covers [ms]:")
    for part, values in delays.items():
        print(summary(f"  {part} ({len(values)} measured)", values, 2))
    print(summary("the lead each stop was stamped with [ms]", leads))
    print(summary("press -> replacement sent [ms]", sent))
    print(summary("press -> achieved speed first falls [ms]", falls))
    print(summary("braking distance planned [mm]", np.array([p.planned_mm for p in presses])))
    print(summary("press -> achieved speed first falls, after the stop's stamp [ms]", falls - leads))
    print(summary("braking distance error, achieved - planned [mm]", errors, 3))
    print(summary("|braking distance error| [mm]", np.abs(errors), 3))
    on_time = sent <= leads
    print(f"the {int(on_time.sum())} replacements sent before their stamp:")
    print(summary("  press -> achieved speed first falls [ms]", falls[on_time]))
    print(summary("  |braking distance error| [mm]", np.abs(errors[on_time]), 3))


def run_leads(args: argparse.Namespace, env: dict[str, str], tmp: Path) -> None:
    """The presses through this process's own client (the stand-in under /panda/), their figures printed."""
    path, joints = plan(args.path, args.speed)
    geometry = PathGeometry(path, joints)
    arc, accelerations = arc_length(path), np.gradient(path.speeds, path.dt)
    planned = [geometry.joint_state(PathState(arc[k], path.speeds[k], accelerations[k])) for k in range(len(arc))]
    q, v, a = (np.array([state[i] for state in planned]) for i in range(3))
    earliest = (0.1 if args.lead is None else args.lead) + 0.05
    rising = path.times[(accelerations > 0.05) & (path.times > earliest)]
    if not len(rising):
        raise SystemExit("braking_bench: the plan's speed never rises")
    rng = np.random.default_rng(args.seed)
    press_times = rng.uniform(rising.min(), rising.max(), args.presses)
    k = int(np.argmax(path.speeds))
    fastest = (q[k], v[k], a[k])  # the longest stop, timed before each approach

    node = start(
        PhysicsNode(
            ("--robot", "panda"),
            dt=args.dt,
            extra=(
                "--trajectory-controller",
                NS,
                "--joint-states-topic",
                JOINT_STATES,
                "--joint-states-rate",
                str(args.joint_states_rate),
            ),
        ),
        env,
        tmp,
        "panda_physics",
        timeout=60,
    )
    try:
        client = Client()
        zero = np.zeros((1, PANDA.dof))
        start_goal = client.trajectory(np.array([TO_START_S]), q[:1], zero, zero)
        approach = client.trajectory(path.times[1:], q[1:], v[1:], a[1:])
        print(
            f"Braking bench: {args.path} approach at {args.speed:g} m/s ({path.times[-1]:.2f} s), physics step "
            f"{args.dt * 1e3:g} ms, joint states at {args.joint_states_rate:g} Hz, the stop stamped "
            + ("a measured lead" if args.lead is None else f"{args.lead * 1e3:g} ms")
            + f" after the press; presses at {rising.min():.2f}-{rising.max():.2f} s (the planned speed rising)"
        )
        presses: list[Press] = []
        began = time.monotonic()
        for press_at in press_times:
            if time.monotonic() - began > args.seconds:
                break
            press = one_press(client, geometry, approach, start_goal, float(press_at), fastest, args.lead)
            presses.append(press)
            sent_late = press.sent_ms > press.lead_ms
            print(
                f"  press at {press.at_s:.3f} s: stamped {press.lead_ms:.1f} ms ahead, sent after "
                f"{press.sent_ms:.1f} ms, the controller's status after {press.acked_ms:.1f} ms, speed falls after "
                f"{press.falls_ms:.1f} ms; distance planned {press.planned_mm:.1f} mm, achieved "
                f"{press.achieved_mm:.1f} mm (error {press.achieved_mm - press.planned_mm:+.3f} mm); {press.result}"
                + (" (sent after its stamp: the controller bridged from later)" if sent_late else "")
            )
        delays = {part: np.array(values) * 1e3 for part, values in client.delays.items()}
        client.close()
    finally:
        node.stop()
    print_leads(presses, delays)


SECTIONS = ("leads", "sweep", "faults")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presses", type=int, default=20, help="how many presses (default 20)")
    parser.add_argument("--seconds", type=float, default=180.0, help="stop pressing after this long (default 180)")
    parser.add_argument("--path", default="diagonal", help="the study's approach path (default diagonal)")
    parser.add_argument("--speed", type=float, default=0.5, help="its peak speed in m/s (default 0.5)")
    parser.add_argument("--dt", type=float, default=0.01, help="the physics step in s (default 0.01)")
    parser.add_argument("--joint-states-rate", type=float, default=100.0, help="Hz (default 100: every step)")
    parser.add_argument(
        "--lead", type=float, default=None, help="s between the press and the stop's stamp (default: measured)"
    )
    parser.add_argument("--seed", type=int, default=0, help="of the press times (default 0)")
    parser.add_argument(
        "--only", action="append", choices=SECTIONS, help="run only these parts (repeatable; default all three)"
    )
    parser.add_argument("--sweep", type=int, default=10, help="presses through the runner, one session (default 10)")
    parser.add_argument(
        "--faults", default="all", help=f"comma-separated, or all (default): {', '.join(fault_bench.FAULTS)}"
    )
    parser.add_argument("--fault-runs", type=int, default=1, help="runs of each fault (default 1)")
    parser.add_argument(
        "--fault-at", type=float, default=None, help="s into the approach of each fault (default: its peak speed)"
    )
    parser.add_argument(
        "--fault-seconds", type=float, default=900.0, help="no fault run begins after this long (default 900)"
    )
    args = parser.parse_args(argv)
    lead_ok = args.lead is None or args.lead > 0
    if not (args.presses > 0 and args.seconds > 0 and args.dt > 0 and args.joint_states_rate > 0 and lead_ok):
        parser.error("--presses, --seconds, --dt, --joint-states-rate and --lead must be > 0")
    fault_at_ok = args.fault_at is None or args.fault_at > 0
    if not (0 <= args.sweep <= MAX_SWEEP and args.fault_runs > 0 and args.fault_seconds > 0 and fault_at_ok):
        parser.error(f"--sweep must be 0-{MAX_SWEEP}; --fault-runs, --fault-seconds and --fault-at > 0")
    faults = list(fault_bench.FAULTS) if args.faults == "all" else [f for f in args.faults.split(",") if f]
    unknown = [name for name in faults if name not in fault_bench.FAULTS]
    if unknown:
        parser.error(f"no fault {', '.join(unknown)}; the faults: {', '.join(fault_bench.FAULTS)}")
    sections = set(args.only or SECTIONS)

    ok = True
    with tempfile.TemporaryDirectory(prefix="braking-bench-") as tmp:
        core = RosCore()
        try:
            os.environ.update(core.env)
            import rospy

            rospy.init_node("braking_bench", anonymous=True, disable_signals=True)
            if "leads" in sections:
                run_leads(args, core.env, Path(tmp))
            if "sweep" in sections or "faults" in sections:
                sweep = args.sweep if "sweep" in sections else 0
                chosen = faults if "faults" in sections else []
                ok = fault_bench.run(
                    rospy, core.env, Path(tmp), sweep, chosen, args.fault_runs, args.fault_seconds, args.fault_at
                )
            rospy.signal_shutdown("braking bench done")
        finally:
            core.stop()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
