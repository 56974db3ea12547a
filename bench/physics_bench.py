"""Benchmark of sim.engine.physics: speed (real-time factor) and tracking accuracy on the thesis's joint-space test.

    .venv/bin/python -m bench.physics_bench [--steps 1000] [--robots ROBOT ...]

1. Real-time factor = sim seconds per wall second, per robot and mode, at dt = 0.02 s, stepping towards a moving
   target (so the drive works every step). Target: >= 100 for the implicit drive (physics mode).
2. Tracking of the thesis's test: Panda joint 1 through 0.25, 1, 2.75, 1.5, -2, -2.45 rad at t = 0, 2, ..., 10 s
   (quintic PolynomialTrajectory: zero velocity and acceleration at every waypoint), the other joints commanded 0.
   The world starts at the trajectory's start; before the step ending at t_k = k*dt the target is the reference at
   t_k with its velocity as feed-forward (targets for the END of the step). Compared at t_k, k = 0..500.
   Metrics (sim.control.metrics): MAPE over samples with |reference| > 1e-3 rad only (MAPE explodes near zero
   crossings),
   WAPE = sum|e| / sum|ref|, NRMSE = RMSE / (max - min of ref), max |e|. For joints 2-7 the reference is 0 all
   along, so only max |e| is defined. Targets: joint-1 MAPE <= 0.05 % in physics mode, exactly 0 in no_physics.
   One extra row passes the same targets one step early (targets for the START of the step) to show the lag that
   convention costs.
   Note: Panda joint 4 = 0 is outside Franka's official range (upper limit -0.0698 rad); the physics does not clamp
   to the limits, so that is fine here. The quintic's peak joint-1 speed (3.3 rad/s) also exceeds the datasheet's
   2.175 rad/s; the physics does not limit velocities either.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from sim.control.metrics import DEFAULT_MAPE_FLOOR, tracking_metrics
from sim.engine.physics import Mode, PhysicsWorld
from sim.geometry.trajectory import PolynomialTrajectory
from sim.robots import ROBOT_NAMES, RobotSpec, load_robot

DT = 0.02
RTF_TARGET = 100.0
MAPE_TARGET_PERCENT = 0.05
THESIS_WAYPOINTS_J1 = [0.25, 1.0, 2.75, 1.5, -2.0, -2.45]  # rad, one every 2 s


def real_time_factor(robot: RobotSpec, mode: Mode, steps: int) -> tuple[float, float]:
    """(sim s per wall s, wall µs per step) stepping towards a slow sine around home."""
    amplitude = np.where(np.array(robot.joint_types) == "prismatic", 0.05, 0.3)
    with PhysicsWorld(robot, mode=mode, dt=DT) as world:
        start = time.perf_counter()
        for k in range(1, steps + 1):
            t = k * DT
            world.set_targets(robot.home + amplitude * np.sin(t), amplitude * np.cos(t))
            world.step()
        wall = time.perf_counter() - start
    return steps * DT / wall, 1e6 * wall / steps


def seed_reference() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, positions, velocities) of the thesis's test sampled at every step end, t = 0 .. 10 s."""
    waypoints = np.zeros((len(THESIS_WAYPOINTS_J1), 7))
    waypoints[:, 0] = THESIS_WAYPOINTS_J1
    trajectory = PolynomialTrajectory(2.0 * np.arange(len(THESIS_WAYPOINTS_J1)), waypoints, order="quintic")
    steps = int(round((trajectory.end_time - trajectory.start_time) / DT))
    times = trajectory.start_time + DT * np.arange(steps + 1)
    sample = trajectory.sample(times)
    return times, sample.positions, sample.velocities


def track(mode: Mode, positions: np.ndarray, velocities: np.ndarray, lead: int = 0) -> np.ndarray:
    """Achieved positions at every step end; `lead` = -1 passes each target one step early."""
    robot = load_robot("panda")
    with PhysicsWorld(robot, mode=mode, dt=DT, q0=positions[0]) as world:
        achieved = [world.state().positions]
        for k in range(1, len(positions)):
            j = max(k + lead, 0)
            world.set_targets(positions[j], velocities[j])
            achieved.append(world.step().positions)
    return np.array(achieved)


def _fmt(value: float, spec: str) -> str:
    return "n/a" if not np.isfinite(value) else format(value, spec)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000, help="steps per real-time-factor measurement")
    parser.add_argument(
        "--robots",
        nargs="+",
        default=list(ROBOT_NAMES),
        metavar="ROBOT",
        help="names or URDF / robot YAML paths (default: the bundled robots)",
    )
    args = parser.parse_args(argv)
    robots = [load_robot(reference) for reference in args.robots]

    print(f"Real-time factor at dt = {DT} s ({args.steps} steps, moving target)")
    print(f"{'robot':<10}{'mode':<20}{'RTF':>10}{'µs/step':>10}   target")
    for robot in robots:
        for mode in Mode:
            rtf, micros = real_time_factor(robot, mode, args.steps)
            target = f">= {RTF_TARGET:g}  {'met' if rtf >= RTF_TARGET else 'MISSED'}" if mode is Mode.PHYSICS else "-"
            print(f"{robot.name:<10}{mode.value:<20}{rtf:>10.0f}{micros:>10.1f}   {target}")

    times, reference, velocities = seed_reference()
    print(
        f"\nTracking, the thesis's test (Panda joint 1 through {THESIS_WAYPOINTS_J1} rad every 2 s, quintic; "
        "other joints 0)"
    )
    print(f"{len(times)} samples at the step ends t = 0..{times[-1]:g} s; MAPE over |ref| > {DEFAULT_MAPE_FLOOR:g} rad")
    header = f"{'mode':<30}{'joint':>6}{'MAPE %':>12}{'(n)':>6}{'WAPE %':>12}{'NRMSE %':>12}{'max|e| rad':>12}   target"
    print(header)
    print("-" * len(header))
    runs = [(mode.value, mode, 0) for mode in Mode] + [("physics, start-of-step targets", Mode.PHYSICS, -1)]
    for label, mode, lead in runs:
        achieved = track(mode, reference, velocities, lead)
        for joint in range(7):
            metrics = tracking_metrics(reference[:, joint], achieved[:, joint], DT)
            target = "-"
            if joint == 0 and lead == 0 and mode is Mode.PHYSICS:
                met = metrics.mape_percent <= MAPE_TARGET_PERCENT
                target = f"MAPE <= {MAPE_TARGET_PERCENT:g} %  {'met' if met else 'MISSED'}"
            elif joint == 0 and mode is Mode.NO_PHYSICS:
                target = f"exact  {'met' if metrics.max_abs_error == 0 else 'MISSED'}"
            print(
                f"{label if joint == 0 else '':<30}{joint + 1:>6}"
                f"{_fmt(metrics.mape_percent, '.5f'):>12}{metrics.mape_samples:>6}"
                f"{_fmt(metrics.wape_percent, '.5f'):>12}{_fmt(metrics.nrmse_percent, '.5f'):>12}"
                f"{metrics.max_abs_error:>12.2e}   {target}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
