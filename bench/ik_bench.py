"""IK benchmark: success rate and solve times of sim.geometry.kinematics on the Panda and the igt, against the targets.

Run: .venv/bin/python -m bench.ik_bench [--targets 500] [--path-points 250] [--seed 0] [--robots path/to/arm.urdf ...]
Every case solves IK for FK poses of random configurations within the datasheet limits, so all are reachable.
`--robots` adds a near-seed case per robot, on the axes its chain controls (sim.control.scenarios.defaults).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from measuring.stats import percentile
from sim.control.scenarios.defaults import controllable_weights, describe_axes
from sim.geometry.kinematics import PLANAR_WEIGHTS, IKResult, chain_for, planar_pose, solve_ik, solve_path_ik
from sim.robots import RobotSpec, load_robot

NEAR_SEED_NOISE = 0.1  # rad (m for the rail): how far the warm start is from a solution
RESTARTS = 20  # for cold starts


@dataclass
class CaseResult:
    name: str
    success_rate: float
    median_ms: float
    p95_ms: float
    success_target: float
    median_target_ms: float | None


def _run_case(
    name: str,
    robot: RobotSpec,
    n: int,
    seed: int,
    solve: Callable[[np.ndarray, np.ndarray, np.random.Generator], IKResult],
    near_seed: bool,
    success_target: float,
    median_target_ms: float | None = None,
) -> CaseResult:
    chain = chain_for(robot)
    rng = np.random.default_rng(seed)
    targets = rng.uniform(robot.lower, robot.upper, size=(n, robot.dof))
    times, successes = [], 0
    for q_true in targets:
        if near_seed:
            seed_q = robot.clip(q_true + rng.uniform(-NEAR_SEED_NOISE, NEAR_SEED_NOISE, robot.dof))
        else:  # cold start: an unrelated random configuration
            seed_q = rng.uniform(robot.lower, robot.upper)
        pose = chain.fk(q_true)
        start = time.perf_counter()
        result = solve(pose, seed_q, rng)
        times.append(time.perf_counter() - start)
        if result.success and not robot.within_limits(result.q):
            raise AssertionError(f"{name}: solution {result.q} outside the limits reported as success")
        successes += result.success
    times_ms = np.array(times) * 1e3
    return CaseResult(
        name,
        successes / n,
        float(np.median(times_ms)),
        percentile(times_ms.tolist(), 95),
        success_target,
        median_target_ms,
    )


def _panda_cases(n: int, seed: int) -> list[CaseResult]:
    panda = load_robot("panda")
    chain = chain_for(panda)
    return [
        _run_case(
            "panda full pose, near seed",
            panda,
            n,
            seed,
            lambda pose, q0, rng: solve_ik(chain, pose, q0),
            True,
            0.995,
            0.3,
        ),
        _run_case(
            f"panda full pose, random seed, ≤{RESTARTS} restarts",
            panda,
            n,
            seed + 1,
            lambda pose, q0, rng: solve_ik(chain, pose, q0, restarts=RESTARTS, rng=rng),
            False,
            0.995,
        ),
        _run_case(
            "panda position only, near seed",
            panda,
            n,
            seed + 2,
            lambda pose, q0, rng: solve_ik(chain, pose, q0, position_only=True),
            True,
            1.0,
        ),
        _run_case(
            f"panda position only, random seed, ≤{RESTARTS} restarts",
            panda,
            n,
            seed + 3,
            lambda pose, q0, rng: solve_ik(chain, pose, q0, position_only=True, restarts=RESTARTS, rng=rng),
            False,
            1.0,
        ),
    ]


def _igt_case(n: int, seed: int) -> CaseResult:
    igt = load_robot("igt")
    chain = chain_for(igt)

    def solve(pose: np.ndarray, q0: np.ndarray, rng: np.random.Generator) -> IKResult:
        target = planar_pose(pose[0, 3], pose[1, 3], math.atan2(pose[1, 0], pose[0, 0]))
        return solve_ik(chain, target, q0, weights=PLANAR_WEIGHTS)

    return _run_case("igt x, y, yaw, near seed", igt, n, seed + 4, solve, True, 1.0)


def _robot_case(reference: str, n: int, seed: int) -> CaseResult:
    robot = load_robot(reference)
    chain = chain_for(robot)
    weights = controllable_weights(chain, robot.home)

    def solve(pose: np.ndarray, q0: np.ndarray, rng: np.random.Generator) -> IKResult:
        return solve_ik(chain, pose, q0, weights=weights)

    return _run_case(f"{robot.name} {describe_axes(weights)}, near seed", robot, n, seed + 5, solve, True, 0.99)


def _path_case(points: int, repeats: int) -> tuple[float, float, float, bool]:
    """Median time (ms) of a warm-started straight-line path, its max joint jump, the per-point time, all solved."""
    panda = load_robot("panda")
    chain = chain_for(panda)
    start = chain.fk(panda.home)
    targets = []
    for s in np.linspace(0.0, 1.0, points):
        pose = start.copy()
        pose[:3, 3] += s * np.array([0.1, 0.3, -0.25])  # 0.4 m diagonal, orientation held
        targets.append(pose)
    durations = []
    for _ in range(repeats):
        begin = time.perf_counter()
        path = solve_path_ik(chain, targets, panda.home)
        durations.append(time.perf_counter() - begin)
    median_ms = float(np.median(durations)) * 1e3
    return median_ms, path.max_joint_jump, median_ms / points, bool(path.success.all())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=500, help="targets per case")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--path-points", type=int, default=250)
    parser.add_argument("--robots", nargs="*", default=[], metavar="ROBOT", help="more robots: URDF or YAML paths")
    args = parser.parse_args(argv)

    cases = _panda_cases(args.targets, args.seed) + [_igt_case(args.targets, args.seed)]
    cases += [_robot_case(reference, args.targets, args.seed) for reference in args.robots]
    all_met = True
    header = f"{'case':<52} {'success':>8} {'target':>8} {'median ms':>10} {'target':>8} {'p95 ms':>8}"
    print(f"IK benchmark, {args.targets} targets per case (numpy {np.__version__})")
    print(header)
    print("-" * len(header))
    for case in cases:
        met = case.success_rate >= case.success_target
        if case.median_target_ms is not None:
            met = met and case.median_ms <= case.median_target_ms
        all_met = all_met and met
        median_target = f"≤{case.median_target_ms:.2f}" if case.median_target_ms is not None else "-"
        print(
            f"{case.name:<52} {100 * case.success_rate:>7.1f}% "
            f"{'≥' + format(100 * case.success_target, '.1f') + '%':>8} "
            f"{case.median_ms:>10.3f} {median_target:>8} {case.p95_ms:>8.3f}{'' if met else '  MISSED'}"
        )

    path_ms, jump, per_point_ms, path_ok = _path_case(args.path_points, repeats=5)
    path_met = path_ms <= 50.0 and path_ok
    all_met = all_met and path_met
    print()
    print(
        f"panda {args.path_points}-point straight-line path IK (warm-started, full pose): "
        f"{path_ms:.1f} ms (target ≤50 ms), {per_point_ms * 1e3:.0f} µs/point, "
        f"all solved: {path_ok}, max joint jump {jump:.4f} rad{'' if path_met else '  MISSED'}"
    )
    print(f"\nall targets met: {all_met}")
    return 0 if all_met else 1


if __name__ == "__main__":
    sys.exit(main())
