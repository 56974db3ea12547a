"""The braking bench's presses and faults through the study's real runner: how often the arm braked, the least
separation it achieved against the floor, and what the controller executed against the Panda's limits.

Run by `python -m bench.braking_bench` (its --sweep and --faults). Each session is the real runner
(`python -m sim.study run --realtime --keyboard --link reality=...`) on a plan of the `vertical` approach to 6 cm at
0.2 m/s, driving the physics node's ros_control trajectory controller (franka_ros's topics, 30 Hz joint states; or
set up as a UR's driver: 500 Hz, a cancel easing to rest over 0.5 s). This process, beside them, presses or injects
one fault into the approach, as tests/integration/test_study_faults.py does (bench.fault_relays):

  - the sweep: one session of N trials, each pressed ("s" at the runner's keyboard) at its own time, spread over
    the approach while the arm still has 6 cm or more to go;
  - each fault once (--fault-runs), at the approach's peak speed so that the arm brakes from its fastest
    (--fault-at; the tests inject at 0.5 s): SIGINT, SIGTERM; query_state gone, then a press; query_state restarted
    between two trials, then a press; query_state answering 0.2 s late, then a press; a joint state with 6 positions
    for 7 joints, one with a NaN; the runner's wall clock stepped by +2 s and -2 s (bench/stepped_clock.py); the
    feed gone stale 50 ms after a press; the braking goal aborted by the controller (a path tolerance of 1 µrad); the
    tracked hand lost. Two of them also on the UR-like controller.

Figures per fault: the runs, how many braked (the arm at rest at least BRAKED_SHORT short of its stand-off, where an
arm not braked comes to rest), the runner's exit codes, the least rest short of the stand-off, the least separation
of the arm from the scene's hand in any joint state heard while the motion ran (and the runner's own record where it
wrote one) against the floor, the largest executed acceleration and jerk as a share of the Panda's limits from the
approach acted on to the end (every goal and cancel heard beside the controller, replayed at 1 kHz through
ros_control's semantics: sim.engine.executed; the whole sessions' below the table, the moves to the starts too), and
the leads the stops were stamped with (how many were sent after their stamp, how many braked from the commanded
path). Per trial with a stop sent, its run-on (the record's braking distance achieved − planned) against the bound
bench.run_on derives from the trial's own figures (the speed at the press, the stop's latency and lead, the tracking
error); per row, the run-ons' median, p95 and max. The last line says whether every fault braked, no separation fell
under the floor and every run-on kept its bound (and whether the executed motion stayed within the limits); run()
returns False when a run did not brake, fell under the floor, ran on past its bound or gave no figures, and the
bench then exits 1.

Every wait is bounded (PHASE_WAIT_S per phase, the sessions by a time budget); every process is killed by its PID.

Long because a fault run is one experiment: each injection is timed to the session it acts on, and its figures are read
from what was heard beside that session and from its record. What stands alone already does: bench.fault_relays,
bench/stepped_clock.py, bench.run_on.
"""

from __future__ import annotations

import csv
import math
import os
import signal
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bench.fault_relays import (
    JOINT_STATES,
    NS,
    RELAY,
    RELAYED_STATES,
    ControllerRelay,
    HeardGoals,
    QueryNode,
    StateRelay,
    Tracker,
    Watch,
)
from bench.run_on import RunOn, distribution, run_on_bound
from sim.engine.executed import Executed, executed_extremes
from sim.launchers import PhysicsNode, start
from sim.processes import PYTHON, REPO, ManagedProcess, kill_process
from sim.study.design.feasibility import Approaches
from sim.study.design.paths import approach_path
from sim.study.design.scene import load_scene, scene_robot
from sim.study.safety.braking import STOP_DECELERATION, PathGeometry, arc_length
from sim.study.safety.limits import PANDA_LIMITS

PATH, STANDOFF, SPEED = "vertical", 0.06, 0.2  # the tests' approach: m, m/s
FLOOR = 0.01  # m: the runner's default --floor
BRAKED_SHORT = 0.01  # m: an arm resting this far short of its stand-off or more was braked
FIRST_PRESS_S = 0.5  # s into the approach of the sweep's first press (the fault tests' time)
LEFT_AT_PRESS = 0.06  # m: the sweep presses while at least this much of the approach is left
PHASE_WAIT_S = 60.0  # the longest wait for one of the runner's phases, or for it to end
STEPPED_CLOCK = Path(__file__).with_name("stepped_clock.py")
ARMS = {  # the controller as franka_ros sets it up, and as a UR's driver does: options, stop_trajectory_duration
    "franka": (("--joint-states-rate", "30"), 0.0),
    "ur_like": (("--joint-states-rate", "500", "--stop-trajectory-duration", "0.5"), 0.5),
}
SEPARATION_EVERY_S = 0.01  # the heard joint states' separations are computed at most this often


@dataclass
class Injection:
    """One fault as a session runs it: what to do to the runner during the last trial's approach, the link
    the runner is given, and what is done between trials and after the session."""

    act: Callable[[subprocess.Popen], None]
    link: str = "franka_ros"
    trials: int = 1
    stepped_clock: bool = False
    between: Callable[[], None] = lambda: None
    close: Callable[[], None] = lambda: None


@dataclass(frozen=True)
class Trial:
    braked: bool
    short: float  # m: the rest short of the stand-off
    least: float  # m: the least separation heard while the motion ran
    recorded: float  # m: the runner's least_separation (NaN: no row, or none recorded)
    run_on: RunOn | None = None  # the stop's run-on and its bound (bench.run_on); None: no stop sent, or no row


@dataclass
class Session:
    code: int | None
    trials: list[Trial]
    executed: Executed | None  # from the first approach acted on to the end
    whole: Executed | None  # the whole session's, the moves to the starts included
    leads: list[float] = field(default_factory=list)  # ms, each stop's
    after_stamp: int = 0
    from_path: int = 0
    acted: int = 0  # the trials the session was to act on: fewer measured is a session that ended early
    said: str = ""  # why the session has no figures ("" when it has)


def press(runner: subprocess.Popen) -> None:
    type_line(runner, "s\n")


def type_line(runner: subprocess.Popen, line: str) -> None:
    if runner.stdin is not None and runner.poll() is None:
        try:
            runner.stdin.write(line)
            runner.stdin.flush()
        except BrokenPipeError:
            pass  # the runner ended: what it did is what the session measures


class Bench:
    """The parts every session shares: this process's rospy node, the ROS environment, the arm's stand-in."""

    def __init__(self, rospy: Any, env: dict[str, str], tmp: Path) -> None:
        from sim.wire.control_types import control_types

        self.rospy, self.env, self.tmp = rospy, env, tmp
        self.types = control_types()
        self.scene = load_scene()
        self.approaches = Approaches(scene_robot(self.scene), self.scene, 0.01)
        self.joint_names = scene_robot(self.scene).joint_names
        planned = self.approaches.plan((PATH, STANDOFF, SPEED))  # the run-on's bound reads the plan's figures
        self.path = planned.path
        geometry = PathGeometry(planned.path, planned.positions)
        along = np.linspace(0.0, float(arc_length(planned.path)[-1]), 2000)
        self.joint_rate = float(np.linalg.norm(geometry.joints(along, 1), axis=1).min())  # rad/m
        accelerations = np.abs(np.gradient(planned.path.speeds, planned.path.times))
        self.acceleration = max(float(accelerations.max()), STOP_DECELERATION)  # m/s²: the plan's, or the braking's
        self.watch = Watch(rospy)
        self.arm: ManagedProcess | None = None
        self.arm_kind = ""
        self.participant = 0

    def use_arm(self, kind: str) -> None:
        """The stand-in set up as `kind` (ARMS), started anew when it is another."""
        if self.arm is not None and self.arm_kind == kind:
            return
        self.stop_arm()
        self.watch.forget_states()  # the last stand-in's rest is not this one's home
        options, _ = ARMS[kind]
        self.arm = start(
            PhysicsNode(
                ("--robot", "panda"),
                mode="physics",
                extra=("--trajectory-controller", NS, "--joint-states-topic", JOINT_STATES, *options),
            ),
            self.env,
            self.tmp,
            f"panda_{kind}",
            timeout=60,
        )
        self.arm_kind = kind

    def stop_arm(self) -> None:
        if self.arm is not None:
            self.arm.stop()
            self.arm = None

    def close(self) -> None:
        self.stop_arm()
        self.watch.close()
        self.approaches.close()

    def separation(self, positions: np.ndarray) -> float:
        return float(self.approaches.hand_distance(np.asarray(positions, dtype=float)))

    def run_on(self, row: dict[str, str], arm: str) -> RunOn | None:
        """A trial row's run-on and its bound (bench.run_on); None without a stop sent (no lead recorded)."""
        names = ("press_time", "replacement_latency", "stop_lead", "tracking_error", "braking_distance")
        figures = [float(row.get(name) or "nan") for name in (*names, "braking_distance_achieved")]
        if not all(math.isfinite(value) for value in figures):
            return None
        press_time, latency, lead, tracking, planned, achieved = figures
        options, _ = ARMS[arm]
        interval = 1.0 / float(options[options.index("--joint-states-rate") + 1])
        path, dof = self.path, len(self.joint_names)
        bound = run_on_bound(
            path.times, path.speeds, press_time, latency, lead, tracking, dof, self.joint_rate, self.acceleration,
            interval,
        )  # fmt: skip
        return RunOn(achieved - planned, bound)

    # --- the faults ---------------------------------------------------------------------------------------------
    def injection(self, name: str) -> Injection:
        signals = {"sigint": signal.SIGINT, "sigterm": signal.SIGTERM, "clock+2": signal.SIGUSR1}
        signals["clock-2"] = signal.SIGUSR2
        if name in signals:
            signum = signals[name]
            return Injection(lambda runner: os.kill(runner.pid, signum), stepped_clock=name.startswith("clock"))
        if name in ("query-gone", "query-restarted"):
            relay = ControllerRelay(self.rospy, self.types, query=False)
            queries = QueryNode(self.rospy, self.env, self.tmp / "query_relay.log")

            def gone_then_press(runner: subprocess.Popen) -> None:
                queries.stop()
                press(runner)

            def restart() -> None:
                queries.stop()
                queries.start()

            def close() -> None:
                queries.stop()
                relay.close()

            restarted = name == "query-restarted"
            return Injection(
                press if restarted else gone_then_press, f"{RELAY},{JOINT_STATES}", trials=2 if restarted else 1,
                between=restart, close=close,
            )  # fmt: skip
        if name == "query-late":
            slow = ControllerRelay(self.rospy, self.types)

            def slow_then_press(runner: subprocess.Popen) -> None:
                slow.query_delay = 0.2  # longer than any stop's lead
                press(runner)

            return Injection(slow_then_press, f"{RELAY},{JOINT_STATES}", close=slow.close)
        if name in ("six-positions", "nan"):
            states = StateRelay(self.env, self.tmp / "state_relay.log", name)
            return Injection(lambda runner: states.inject(), f"{NS},{RELAYED_STATES}", close=states.close)
        if name == "stale-braking":
            feed = StateRelay(self.env, self.tmp / "state_relay.log", "silence")

            def press_then_stale(runner: subprocess.Popen) -> None:
                press(runner)
                time.sleep(0.05)  # the stop on its way: the feed ends as the arm brakes
                feed.inject()

            return Injection(press_then_stale, f"{NS},{RELAYED_STATES}", close=feed.close)
        if name == "braking-aborted":
            tolerance = self.types.joint_tolerance

            def tight(number: int, goal: Any) -> None:
                if number == 3:  # 1: the move to the path's start, 2: the approach, 3: the stop
                    tight_path = [tolerance(name=joint, position=1e-6) for joint in self.joint_names]
                    goal.goal.path_tolerance = tight_path

            relay = ControllerRelay(self.rospy, self.types, tight)
            return Injection(press, f"{RELAY},{JOINT_STATES}", close=relay.close)
        if name == "tracking-gap":
            tracker = Tracker(self.rospy, np.asarray(self.scene.hand.top, dtype=float))
            return Injection(lambda runner: tracker.lose(), close=tracker.close)
        raise ValueError(f"no fault {name!r}")

    # --- one session --------------------------------------------------------------------------------------------
    def session(self, injection: Injection, acts: list[float], arm: str) -> Session:
        """The runner on a plan of `injection.trials` trials (at least len(acts)): the last len(acts) trials each get
        `injection.act` that many s into their approach. What it did."""
        self.use_arm(arm)
        self.participant += 1
        participant, trials = self.participant, max(injection.trials, len(acts))
        home = self.watch.at_rest(30)
        if home is None:
            return Session(None, [], None, None, said="the arm did not rest before the session")
        folder = self.tmp / f"session_{participant:02d}"
        folder.mkdir()
        plan = folder / "plan.yaml"
        rows = [
            {"index": k, "condition": "reality", "test": 1, "path": PATH, "standoff": STANDOFF, "peak_speed": SPEED,
             "speed_set": "", "group": 0}
            for k in range(1, trials + 1)
        ]  # fmt: skip
        document = {"participant": participant, "seed": 0, "conditions": ["reality", "vr"], "trials": rows}
        plan.write_text(yaml.safe_dump({**document, "questionnaires": [], "items": {}}))
        program = [str(STEPPED_CLOCK)] if injection.stepped_clock else ["-m", "sim.study"]
        command = [
            PYTHON, *program, "run", "--plan", str(plan), "--out", str(folder / "out"), "--keyboard", "--realtime",
            "--no-record", "--auto-go", "--connect-timeout", "30", "--link", f"reality={injection.link}",
        ]  # fmt: skip
        heard = HeardGoals(self.rospy, self.types)
        log = folder / "runner.log"
        windows: list[tuple[int, float, float]] = []  # (index, moving, asked for the distance) of each acted on
        self.watch.forget_phases()  # the last session's trials had the same indices
        try:
            with open(log, "w") as output:
                runner = subprocess.Popen(
                    command, env=self.env, cwd=REPO, stdin=subprocess.PIPE, stdout=output, stderr=subprocess.STDOUT,
                    text=True, start_new_session=True,
                )  # fmt: skip
            try:
                first_act = trials - len(acts) + 1
                for k in range(1, trials + 1):
                    moving = self.watch.wait(k, "moving", runner, PHASE_WAIT_S)
                    if moving is None:
                        break
                    if k >= first_act:
                        time.sleep(max(0.0, moving + acts[k - first_act] - time.time()))
                        injection.act(runner)
                    asked = self.watch.wait(k, "distance", runner, PHASE_WAIT_S)
                    if k >= first_act:
                        windows.append((k, moving, asked if asked is not None else math.inf))
                    if asked is None:
                        break
                    if k < trials:
                        injection.between()
                    type_line(runner, "20 cm\n")
                try:
                    runner.wait(PHASE_WAIT_S)
                except subprocess.TimeoutExpired:
                    pass  # killed below: its figures are what it did until then
            finally:
                kill_process(runner)
            rest = self.watch.at_rest(30)
            until = time.time()
        finally:
            heard.close()
            injection.close()
        measured = self._measured(runner.returncode, home, rest, until, windows, heard, folder, participant, arm)
        measured.acted = len(acts)
        return measured

    def _measured(
        self,
        code: int | None,
        home: np.ndarray,
        rest: np.ndarray | None,
        until: float,
        windows: list[tuple[int, float, float]],
        heard: HeardGoals,
        folder: Path,
        participant: int,
        arm: str,
    ) -> Session:
        output = (folder / "runner.log").read_text(errors="replace")
        if rest is None:
            return Session(code, [], None, None, said="the arm did not come to rest")
        if not windows:
            return Session(code, [], None, None, said=f"no approach began; the runner: {output[-400:]!r}")
        records = folder / "out" / f"participant_{participant:02d}.csv"
        rows: dict[int, dict[str, str]] = {}
        if records.exists():
            with open(records, newline="") as source:
                rows = {int(row["index"]): row for row in csv.DictReader(source)}
        trials = []
        for k, began, ended in windows:
            states = self.watch.between(began, min(ended, until))
            last = rest if math.isinf(ended) or not states else states[-1][1]
            separations, seen = [], -math.inf
            for stamp, positions, _ in states:
                if stamp - seen >= SEPARATION_EVERY_S:
                    separations.append(self.separation(positions))
                    seen = stamp
            at_rest = self.separation(last)
            recorded = rows.get(k, {}).get("least_separation", "")
            trials.append(
                Trial(
                    at_rest - STANDOFF >= BRAKED_SHORT,
                    at_rest - STANDOFF,
                    min([*separations, at_rest]),
                    float(recorded) if recorded else math.nan,
                    self.run_on(rows.get(k, {}), arm),
                )
            )
        events = heard.taken()
        _, stop_duration = ARMS[arm]
        executed = whole = None
        if events:
            limits = PANDA_LIMITS
            assert limits.acceleration is not None and limits.jerk is not None
            replay = (events, self.joint_names, home, until, limits.acceleration, limits.jerk, stop_duration)
            whole = executed_extremes(*replay)
            executed = executed_extremes(*replay, since=windows[0][1])
        stops = [line for line in output.splitlines() if ": a stop stamped " in line]
        leads = [float(line.split(": a stop stamped ")[1].split(" ms")[0]) for line in stops]
        after = sum("(AFTER its stamp)" in line for line in stops)
        from_path = sum("from the commanded path" in line for line in stops)
        return Session(code, trials, executed, whole, leads, after, from_path)


# --- what the bench runs and prints -------------------------------------------------------------------------------
FAULTS = {  # name: (what the table says, the arm, the fault injected)
    "sigint": ("SIGINT to the runner", "franka", "sigint"),
    "sigterm": ("SIGTERM to the runner", "franka", "sigterm"),
    "query-gone": ("query_state gone, a press", "franka", "query-gone"),
    "query-restarted": ("query_state restarted, a press", "franka", "query-restarted"),
    "query-late": ("query_state 0.2 s late, a press", "franka", "query-late"),
    "six-positions": ("joint state of 6 positions", "franka", "six-positions"),
    "nan": ("joint state with a NaN", "franka", "nan"),
    "clock+2": ("runner's wall clock +2 s", "franka", "clock+2"),
    "clock-2": ("runner's wall clock -2 s", "franka", "clock-2"),
    "stale-braking": ("feed stale while braking", "franka", "stale-braking"),
    "braking-aborted": ("braking goal aborted", "franka", "braking-aborted"),
    "tracking-gap": ("tracked hand lost", "franka", "tracking-gap"),
    "sigterm-ur": ("SIGTERM, UR-like controller", "ur_like", "sigterm"),
    "query-late-ur": ("query_state 0.2 s late, UR-like", "ur_like", "query-late"),
}


def sweep_times(count: int) -> list[float]:
    """`count` press times spread evenly from FIRST_PRESS_S s into the approach to where LEFT_AT_PRESS m of it are
    left."""
    path = approach_path(load_scene(), PATH, STANDOFF, peak_speed=SPEED)
    arc = arc_length(path)
    last = float(path.times[np.searchsorted(arc, arc[-1] - LEFT_AT_PRESS)])
    return [float(t) for t in np.linspace(FIRST_PRESS_S, last, count)] if count > 1 else [FIRST_PRESS_S]


def peak_time() -> float:
    """s into the approach at its peak speed: a fault then brakes the arm from its fastest."""
    path = approach_path(load_scene(), PATH, STANDOFF, peak_speed=SPEED)
    return float(path.times[int(np.argmax(path.speeds))])


@dataclass(frozen=True)
class Row:
    name: str
    what: str
    sessions: list[Session]


def _percent(value: float) -> str:
    return f"{value * 100:.0f}"


def row_line(row: Row) -> str:
    trials = [trial for session in row.sessions for trial in session.trials]
    executed = [s.executed for s in row.sessions if s.executed is not None]
    leads = [lead for session in row.sessions for lead in session.leads]
    codes = ",".join(sorted({str(s.code) for s in row.sessions}))
    recorded = [t.recorded for t in trials if math.isfinite(t.recorded)]
    if not trials:
        said = "; ".join(s.said for s in row.sessions if s.said) or "no trial measured"
        return f"{row.what:<34} {len(row.sessions):>4}  no figures: {said}"
    acc = max(executed, key=lambda e: e.acceleration) if executed else None
    jerk = max(executed, key=lambda e: e.jerk) if executed else None
    lead = f"{np.median(leads):.1f}/{max(leads):.1f}" if leads else "none"
    stops = f"{sum(s.after_stamp for s in row.sessions)}/{sum(s.from_path for s in row.sessions)}"
    return (
        f"{row.what:<34} {len(trials):>4} {sum(t.braked for t in trials):>3}/{len(trials):<3} {codes:>7} "
        f"{min(t.short for t in trials) * 1e3:>8.1f} {min(t.least for t in trials) * 1e3:>9.1f} "
        f"{(min(recorded) * 1e3 if recorded else math.nan):>8.1f} "
        + (f"{_percent(acc.acceleration):>5} (j{acc.acceleration_joint})" if acc else f"{'-':>10}")
        + (f" {_percent(jerk.jerk):>5} (j{jerk.jerk_joint})" if jerk else f" {'-':>10}")
        + f" {lead:>11} {stops:>5}"
    )


HEADER = (
    f"{'fault':<34} {'runs':>4} {'braked':>7} {'exit':>7} {'short mm':>8} {'least mm':>9} {'runner':>8} "
    f"{'acc %':>10} {'jerk %':>10} {'lead ms':>11} {'late/':>5}\n"
    f"{'':<34} {'':>4} {'':>7} {'':>7} {'(min)':>8} {'(min)':>9} {'(min)':>8} {'(joint)':>10} {'(joint)':>10} "
    f"{'(med/max)':>11} {'path':>5}"
)


def verdict(rows: list[Row]) -> tuple[bool, str]:
    """Whether every run braked with its separation above the floor and every stop's run-on within its bound
    (bench.run_on), and one line saying so or what failed."""
    unbraked, under, over, unmeasured, ran_on, early = [], [], [], [], [], []
    for row in rows:
        trials = [trial for session in row.sessions for trial in session.trials]
        if not trials:
            unmeasured.append(row.name)
        acted = sum(session.acted for session in row.sessions)
        if trials and len(trials) < acted:  # e.g. a sweep's session the runner ended on its own (exit 5)
            codes = sorted({str(s.code) for s in row.sessions if len(s.trials) < s.acted})
            early.append(f"{row.name} ({len(trials)} of {acted} trials; exit {', '.join(codes)})")
        if any(not trial.braked for trial in trials):
            unbraked.append(f"{row.name} ({sum(not t.braked for t in trials)} of {len(trials)})")
        least = [t.least for t in trials] + [t.recorded for t in trials if math.isfinite(t.recorded)]
        if least and min(least) < FLOOR:
            under.append(f"{row.name} ({min(least) * 1e3:.1f} mm)")
        beyond = [t.run_on for t in trials if t.run_on is not None and not t.run_on.within]
        if beyond:
            worst = max(beyond, key=lambda r: r.value - r.bound)
            ran_on.append(f"{row.name} ({len(beyond)}; {worst.value * 1e3:.1f} mm of {worst.bound * 1e3:.1f})")
        for session in row.sessions:
            if session.whole is not None and max(session.whole.acceleration, session.whole.jerk) > 1.0:
                over.append(f"{row.name} ({session.whole.describe()})")
    failed = [
        *([f"not braked: {', '.join(unbraked)}"] if unbraked else []),
        *([f"separation under the {FLOOR * 1e3:g} mm floor: {', '.join(under)}"] if under else []),
        *([f"no figures: {', '.join(unmeasured)}"] if unmeasured else []),
        *([f"ended early: {', '.join(early)}"] if early else []),
        *([f"run-on over its bound: {', '.join(ran_on)}"] if ran_on else []),
    ]
    limits = (
        "executed acceleration and jerk within the Panda's limits"
        if not over
        else f"over the Panda's limits: {'; '.join(over)}"
    )
    if failed:
        return False, f"FAILED: {'; '.join(failed)}; {limits}"
    measured = sum(t.run_on is not None for row in rows for session in row.sessions for t in session.trials)
    return True, f"all faults braked; separation never under the floor; {measured} run-ons within their bound; {limits}"


def run(
    rospy: Any,
    env: dict[str, str],
    tmp: Path,
    presses: int,
    faults: list[str],
    runs: int,
    seconds: float,
    fault_at: float | None = None,
) -> bool:
    """The sweep of `presses` (0: none) and each of `faults` `runs` times, `fault_at` s into the approach (None: at
    its peak speed), within `seconds` (sessions not begun by then are left out, and said); the table printed.
    Whether every run braked above the floor."""
    fault_time = peak_time() if fault_at is None else fault_at
    bench = Bench(rospy, env, tmp)
    rows: list[Row] = []
    began = time.monotonic()
    try:
        print(
            f"\nFaults through the study's runner: the {PATH} approach to {STANDOFF * 100:g} cm at {SPEED:g} m/s on "
            f"the stand-in's controller (franka_ros's topics); braked: at rest {BRAKED_SHORT * 1e3:g} mm or more short "
            f"of the stand-off; the floor {FLOOR * 1e3:g} mm; limits: the Panda's published acceleration and jerk"
        )
        if presses > 0:
            times = sweep_times(presses)
            print(f"the sweep: {presses} presses in one session, at {', '.join(f'{t:.2f}' for t in times)} s")
            session = bench.session(Injection(press, trials=presses), times, "franka")
            rows.append(Row("presses", f"press (a sweep of {presses})", [session]))
            for pressed, trial in zip(times, session.trials):
                ran_on = trial.run_on
                said = f"{ran_on.value * 1e3:.1f} mm (bound {ran_on.bound * 1e3:.1f})" if ran_on else "not measured"
                print(
                    f"  press at {pressed:.2f} s: at rest {trial.short * 1e3:.1f} mm short of the stand-off, least "
                    f"separation {trial.least * 1e3:.1f} mm (the runner's {trial.recorded * 1e3:.1f} mm), run-on {said}"
                )
        if faults:
            peak = f"its peak speed {SPEED:g} m/s at {peak_time():.2f} s"
            print(f"the faults: each {fault_time:.2f} s into the approach ({peak})")
        for name in sorted(faults, key=lambda name: FAULTS[name][1]):  # each arm started once
            what, arm, fault = FAULTS[name]
            sessions = []
            for _ in range(runs):
                if time.monotonic() - began > seconds:
                    print(f"  {name}: left out, the bench's {seconds:g} s were spent")
                    break
                sessions.append(bench.session(bench.injection(fault), [fault_time], arm))
            rows.append(Row(name, what, sessions))
    finally:
        bench.close()
    print(HEADER)
    for row in rows:
        print(row_line(row))
    wholes = [session.whole for row in rows for session in row.sessions if session.whole is not None]
    if wholes:
        acc, jerk = max(wholes, key=lambda e: e.acceleration), max(wholes, key=lambda e: e.jerk)
        print(
            f"the whole sessions (the moves to the starts included): the largest executed acceleration "
            f"{_percent(acc.acceleration)}% of joint {acc.acceleration_joint}'s limit, jerk {_percent(jerk.jerk)}% of "
            f"joint {jerk.jerk_joint}'s"
        )
    print(
        "short: the rest short of the stand-off; least: the least separation from the scene's hand in the joint "
        "states heard while the motion ran (runner: its record's least_separation); acc, jerk: the largest executed "
        "from the approach acted on to the end, as a share of the limit; lead: each stop's, as the runner said it; "
        "late/path: stops sent after their stamp "
        "/ braked from the commanded path"
    )
    for row in rows:
        stops = [t.run_on for session in row.sessions for t in session.trials if t.run_on is not None]
        if stops:
            print(f"{row.what}: {distribution(stops)}")
    ok, line = verdict(rows)
    print(line)
    return ok
