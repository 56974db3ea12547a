"""`python -m sim.study simulate`: the whole study with simulated participants, end to end."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from sim.entry import EXIT_FAILED, EXIT_OK, fail
from sim.robots import overrides_from_args
from sim.study.checks import check_positive
from sim.study.design.options import add_design_option, add_scene_options
from sim.study.errors import StudyError
from sim.study.participants.cli import add_fault_option, add_population_options, population_from_args

__all__ = ["register"]


def register(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    simulate = commands.add_parser("simulate", help="the whole study with simulated participants, end to end")
    simulate.add_argument("--participants", type=int, default=12)
    simulate.add_argument("--out", type=Path, required=True, help="plans, CSVs, bags, logs, report.md and plots")
    simulate.add_argument("--seed", type=int, default=1)
    simulate.add_argument(
        "--no-record", action="store_true", help="no rosbag record: the sessions' CSVs and the report only"
    )
    add_design_option(simulate)
    add_scene_options(simulate)
    add_population_options(simulate)
    add_fault_option(simulate)  # tests only: handed to every simulated participant
    simulate.set_defaults(handler=simulate_command)


def simulate_command(args: argparse.Namespace) -> int:
    from sim.study.simulation.errors import SimulationError
    from sim.study.simulation.session import Simulation, simulate

    check_positive(args.dt, "--dt")
    if args.seed < 0:
        raise StudyError(f"--seed must be >= 0, got {args.seed}")
    started = time.monotonic()
    settings = Simulation(
        args.participants,
        args.seed,
        args.out,
        args.design,
        args.scene,
        args.dt,
        population_from_args(args),
        robot=args.robot,
        robot_overrides=overrides_from_args(args),
        fault_trial=args.fault_trial,
        record=not args.no_record,
    )
    try:
        report = simulate(settings, lambda line: print(f"simulate: {line}", flush=True))
    except SimulationError as error:
        return fail("sim.study simulate", error, EXIT_FAILED)
    print(report.read_text(), end="")
    print(f"simulate: {args.participants} participants in {time.monotonic() - started:.0f} s; report: {report}")
    return EXIT_OK
