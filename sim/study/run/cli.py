"""`python -m sim.study run`: the runner node executes a participant's plan (ROS)."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from sim.study.checks import check_positive
from sim.study.design.options import add_scene_options, scene_and_robot
from sim.study.design.plan import plan_from_data
from sim.study.design.yamlfile import read_yaml
from sim.study.run.errors import RunError
from sim.study.safety.limits import DEFAULT_MARGIN

if TYPE_CHECKING:
    from sim.robots import RobotSpec
    from sim.study.design.feasibility import PlannedApproach
    from sim.study.design.plan import SessionPlan
    from sim.study.run.links.specs import TrajectoryLinkSpec

__all__ = ["register", "UNCHECKED"]

UNCHECKED = "--unchecked-limits-stand-in-only"  # loud on purpose: it lets a real arm move beyond its limits


def register(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    run = commands.add_parser("run", help="the runner node: execute a plan")
    run.add_argument("--plan", type=Path, required=True)
    run.add_argument("--out", type=Path, required=True, help="the participant's CSV, bag and logs go here")
    add_scene_options(run)
    run.add_argument("--realtime", action="store_true", help="pace by the wall clock (VR headset, real robot)")
    run.add_argument("--auto-go", action="store_true", help="start each approach at once, without waiting for go")
    run.add_argument(
        "--keyboard",
        action="store_true",
        help="the observer types here: Enter = go, s = stop, distances and preferences when asked",
    )
    run.add_argument("--no-record", action="store_true", help="no rosbag record")
    run.add_argument("--settle", type=float, default=0.5, help="s held after each motion before it is at rest")
    run.add_argument("--deceleration", type=float, default=1.0, help="braking on a press, m/s² along the path")
    run.add_argument(
        "--response-timeout",
        type=float,
        default=300.0,
        help="longest wait for go or an answer in s; then the trial goes on without it (default 300)",
    )
    run.add_argument("--step-timeout", type=float, default=10.0, help="lockstep: longest wait for a joint state")
    run.add_argument("--connect-timeout", type=float, default=60.0, help="longest wait for the engine at start")
    run.add_argument(
        "--pose-source",
        action="append",
        default=[],
        metavar="CONDITION=NAME",
        help="a condition's pose source by name, over what announces itself on /study/tracking (e.g. reality=vicon)",
    )
    run.add_argument(
        "--link",
        action="append",
        default=[],
        metavar="CONDITION=LINK",
        help="a condition's robot link: stream (default), a driver's preset (franka_ros, ur_robot_driver, iiwa_stack, "
        "xarm_ros) or NAMESPACE,JOINT_STATES_TOPIC of a joint_trajectory_controller (needs --realtime)",
    )
    trajectory = run.add_argument_group("a trajectory controller's link (the toolkit's checks, never the robot's stop)")
    trajectory.add_argument(
        "--stale-after", type=float, default=0.25, help="s without a joint state in a motion: stop the arm (0.25)"
    )
    trajectory.add_argument(
        "--tracking-tolerance", type=float, default=0.1, help="rad of joint error in a motion: stop the arm (0.1)"
    )
    trajectory.add_argument(
        "--surface-tolerance",
        type=float,
        default=0.005,
        help="m the joint error may change the arm's distance to the hand in an approach: stop the arm (0.005)",
    )
    trajectory.add_argument(
        "--floor", type=float, default=0.01, help="m: plans closer to the hand are refused, the arm stopped (0.01)"
    )
    trajectory.add_argument(
        "--rehearsal-speed", type=float, default=1.0, help="approaches at this fraction of their speed (0..1]"
    )
    trajectory.add_argument(
        "--rehearsal-clearance",
        type=float,
        metavar="M",
        help="the rehearsal with the hand out of reach: every approach ends M m further from the hand than planned",
    )
    trajectory.add_argument(
        "--margin",
        type=float,
        default=DEFAULT_MARGIN,
        help="the fraction of each of the robot's limits a motion on a trajectory controller may use; plans beyond "
        f"are refused before any motion ({DEFAULT_MARGIN:g})",
    )
    trajectory.add_argument(
        UNCHECKED,
        action="store_true",
        help="DANGER, for a stand-in only, never a real arm: run motions beyond the robot's limits and --margin",
    )
    run.set_defaults(handler=run_command)
    tracker = commands.add_parser("tracker", help="relay a tracker's poses into the scene's world, calibrated")
    tracker.add_argument("--config", type=Path, required=True, help="the tracker's YAML (docs/study.md)")
    tracker.add_argument("--participant", type=int, required=True, help="the session's participant number")
    tracker.add_argument("--out", type=Path, required=True, help="the study's output: the fit goes in its tracking/")
    tracker.add_argument("--calibration", type=Path, help="a saved fit (tracking/*.json) instead of touching points")
    add_scene_options(tracker)
    tracker.set_defaults(handler=tracker_command)


def run_command(args: argparse.Namespace) -> int:
    from sim.control.stepper import Pacing
    from sim.study.design.feasibility import Approaches, remedies
    from sim.study.run.node import run_node
    from sim.study.run.runner import RunnerOptions

    for option in ("dt", "settle", "deceleration", "response_timeout", "step_timeout", "connect_timeout"):
        check_positive(getattr(args, option), f"--{option.replace('_', '-')}")
    from sim.study.run.links.specs import link_specs

    if not (0 < args.margin <= 1):  # said before the planning, not after
        raise RunError(f"--margin must be in (0, 1], got {args.margin!r}")
    plan = plan_from_data(read_yaml(args.plan, "plan"), str(args.plan))
    if args.rehearsal_clearance is not None:
        from sim.study.run.rehearsal import out_of_reach

        plan = out_of_reach(plan, args.rehearsal_clearance)
    links = link_specs(
        args.link, plan.conditions, args.stale_after, args.tracking_tolerance, args.floor, args.rehearsal_speed,
        args.surface_tolerance,
    )  # fmt: skip
    if links and not args.realtime:
        raise RunError(f"--link: a trajectory controller ({', '.join(links)}) runs on wall time: give --realtime")
    scene, robot = scene_and_robot(args)
    options = RunnerOptions(
        Pacing(args.dt, args.realtime, step_timeout=args.step_timeout),
        args.auto_go,
        args.keyboard,
        args.settle,
        args.response_timeout,
        args.deceleration,
        pose_sources=pose_sources(args.pose_source),
    )
    with Approaches(robot, scene, args.dt) as approaches:
        planned = approaches.plan_all((t.path, t.standoff, t.peak_speed) for t in plan.trials)
        infeasible = {key: approach.problems for key, approach in planned.items() if not approach.feasible}
        if infeasible:
            raise RunError(
                "the plan has combinations that are not feasible (none was run): "
                + "; ".join(f"{p} to {s} m at {v} m/s: {', '.join(why)}" for (p, s, v), why in infeasible.items())
                + f"; to change: {remedies(planned[key] for key in infeasible)}"
            )
        close = {key: a.distances.min() for key, a in planned.items() if float(a.distances.min()) < args.floor}
        if close:
            raise RunError(
                f"the plan comes closer to the hand than the floor of {args.floor:g} m (none was run): "
                + "; ".join(f"{p} to {s} m at {v} m/s: {d:.4f} m" for (p, s, v), d in close.items())
            )
        refuse_beyond_limits(robot, plan, planned, links, args)
        if args.rehearsal_clearance is not None:
            closest = min(float(a.distances.min()) for a in planned.values())
            print(
                f"rehearsal: every approach ends {args.rehearsal_clearance:g} m further from the hand than planned; "
                f"the closest comes {closest:.4f} m from it (these rows are not data)"
            )
        return run_node(
            robot, scene, plan, approaches, options, args.out.resolve(), not args.no_record, args.connect_timeout, links
        )


def refuse_beyond_limits(
    robot: RobotSpec,
    plan: SessionPlan,
    planned: Mapping[tuple[str, float, float], PlannedApproach],
    links: Mapping[str, TrajectoryLinkSpec],
    args: argparse.Namespace,
) -> None:
    """Before any motion: the trials on a trajectory controller (a real arm) against the robot's limits at --margin,
    their braking from a press at any sample and the moves to their starts too, and the --floor (check --safety's
    check). One line per refusal, naming the limit, then a RunError (exit 2). The stream's stand-in is not checked."""
    import sys

    from sim.study.safety.check import design_refusals
    from sim.study.safety.limits import limits_for
    from sim.study.safety.start_moves import start_move_refusals

    on_links = sorted({(t.path, t.standoff, t.peak_speed) for t in plan.trials if t.condition in links})
    if not on_links:
        return
    if getattr(args, UNCHECKED.lstrip("-").replace("-", "_")):
        print(
            f"sim.study run: WARNING: {UNCHECKED}: {robot.name}'s limits are NOT checked; never on a real arm",
            file=sys.stderr,
        )
        return
    limits = limits_for(robot)
    checked = {key: planned[key] for key in on_links}
    refusals = design_refusals(limits, checked, args.margin, args.floor, args.deceleration)
    refusals += start_move_refusals(robot, limits, checked, args.margin)
    for line in refusals:
        print(f"refused: {line}")
    if refusals:
        raise RunError(
            f"{len(refusals)} refusal(s) of {robot.name}'s limits ({limits.source}) at {args.margin:.0%} on a "
            "trajectory controller (none was run); to change: lower peak speeds, a gentler --deceleration"
        )


def pose_sources(given: list[str]) -> dict[str, str]:
    """--pose-source CONDITION=NAME, each condition once."""
    from sim.study.design.spec import CONDITIONS

    named: dict[str, str] = {}
    for text in given:
        condition, _, name = text.partition("=")
        if condition not in CONDITIONS or not name.strip() or condition in named:
            raise RunError(
                f"--pose-source must be CONDITION=NAME, a condition of {', '.join(CONDITIONS)} once, got {text!r}"
            )
        named[condition] = name.strip()
    return named


def tracker_command(args: argparse.Namespace) -> int:
    import json

    from sim.study.run.tracker import run_tracker
    from sim.study.run.tracking import marked_points, saved_calibration, tracker_config

    scene, _ = scene_and_robot(args)
    config = tracker_config(read_yaml(args.config, "tracker config"), scene, str(args.config))
    saved = None
    if args.calibration is not None:
        try:
            data = json.loads(args.calibration.read_text(encoding="utf-8"))
        except (OSError, ValueError) as error:
            raise RunError(f"cannot read the calibration {args.calibration}: {error}") from None
        saved = saved_calibration(data, config, marked_points(scene), str(args.calibration))
    return run_tracker(config, marked_points(scene), args.participant, args.out.resolve(), saved)
