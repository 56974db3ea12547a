"""`python -m sim.study plan` (a participant's session plan), `check` (every combination of the design planned
and checked) and `scene` (a scene proposed for the robot)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from sim.entry import EXIT_OK
from sim.robots import RobotSpec, overrides_from_args
from sim.study.checks import check_positive
from sim.study.design.errors import DesignError
from sim.study.design.options import add_design_option, add_scene_options, scene_and_robot
from sim.study.design.plan import make_plan, plan_to_data, printable
from sim.study.design.scene import DEFAULT_SCENE, load_scene, scaling_note, scene_robot
from sim.study.design.spec import load_design

if TYPE_CHECKING:
    from sim.study.design.feasibility import Combination, PlannedApproach

__all__ = ["register", "checked_combinations"]


def register(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    plan = commands.add_parser("plan", help="a participant's session plan")
    plan.add_argument("--participant", type=int, required=True)
    plan.add_argument("--seed", type=int, required=True)
    add_design_option(plan)
    plan.add_argument("--out", type=Path, help="write the plan here (default: print it as YAML)")
    plan.add_argument("--print", action="store_true", help="print the observer's table instead of YAML")
    plan.set_defaults(handler=plan_command)

    check = commands.add_parser("check", help="plan and check every combination of the design")
    add_design_option(check)
    add_scene_options(check)
    check.set_defaults(handler=check_command)

    scene = commands.add_parser("scene", help="propose a scene that fits the robot, checked like check")
    add_design_option(scene)
    add_scene_options(scene)
    scene.add_argument("--out", type=Path, help="write the scene here (default: print it as YAML)")
    scene.set_defaults(handler=scene_command)


def plan_command(args: argparse.Namespace) -> int:
    plan = make_plan(load_design(args.design), args.participant, args.seed)
    text = printable(plan) if args.print else yaml.safe_dump(plan_to_data(plan), sort_keys=False)
    if args.out is None:
        print(text, end="")
    else:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
        print(
            f"plan of participant {plan.participant}: {len(plan.trials)} trials, {' then '.join(plan.conditions)}"
            f" -> {args.out}"
        )
    return EXIT_OK


def check_command(args: argparse.Namespace) -> int:
    checked_combinations(args)
    return EXIT_OK


def checked_combinations(args: argparse.Namespace) -> tuple[RobotSpec, dict[Combination, PlannedApproach]]:
    """Every combination of the design planned, printed as a table; DesignError when one is not feasible. The robot
    and the approaches, for checks above the design's (sim.study.safety's `check --safety`)."""
    from sim.study.design.feasibility import CONSTRAINTS, plan_combinations, remedies

    check_positive(args.dt, "--dt")
    design = load_design(args.design)
    scene, robot = scene_and_robot(args)
    plan = make_plan(design, 1, 0)
    started = time.monotonic()
    approaches = plan_combinations(robot, scene, [(t.path, t.standoff, t.peak_speed) for t in plan.trials], args.dt)
    elapsed = time.monotonic() - started
    if scaling_note(scene):
        print(f"{robot.name}: {scaling_note(scene)}")
    print("| path | stand-off | peak speed | samples | duration | clearance table / hand | IK kept | verdict |")
    print("|---|---|---|---|---|---|---|---|")
    for (path, standoff, speed), planned in approaches.items():
        clearance = planned.min_clearance
        verdict = "feasible" if planned.feasible else "; ".join(planned.problems)
        print(
            f"| {path} | {standoff:.3f} m | {speed:.2f} m/s | {len(planned.path.times)} | "
            f"{planned.path.duration:.2f} s | {clearance['table'] * 1000:.0f} / {clearance['hand'] * 1000:.0f} mm | "
            f"{CONSTRAINTS[planned.constraints]} | {verdict} |"
        )
    print(f"{len(approaches)} combinations planned in {elapsed:.1f} s")
    infeasible = [key for key, planned in approaches.items() if not planned.feasible]
    if infeasible:
        raise DesignError(
            f"{len(infeasible)} combination(s) of the design are not feasible: "
            f"{', '.join(f'{p} to {s} m at {v} m/s' for p, s, v in infeasible)}; to change: "
            + remedies(approaches[key] for key in infeasible)
        )
    return robot, approaches


def scene_command(args: argparse.Namespace) -> int:
    """The first candidate scene that fits (sim.study.design.fit), each tried printed with why not."""
    from sim.study.design.fit import design_combinations, fit_scene, keep, no_fit_message
    from sim.study.design.scene import scene_to_data

    check_positive(args.dt, "--dt")
    template = load_scene(args.scene)
    robot = scene_robot(template, args.robot, overrides_from_args(args))
    combinations = design_combinations(load_design(args.design))
    fit = fit_scene(
        robot, template, combinations, args.dt, progress=lambda _done, _total, line: print(f"tried {line}", flush=True)
    )
    if fit.scene is None:
        raise DesignError(no_fit_message(robot, fit))
    template_text = (args.scene or DEFAULT_SCENE).read_text(encoding="utf-8")
    keep(fit.scene, robot, template_text, combinations, args.dt)  # what a command given this --robot then uses
    chosen = fit.tried[-1]
    header = (
        f"# The study's scene for {robot.name}, proposed by python -m sim.study scene: its reach is "
        f"{fit.proportions.reach:.2f} m from its shoulder, {fit.proportions.shoulder[2]:.2f} m above its base;\n"
        f"# {chosen.label}. Every combination of the design ({len(combinations)}) was planned and checked in it.\n"
        + (f"# {scaling_note(fit.scene).capitalize()}.\n" if scaling_note(fit.scene) else "")
    )
    text = header + yaml.safe_dump(scene_to_data(fit.scene), sort_keys=False)
    if args.out is None:
        print(text, end="")
    else:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
        print(f"scene for {robot.name}: {chosen.label} -> {args.out}")
    return EXIT_OK
