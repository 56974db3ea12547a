"""Benchmark of the perception study (sim.study): planning time per approach path, and the wall time of a whole
38-test session with a simulated participant in lockstep.

    .venv/bin/python -m bench.study_bench [--participants 2] [--repeats 3] [--design DESIGN.yaml]

1. Planning: every combination of the bundled design (path x stand-off or speed), each planned and checked
   `--repeats` times (the path, IK of every sample, limits, collisions in pybullet, the stand-off reached); the
   median per combination, and per sample.
2. Sessions: `simulate` end to end (its own roscore, endpoint, engine stand-in in physics mode, a simulated
   participant and the runner with rosbag record) for `--participants` participants of the bundled design; the
   runner's wall time per 38-test session. Target: under a minute per session.
`--design` plans and simulates another design file in the bundled one's place (the smoke test's is a small one).
"""

from __future__ import annotations

import argparse
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

from sim.study.design.feasibility import SceneWorld, plan_combination
from sim.study.design.plan import make_plan
from sim.study.design.scene import load_scene, scene_robot
from sim.study.design.spec import load_design
from sim.study.simulation.session import Simulation, simulate

SESSION_TARGET_S = 60.0
DT = 0.02


def bench_planning(repeats: int, design: Path | None) -> None:
    scene = load_scene()
    robot = scene_robot(scene)
    plan = make_plan(load_design(design), 1, 0)
    combinations = list(dict.fromkeys((t.path, t.standoff, t.peak_speed) for t in plan.trials))
    print(f"Planning, {len(combinations)} combinations of {design or 'the bundled design'}, median of {repeats}")
    print(f"{'path':<14}{'stand-off m':>12}{'speed m/s':>11}{'samples':>9}{'ms':>9}{'ms/sample':>11}  verdict")
    per_path: dict[str, list[float]] = {}
    with SceneWorld(robot, scene) as world:
        for name, standoff, speed in combinations:
            times, planned = [], None
            for _ in range(repeats):
                started = time.perf_counter()
                planned = plan_combination(robot, scene, (name, standoff, speed), DT, world)
                times.append((time.perf_counter() - started) * 1000)
            assert planned is not None
            median = statistics.median(times)
            samples = len(planned.path.times)
            per_path.setdefault(name, []).append(median)
            print(
                f"{name:<14}{standoff:>12.3f}{speed:>11.2f}{samples:>9}{median:>9.1f}{median / samples:>11.3f}  "
                f"{'feasible' if planned.feasible else 'NOT feasible'}"
            )
    print("median per path: " + ", ".join(f"{name} {statistics.median(ms):.0f} ms" for name, ms in per_path.items()))


def bench_sessions(participants: int, design: Path | None) -> None:
    lines: list[str] = []
    with tempfile.TemporaryDirectory(prefix="study-bench-") as out:
        started = time.monotonic()
        simulate(Simulation(participants, 1, Path(out), design=design), lines.append)
        total = time.monotonic() - started
    print(
        f"\nSessions: {participants} simulated participants, {design or 'the bundled design'}, lockstep, physics mode"
    )
    walls = []
    for line in lines:
        found = re.match(r"participant (\d+): (\d+) trials .* in ([\d.]+) s of wall time, ([\d.]+) s of ROS time", line)
        if found:
            number, trials, wall, ros = found.groups()
            walls.append(float(wall))
            print(
                f"participant {number}: {trials} trials, {float(wall):6.1f} s wall, {float(ros):6.1f} s ROS time "
                f"({float(ros) / float(wall):.1f}x real time)"
            )
    worst = max(walls)
    verdict = "met" if worst < SESSION_TARGET_S else "MISSED"
    print(
        f"slowest session {worst:.1f} s (target < {SESSION_TARGET_S:g} s: {verdict}); whole run with start-up, "
        f"planning and the report: {total:.0f} s"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--design", type=Path, help="a design file in the bundled design's place")
    args = parser.parse_args()
    bench_planning(args.repeats, args.design)
    bench_sessions(args.participants, args.design)
    return 0


if __name__ == "__main__":
    sys.exit(main())
