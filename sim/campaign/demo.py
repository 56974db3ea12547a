"""The main job, end to end on embedded defaults: `bash launch_scripts/demo.sh` (or `python -m sim.demo`).

Starts its own roscore (free port, own ROS_HOME/ROS_LOG_DIR), then for the Panda (or `--robot`: any URDF):
  1. the base case: endpoint + game-engine stand-in (TCP, pybullet physics, auto-simulate) driven by the commander
     along the 40 s sweep (at --time-scale), recorded by rosbag record;
  2. an IK scenario: a straight Cartesian line to the robot's default IK goal (the Panda's: (0.5, 0.375, 0.75) m),
     IK of every sample, /clock-driven;
then analyses both bags (rosbags), prints the metrics table, writes the report and plots, and stops everything
it started (by PID), whatever happens.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from sim.campaign import analysis
from sim.campaign.trials import USE_CASES, Campaign, UseCase
from sim.control.scenarios import build_motion
from sim.entry import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK, fail, log_to_stderr
from sim.errors import SimError
from sim.robots import add_robot_arguments, robot_from_args

__all__ = ["main"]


def _case(name: str) -> UseCase:
    return next(case for case in USE_CASES if case.name == name)


PROG = "sim.demo"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sim.demo", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/demo"), help="where bags, report and plots go")
    parser.add_argument("--time-scale", type=float, default=4.0, help="speed-up of the wall-clock base case")
    add_robot_arguments(parser)
    args = parser.parse_args(argv)
    log_to_stderr()
    try:
        robot = robot_from_args(args)
        for scenario in ("sweep", "ik_cartesian"):  # bad input is found before anything starts
            goal = build_motion(robot, scenario).goal
    except SimError as error:
        return fail(PROG, error, EXIT_BAD_INPUT)
    assert goal is not None
    out = args.out.resolve()
    campaign = Campaign(out, time_scale=args.time_scale)
    started = time.monotonic()
    try:
        print(f"demo: roscore, endpoint, engine and commander for the {robot.name}; output in {out}", flush=True)
        print("demo: 1/2 base case (TCP engine, physics, auto-simulate), 40 s sweep ...", flush=True)
        base = campaign.run_trial(robot, _case("base"), 1)
        print("demo: 2/2 IK scenario (Cartesian line, IK of every sample, /clock-driven) ...", flush=True)
        ik = campaign.run_trial(robot, _case("auto_simulate_off"), 1, ("ik_cartesian",))
        ik.use_case = "ik_cartesian"
    except (SimError, TimeoutError) as error:
        return fail(PROG, error, EXIT_FAILED)
    finally:
        campaign.close()

    results = [base, ik]
    report = analysis.write_report(results, out, title=f"Demo: {robot.name} base case and IK scenario")
    assert ik.series is not None
    _, desired, achieved = analysis.align(ik.series)
    ee_plot = analysis.plot_ee_paths(robot, desired, achieved, goal[:3, 3], out / "ee_path_ik_cartesian.png")
    print()
    print(analysis.markdown_table(analysis.summary_rows(results)))
    lost = sum(result.lost_messages for result in results)
    print(f"messages lost: {lost}; wall time {time.monotonic() - started:.0f} s")
    print(f"bags:   {out / 'bags'}")
    print(f"report: {report}")
    for plot in sorted(out.glob("*.png")):
        print(f"plot:   {plot}")
    print(f"(end-effector path: {ee_plot.name})")
    return EXIT_OK if lost == 0 else EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
