"""The accuracy campaign: robots × use cases × trials of the commander's 40 s sweep, each recorded by a real
`rosbag record` into its own bag (CSV logs for the no-ROS cases), then analysed into a report with plots.

    python -m sim.trials --robots panda igt --trials 5 --out results/

Use cases (names as in the thesis):
  base                          endpoint + TCP engine, physics, auto-simulate (wall clock × time scale)
  no_ros                        engine CSV mode (no ROS, no TCP), physics
  ros_other_host                roscore + commander + rosbag, endpoint, engine in three network namespaces
                                joined by veth links (made and removed by the run; skipped where not permitted)
  no_joint_physics              as base, joints set kinematically (no_physics)
  infinite_stiffness            as base, infinite drive stiffness
  no_ros_no_physics             engine CSV mode, no_physics
  auto_simulate_off             endpoint + TCP engine stepping only as /clock advances (lockstep), physics
  auto_simulate_off_no_physics  as auto_simulate_off, no_physics
Wall-clock use cases run at `--time-scale` (default 5: the 40 s path in 8 s), commander and engine alike; lockstep
ones no faster (the commander's --lockstep-rate), so that `rosbag record` may fall as far behind in either.
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.campaign import analysis
from sim.control.scenarios import ScenarioConfig, build_motion
from sim.engine.physics import Mode
from sim.entry import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK, fail, log_to_stderr
from sim.errors import SimError
from sim.launchers import Commander, Engine, finish, start
from sim.processes import EndpointProcess, RosCore, pid_alive, plain_env, start_recorder, stop_recorder
from sim.robots import ROBOT_NAMES, RobotError, RobotSpec, add_robot_overrides, load_robot, overrides_from_args
from sim.wire.contract import STEP_S

__all__ = [
    "TCP",
    "CSV",
    "NETNS",
    "UseCase",
    "USE_CASES",
    "USE_CASE_NAMES",
    "TrialError",
    "TrialSkipped",
    "NETNS_HOSTS",
    "Namespaces",
    "network_hosts",
    "stale_namespaces",
    "Placement",
    "TrialPaths",
    "Campaign",
    "load_robots",
    "run_campaign",
    "main",
]

log = logging.getLogger(__name__)

TCP = "tcp"
CSV = "csv"
NETNS = "netns"


@dataclass(frozen=True)
class UseCase:
    name: str
    transport: str  # TCP | CSV | NETNS
    mode: Mode
    auto_simulate: bool
    description: str


USE_CASES: tuple[UseCase, ...] = (
    UseCase("base", TCP, Mode.PHYSICS, True, "endpoint + TCP engine, physics, auto-simulate"),
    UseCase("no_ros", CSV, Mode.PHYSICS, True, "engine CSV mode, no ROS/TCP, physics"),
    UseCase("ros_other_host", NETNS, Mode.PHYSICS, True, "ROS, endpoint and engine on three network hosts"),
    UseCase("no_joint_physics", TCP, Mode.NO_PHYSICS, True, "as base, kinematic joints"),
    UseCase("infinite_stiffness", TCP, Mode.INFINITE_STIFFNESS, True, "as base, infinite drive stiffness"),
    UseCase("no_ros_no_physics", CSV, Mode.NO_PHYSICS, True, "engine CSV mode, kinematic joints"),
    UseCase("auto_simulate_off", TCP, Mode.PHYSICS, False, "engine steps as /clock advances, physics"),
    UseCase("auto_simulate_off_no_physics", TCP, Mode.NO_PHYSICS, False, "as auto_simulate_off, kinematic"),
)
USE_CASE_NAMES = tuple(case.name for case in USE_CASES)


class TrialError(SimError, RuntimeError):
    """A trial that could not run (a process failed, a bag is missing); the message says which and why."""


class TrialSkipped(SimError):
    """A use case this machine cannot run (e.g. network namespaces not permitted)."""


# --- network hosts ---------------------------------------------------------------------------------------------
# 198.18.0.0/15 is reserved for network test beds (RFC 2544): nothing outside these namespaces uses it.
NETNS_HOSTS = {
    "ros": "198.18.71.1",
    "bridge": "198.18.71.2",
    "bridge_engine_side": "198.18.72.1",
    "engine": "198.18.72.2",
}


@dataclass(frozen=True)
class Namespaces:
    ros: str
    bridge: str
    engine: str

    def prefix(self, namespace: str) -> list[str]:
        return ["ip", "netns", "exec", namespace]


def _ip(*args: str) -> None:
    result = subprocess.run(["ip", *args], capture_output=True, text=True)
    if result.returncode != 0:
        raise TrialSkipped(f"'ip {' '.join(args)}' failed: {result.stderr.strip()}")


def stale_namespaces(tag: str, listed: str, alive: Callable[[int], bool] = pid_alive) -> list[str]:
    """Of `ip netns list`'s output, the namespaces network_hosts(tag) made in a process that is gone: killed before
    its clean-up ran, they stay until deleted."""
    pattern = re.compile(rf"vrt_{re.escape(tag)}_(\d+)_(?:ros|bridge|engine)")
    stale = []
    for line in listed.splitlines():
        name = line.split(" ", 1)[0]
        match = pattern.fullmatch(name)
        if match and not alive(int(match.group(1))):
            stale.append(name)
    return stale


@contextmanager
def network_hosts(tag: str) -> Iterator[Namespaces]:
    """Three namespaces (ros — bridge — engine) linked by two veth pairs; removed on exit, whatever happens. Named by
    this process, so that another run's never stand in the way (two at once, or one killed before its clean-up: its
    namespaces, and their /etc/netns folders, are removed here)."""
    if shutil.which("ip") is None:
        raise TrialSkipped("the 'ip' command (iproute2) is not installed")
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    for namespace in stale_namespaces(tag, listed):
        subprocess.run(["ip", "netns", "delete", namespace], capture_output=True)
        shutil.rmtree(Path("/etc/netns") / namespace, ignore_errors=True)
    owner = os.getpid()
    spaces = Namespaces(f"vrt_{tag}_{owner}_ros", f"vrt_{tag}_{owner}_bridge", f"vrt_{tag}_{owner}_engine")
    made: list[str] = []
    try:
        for namespace in (spaces.ros, spaces.bridge, spaces.engine):
            _ip("netns", "add", namespace)
            made.append(namespace)
            _ip("-n", namespace, "link", "set", "lo", "up")
        links = (
            (spaces.ros, f"vr{tag}r0", NETNS_HOSTS["ros"], spaces.bridge, f"vr{tag}b0", NETNS_HOSTS["bridge"]),
            (
                spaces.bridge,
                f"vr{tag}b1",
                NETNS_HOSTS["bridge_engine_side"],
                spaces.engine,
                f"vr{tag}e0",
                NETNS_HOSTS["engine"],
            ),
        )
        for ns_a, dev_a, addr_a, ns_b, dev_b, addr_b in links:
            _ip("link", "add", dev_a, "netns", ns_a, "type", "veth", "peer", "name", dev_b, "netns", ns_b)
            _ip("-n", ns_a, "addr", "add", f"{addr_a}/24", "dev", dev_a)
            _ip("-n", ns_b, "addr", "add", f"{addr_b}/24", "dev", dev_b)
            _ip("-n", ns_a, "link", "set", dev_a, "up")
            _ip("-n", ns_b, "link", "set", dev_b, "up")
        yield spaces
    finally:
        for namespace in reversed(made):  # deleting a namespace deletes its veth ends too
            subprocess.run(["ip", "netns", "delete", namespace], capture_output=True)


# --- one trial -------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Placement:
    """Where a trial's ROS processes run: roscore's host (commander, rosbag), the endpoint's, the engine's.
    On one machine the prefixes are empty; across network namespaces they are `ip netns exec NAME`."""

    ros_env: dict[str, str]
    bridge_env: dict[str, str]
    endpoint_host: str  # the endpoint's address as the engine reaches it
    ros_prefix: Sequence[str] = ()
    bridge_prefix: Sequence[str] = ()
    engine_prefix: Sequence[str] = ()


@dataclass
class TrialPaths:
    bag: Path
    commander_log: Path
    desired_csv: Path
    achieved_csv: Path
    process_logs: Path


class Campaign:
    def __init__(self, out_dir: Path, time_scale: float = 5.0, timeout_s: float = 180.0) -> None:
        self.out_dir = out_dir
        self.time_scale = time_scale
        self.timeout_s = timeout_s
        self._roscore: RosCore | None = None

    def paths(self, robot: RobotSpec, case: UseCase, trial: int, scenario: str = "sweep") -> TrialPaths:
        stem = (
            f"{robot.name}_{case.name}_{trial}"
            if scenario == "sweep"
            else f"{robot.name}_{case.name}_{scenario}_{trial}"
        )
        return TrialPaths(
            bag=self.out_dir / "bags" / f"{stem}.bag",
            commander_log=self.out_dir / "commander" / f"{stem}.csv",
            desired_csv=self.out_dir / "csv" / f"{stem}_desired.csv",
            achieved_csv=self.out_dir / "csv" / f"{stem}_achieved.csv",
            process_logs=self.out_dir / "logs",
        )

    def close(self) -> None:
        if self._roscore is not None:
            self._roscore.stop()
            self._roscore = None

    def roscore(self) -> RosCore:
        if self._roscore is None:
            self._roscore = RosCore(tmp=self._ros_logs("ros"))
        return self._roscore

    def _ros_logs(self, name: str) -> Path:
        """A roscore's own dir (its ROS_HOME and ROS_LOG_DIR: the master's log of every registration, and every
        node's log), kept with the campaign's process logs: a trial that fails can be read afterwards."""
        path = self.out_dir / "logs" / name
        path.mkdir(parents=True, exist_ok=True)
        return path

    def run_trial(
        self, robot: RobotSpec, case: UseCase, trial: int, scenario: Sequence[str] = ("sweep",)
    ) -> analysis.TrialResult:
        """One run of the commander's `scenario` (name and options) under `case`, recorded and analysed."""
        paths = self.paths(robot, case, trial, scenario[0])
        if case.transport == CSV:
            series = self._run_csv(robot, case, paths)
        elif case.transport == TCP:
            env = self.roscore().env
            self._run_ros(robot, case, paths, Placement(env, env, "127.0.0.1"), scenario)
            series = self._scenario_part(paths, robot)
        else:
            with network_hosts(f"{trial}{robot.name[0]}") as spaces, ExitStack() as stack:
                core = RosCore(
                    host=NETNS_HOSTS["ros"],
                    prefix=spaces.prefix(spaces.ros),
                    tmp=self._ros_logs(f"ros_{paths.bag.stem}"),
                )
                stack.callback(core.stop)
                placement = Placement(
                    ros_env=core.env,
                    bridge_env=dict(core.env, ROS_HOSTNAME=NETNS_HOSTS["bridge"]),
                    endpoint_host=NETNS_HOSTS["bridge_engine_side"],
                    ros_prefix=spaces.prefix(spaces.ros),
                    bridge_prefix=spaces.prefix(spaces.bridge),
                    engine_prefix=spaces.prefix(spaces.engine),
                )
                self._run_ros(robot, case, paths, placement, scenario)
            series = self._scenario_part(paths, robot)
        return analysis.TrialResult(
            robot.name, case.name, trial, analysis.trial_metrics(series, STEP_S), series.lost_messages, series
        )

    @staticmethod
    def _scenario_part(paths: TrialPaths, robot: RobotSpec) -> analysis.TrialSeries:
        """The bag's series from the scenario's start on: the commander's approach to it is left out, as in the
        commander's own metrics (CSV use cases export the scenario alone)."""
        series = analysis.read_bag(paths.bag, robot)
        return analysis.without_approach(series, analysis.scenario_start(paths.commander_log))

    def _run_csv(self, robot: RobotSpec, case: UseCase, paths: TrialPaths) -> analysis.TrialSeries:
        logs = paths.process_logs
        export = Commander(robot.cli_args, ["sweep"], STEP_S, export_csv=paths.desired_csv, export_only=True)
        finish(start(export, plain_env(), logs, "commander"), self.timeout_s)
        replay = Engine(robot.cli_args, STEP_S, mode=case.mode.value, csv=paths.desired_csv, log=paths.achieved_csv)
        finish(start(replay, plain_env(), logs, "engine"), self.timeout_s)
        return analysis.read_csv_pair(paths.desired_csv, paths.achieved_csv, robot)

    def _run_ros(
        self, robot: RobotSpec, case: UseCase, paths: TrialPaths, where: Placement, scenario: Sequence[str]
    ) -> None:
        logs = paths.process_logs
        topics = [robot.command_topic, robot.joint_states_topic, "/clock", robot.pose_topic]
        wall_clock = self.time_scale if case.auto_simulate else None
        # rosbag record keeps 100 messages per topic and drops the oldest past them. Lockstep unpaced (some 1000
        # steps a second) lost 19 commands and clocks to one stall of the recorder's callbacks, 0.12 s long, on a
        # loaded machine. At the wall-clock use cases' rate (time_scale / dt: 250 a second by default) the
        # recorder may fall 0.4 s behind without losing one.
        lockstep_rate = None if case.auto_simulate else self.time_scale / STEP_S
        with ExitStack() as running:
            endpoint = EndpointProcess(where.bridge_env, logs, host=where.endpoint_host, prefix=where.bridge_prefix)
            running.callback(endpoint.stop)
            recorder = start_recorder(paths.bag, topics, "trial_recorder", where.ros_env, logs, where.ros_prefix)
            running.callback(lambda: stop_recorder(recorder, paths.bag))
            engine = Engine(
                robot.cli_args,
                STEP_S,
                port=endpoint.port,
                host=where.endpoint_host,
                mode=case.mode.value,
                auto_simulate=case.auto_simulate,
                time_scale=wall_clock,
            )
            running.callback(start(engine, plain_env(), logs, "engine", where.engine_prefix).stop)
            recorder.wait_for_output("Recording to", timeout=30)
            commander = Commander(
                robot.cli_args,
                scenario,
                STEP_S,
                log=paths.commander_log,
                wait_for=("trial_recorder",),
                timeout=30,
                realtime=case.auto_simulate,
                time_scale=wall_clock,
                lockstep_rate=lockstep_rate,
            )
            process = start(commander, where.ros_env, logs, "commander", where.ros_prefix)
            running.callback(process.stop)
            finish(process, self.timeout_s)
        if not paths.bag.exists():
            raise TrialError(f"rosbag record left no {paths.bag}; see {recorder.log_path}")


# --- campaign --------------------------------------------------------------------------------------------------


def load_robots(references: Sequence[str], overrides: Mapping[str, Any] | None = None) -> list[RobotSpec]:
    """The campaign's robots (names or URDF/YAML paths); their names key bags and reports, so they must differ.
    `overrides` (load_robot's keywords, from the command line) are for a campaign of one robot: several robots each
    keep theirs in a YAML beside the URDF."""
    if overrides and len(references) > 1:
        options = ", ".join(f"--{key.replace('_', '-')}" for key in overrides)
        raise RobotError(
            f"{options} {'applies' if len(overrides) == 1 else 'apply'} to one robot, and {len(references)} are "
            "given; put each robot's overrides in a YAML "
            "beside its URDF (arm.urdf -> arm.yaml: ee_link, base_link, name, home)"
        )
    specs = [load_robot(reference, **(overrides or {})) for reference in references]
    names = [spec.name for spec in specs]
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise RobotError(
            f"two robots are named {', '.join(twice)}; give one another name in a robot YAML beside its URDF"
        )
    return specs


def run_campaign(
    robots: Sequence[RobotSpec], use_cases: Sequence[str], trials: int, out_dir: Path, time_scale: float, progress: bool
) -> tuple[list[analysis.TrialResult], list[str]]:
    from tqdm import tqdm

    cases = [next(case for case in USE_CASES if case.name == name) for name in use_cases]
    plan = [(robot, case, trial) for robot in robots for case in cases for trial in range(1, trials + 1)]
    campaign = Campaign(out_dir, time_scale)
    results: list[analysis.TrialResult] = []
    skipped: dict[tuple[str, str], str] = {}  # (robot, use case) -> why
    try:
        for robot, case, trial in tqdm(plan, desc="trials", unit="trial", disable=not progress):
            if (robot.name, case.name) in skipped:
                continue
            try:
                results.append(campaign.run_trial(robot, case, trial))
            except TrialSkipped as why:
                skipped[(robot.name, case.name)] = str(why)
    finally:
        campaign.close()
    return results, [f"{robot}/{case}: skipped, {why}" for (robot, case), why in skipped.items()]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m sim.trials", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--robots",
        nargs="+",
        default=list(ROBOT_NAMES),
        metavar="ROBOT",
        help=f"names ({', '.join(ROBOT_NAMES)}) or URDF / robot YAML paths (default: all names)",
    )
    add_robot_overrides(parser.add_argument_group("overrides of a single robot (as every command takes them)"))
    parser.add_argument("--use-cases", nargs="+", default=list(USE_CASE_NAMES), choices=USE_CASE_NAMES)
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument("--out", type=Path, default=Path("results"))
    parser.add_argument("--time-scale", type=float, default=5.0, help="speed-up of the wall-clock use cases")
    parser.add_argument("--no-progress", action="store_true")
    return parser


PROG = "sim.trials"


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    log_to_stderr()
    if args.trials < 1 or args.time_scale <= 0:
        return fail(PROG, "--trials must be >= 1 and --time-scale > 0", EXIT_BAD_INPUT)
    try:
        robots = load_robots(args.robots, overrides_from_args(args))
        for robot in robots:  # a robot whose sweep cannot be built is bad input, found before anything runs
            build_motion(robot, "sweep", ScenarioConfig(dt=STEP_S))
    except SimError as error:
        return fail(PROG, error, EXIT_BAD_INPUT)
    out = args.out.resolve()  # the processes it starts (rosbag, commander) run in folders of their own
    started = time.monotonic()
    try:
        results, skipped = run_campaign(
            robots, args.use_cases, args.trials, out, args.time_scale, progress=not args.no_progress
        )
    except (SimError, TimeoutError) as error:
        return fail(PROG, error, EXIT_FAILED)
    report = analysis.write_report(results, out, title="Tracking accuracy per use case")
    print(analysis.markdown_table(analysis.summary_rows(results)))
    print("Per robot and use case, its worst moving joint (mean over trials):\n")
    print(analysis.markdown_table(analysis.worst_joint_rows(results)))
    for line in skipped:
        print(line)
    lost = sum(result.lost_messages for result in results)
    print(f"{len(results)} trials in {time.monotonic() - started:.0f} s; messages lost: {lost}")
    print(f"report: {report.resolve()}")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
