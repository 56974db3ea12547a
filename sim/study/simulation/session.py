"""The whole study with simulated participants, end to end (`python -m sim.study simulate --participants 12 --out
DIR`): its own roscore and endpoint; per participant a session plan, the engine stand-in (physics, lockstep), a
simulated participant (TCP client of the endpoint) and the runner (rospy node, rosbag record); then the report.
Every process it starts is stopped by PID, whatever happens.
"""

from __future__ import annotations

import time
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import yaml

from sim.launchers import Engine, Participant, Runner, finish, start, wait_ready
from sim.processes import EndpointProcess, ManagedProcess, ProcessError, RosCore, plain_env
from sim.study.analysis.questionnaires import load_questionnaires, summarise_questionnaires
from sim.study.analysis.report import load_study, write_report
from sim.study.analysis.trackers import load_trackers, summarise_trackers
from sim.study.design.feasibility import plan_combinations, remedies
from sim.study.design.fit import scene_for, scene_to_data
from sim.study.design.plan import make_plan, plan_to_data
from sim.study.design.progress import progress_bar
from sim.study.design.scene import scaling_note
from sim.study.design.spec import load_design
from sim.study.errors import StudyError
from sim.study.participants.model import KNOWN_TRUTHS, Population
from sim.study.simulation.errors import SimulationError
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


def _finish(process: ManagedProcess, timeout: float) -> str:
    try:
        return finish(process, timeout)
    except ProcessError as error:
        raise SimulationError(str(error)) from None


def simulate(settings: Simulation, log: Callable[[str], None]) -> Path:
    """Run the study and write its report; the report's path. StudyError on bad input, before anything starts."""
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
    logs = out / "logs"
    # Every process of the study is handed the scene as chosen here (given, bundled or proposed for the robot)
    scene_path = out / "scene.yaml"
    scene_path.parent.mkdir(parents=True, exist_ok=True)
    scene_path.write_text(yaml.safe_dump(scene_to_data(scene), sort_keys=False))
    scene_and_robot = ["--scene", str(scene_path)]
    truths = [f"--{name.replace('_', '-')}={getattr(settings.population, name)!r}" for name in KNOWN_TRUTHS]
    scene_and_robot += robot.cli_args  # every process of the study takes the robot, with its overrides, as chosen here
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
                engine = Engine(robot.cli_args, settings.dt, port=port, auto_simulate=False)
                participant = Participant(number, settings.seed, port, scene_and_robot, settings.dt, truths)
                engine_process = start(engine, plain_env(), logs, "engine", wait=False)
                session.callback(engine_process.stop)
                answering = start(participant, plain_env(), logs, f"participant_{number:02d}", wait=False)
                session.callback(answering.stop)
                wait_ready(engine_process, engine)
                wait_ready(answering, participant)
                runner = Runner(plan_path, out, scene_and_robot, settings.dt, extra=SIMULATED_POSE_SOURCES)
                running_session = start(runner, core.env, logs, f"runner_{number:02d}")
                session.callback(running_session.stop)
                summary = _finish(running_session, settings.timeout)
                _finish(answering, 60)
            line = next((line for line in summary.splitlines() if line.startswith(f"participant {number}:")), "")
            log(line or f"participant {number}: done")
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
