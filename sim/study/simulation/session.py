"""The whole study with simulated participants, end to end (`python -m sim.study simulate --participants 12 --out
DIR`): its own roscore and endpoint; per participant a session plan, the engine stand-in (physics, lockstep), a
simulated participant (TCP client of the endpoint) and the runner (rospy node, rosbag record unless --no-record);
then the report, from the sessions' CSVs.
Every process it starts is stopped by PID, whatever happens.

While a session runs, every part of it is watched, not the runner alone: a part that fails (the participant, the
engine, the runner, or roscore or the endpoint ending at all) ends the study at once with a SimulationError naming
the part and its own error line (sim.study.simulation.failures), rather than the runner waiting out its response
timeout for an answer a failed participant will never give.
"""

from __future__ import annotations

import time
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import yaml

from sim.launchers import Engine, Participant, Runner, finish, start, wait_ready
from sim.processes import EndpointProcess, ManagedProcess, ProcessError, RosCore, plain_env
from sim.study.analysis.questionnaires import load_questionnaires, summarise_questionnaires
from sim.study.analysis.report import load_study, write_report
from sim.study.analysis.trackers import load_trackers, summarise_trackers
from sim.study.checks import check_fault_trial
from sim.study.design.feasibility import plan_combinations, remedies
from sim.study.design.fit import scene_for
from sim.study.design.plan import SessionPlan, make_plan, plan_to_data
from sim.study.design.progress import progress_bar
from sim.study.design.scene import scaling_note, scene_to_data
from sim.study.design.spec import load_design
from sim.study.errors import StudyError
from sim.study.participants.model import KNOWN_TRUTHS, Population
from sim.study.simulation.errors import SimulationError
from sim.study.simulation.failures import failed_line, one_line
from sim.wire.contract import STEP_S

__all__ = ["Simulation", "simulate"]

# The simulated participants send their own poses in both conditions: one pose source, named for the report
SIMULATED_POSE_SOURCES = ("--pose-source", "vr=simulated participant", "--pose-source", "reality=simulated participant")


@dataclass(frozen=True)
class Simulation:
    participants: int
    seed: int
    out: Path
    design: Path | None = None
    scene: Path | None = None
    dt: float = STEP_S
    population: Population = Population()  # the simulated participants' known truths
    timeout: float = 600.0  # s per participant's session
    robot: str | None = None  # --robot: in the scene's place
    robot_overrides: Mapping[str, Any] = field(default_factory=dict)  # load_robot's keywords from the command line
    fault_trial: int | None = None  # tests only: every participant's fault (participant --fault-trial)
    record: bool = True  # each session's rosbag record (the runner's); the report reads the CSVs alone


_POLL = 0.05  # s between looks at a session's parts


def _finish(process: ManagedProcess, timeout: float) -> str:
    try:
        return finish(process, timeout)
    except ProcessError as error:
        raise SimulationError(one_line(str(error))) from None


def _await_runner(runner: ManagedProcess, parts: list[tuple[ManagedProcess, bool]], timeout: float) -> str:
    """The runner's output once it has ended well. SimulationError at once when a part fails first: one that ends
    with an error, or at all where it may not end before the runner (its flag False), or the runner itself."""
    deadline = time.monotonic() + timeout
    while True:
        for part, may_end in parts:  # before the runner's own code: a runner that failed mostly waited for a part
            code = part.process.poll()
            if code is not None and not (may_end and code == 0):
                raise SimulationError(failed_line(part.name, code, part.output(), part.log_path))
        code = runner.process.poll()
        if code is not None:
            if code != 0:
                raise SimulationError(failed_line(runner.name, code, runner.output(), runner.log_path))
            return runner.output()
        if time.monotonic() > deadline:
            raise SimulationError(f"{runner.name} still running after {timeout:g} s; its log: {runner.log_path}")
        time.sleep(_POLL)


def simulate(settings: Simulation, log: Callable[[str], None]) -> Path:
    """Run the study and write its report; the report's path. StudyError on bad input, before anything starts."""
    check_fault_trial(settings.fault_trial)
    if not (isinstance(settings.participants, int) and 2 <= settings.participants <= 200):
        raise StudyError(f"--participants must be 2..200 (the analysis pairs them), got {settings.participants}")
    earlier = sorted(settings.out.glob("participant_*.csv"))
    if earlier:  # the report would mix them in, and they may be a real study's: never overwritten
        raise StudyError(
            f"{settings.out} already holds participant records ({earlier[0].name}, ...): choose a new directory"
        )
    design = load_design(settings.design)
    with progress_bar("scenes tried for the arm", "scene") as progress:  # on a terminal
        scene, robot = scene_for(settings.scene, settings.robot, settings.robot_overrides, progress)
    plans = [make_plan(design, participant, settings.seed) for participant in range(1, settings.participants + 1)]
    started = time.monotonic()
    approaches = plan_combinations(
        robot, scene, [(t.path, t.standoff, t.peak_speed) for t in plans[0].trials], settings.dt
    )
    infeasible = [
        f"{p} to {s} m at {v} m/s: {'; '.join(a.problems)}" for (p, s, v), a in approaches.items() if not a.feasible
    ]
    if infeasible:
        fixes = remedies(approach for approach in approaches.values() if not approach.feasible)
        raise StudyError(
            f"the design has combinations that are not feasible: {' | '.join(infeasible)}; to change: {fixes}"
        )
    log(f"{len(approaches)} combinations of the design planned and checked in {time.monotonic() - started:.1f} s")
    out = settings.out.resolve()
    # Every process of the study is handed the scene as chosen here (given, bundled or proposed for the robot)
    scene_path = out / "scene.yaml"
    scene_path.parent.mkdir(parents=True, exist_ok=True)
    scene_path.write_text(yaml.safe_dump(scene_to_data(scene), sort_keys=False))
    scene_and_robot = ["--scene", str(scene_path)]
    truths = [f"--{name.replace('_', '-')}={getattr(settings.population, name)!r}" for name in KNOWN_TRUTHS]
    scene_and_robot += robot.cli_args  # every process of the study takes the robot, with its overrides, as chosen here
    try:
        _run_sessions(settings, plans, out, scene_and_robot, truths, robot.cli_args, log)
    except ProcessError as error:  # a part that did not start (roscore, the endpoint, one not ready): not bad input
        raise SimulationError(one_line(str(error))) from None
    records = load_study(out)
    return write_report(
        records,
        out,
        f"Perception study, {settings.participants} simulated participants (seed {settings.seed})",
        design.sesoi,
        summarise_questionnaires(load_questionnaires(out)),
        summarise_trackers(load_trackers(out)),
        [f"The scene for {robot.name}: {scaling_note(scene)}."] if scaling_note(scene) else [],
    )


def _run_sessions(
    settings: Simulation,
    plans: list[SessionPlan],
    out: Path,
    scene_and_robot: list[str],
    truths: list[str],
    robot_args: Sequence[str],
    log: Callable[[str], None],
) -> None:
    """Every participant's session in turn, in a roscore and endpoint of their own (module doc)."""
    logs = out / "logs"
    fault = [] if settings.fault_trial is None else ["--fault-trial", str(settings.fault_trial)]
    with ExitStack() as running:
        core = RosCore()
        running.callback(core.stop)
        endpoint = EndpointProcess(core.env, logs, host="127.0.0.1")
        running.callback(endpoint.stop)
        port = endpoint.port
        log(f"roscore {core.uri}, endpoint on port {port}")
        for plan in plans:
            number = plan.participant
            plan_path = out / "plans" / f"participant_{number:02d}.yaml"
            plan_path.parent.mkdir(parents=True, exist_ok=True)
            plan_path.write_text(yaml.safe_dump(plan_to_data(plan), sort_keys=False))
            with ExitStack() as session:  # the engine and the participant start side by side
                engine = Engine(robot_args, settings.dt, port=port, auto_simulate=False)
                participant = Participant(number, settings.seed, port, scene_and_robot, settings.dt, truths, fault)
                engine_process = start(engine, plain_env(), logs, "engine", wait=False)
                session.callback(engine_process.stop)
                answering = start(participant, plain_env(), logs, f"participant_{number:02d}", wait=False)
                session.callback(answering.stop)
                wait_ready(engine_process, engine)
                wait_ready(answering, participant)
                runner = Runner(
                    plan_path, out, scene_and_robot, settings.dt, record=settings.record, extra=SIMULATED_POSE_SOURCES
                )
                running_session = start(runner, core.env, logs, f"runner_{number:02d}")
                session.callback(running_session.stop)
                parts = [(core, False), (endpoint, False), (engine_process, False), (answering, True)]
                summary = _await_runner(running_session, parts, settings.timeout)
                _finish(answering, 60)
            line = next((line for line in summary.splitlines() if line.startswith(f"participant {number}:")), "")
            log(line or f"participant {number}: done")
