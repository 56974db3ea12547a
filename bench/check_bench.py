"""Benchmark of the study's `check` on arms labs have (issue 50: seconds, not minutes): for each test arm, the wall
time of `python -m sim.study check --robot <its URDF>` cold (an empty cache: the self-contact verdict sampled and a
scene proposed for the arm) and warm (the same cache again: both read back), and check's verdict.

    .venv/bin/python -m bench.check_bench [--arms ur5_like widowx_like ...] [--design DESIGN.yaml]

The arms are the example arms the tests run on too (sim.robots.examples, written into a temporary folder): the three
LAB_ARMS, the STUDY_ARMS and the Panda of the bundled scene. Target: cold within 30 s on 2 cores for a 6-joint arm.
Each check runs as its own process, as a user runs it, with $VR_SIM_CACHE pointing into the temporary folder.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from sim.processes import PYTHON, REPO, plain_env
from sim.robots.examples import LAB_ARM_EE_LINKS, LAB_ARMS, STUDY_ARMS, write_example_arm

COLD_TARGET_S = 30.0
ARMS = ("panda", *LAB_ARMS, *(design.name for design in STUDY_ARMS))


def _cpu_of_children() -> float:
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return used.ru_utime + used.ru_stime


def check(robot_args: list[str], cache: Path, design: Path | None) -> tuple[float, float, str]:
    """(wall time in s, CPU time in s, check's last line) of one `check` with the cache `cache`. The CPU time is
    what the wall time would be on an idle core: on a machine shared with other work, the wall time is not."""
    command = [PYTHON, "-m", "sim.study", "check", *robot_args, *(["--design", str(design)] if design else [])]
    started, cpu = time.monotonic(), _cpu_of_children()
    done = subprocess.run(
        command, cwd=REPO, env=dict(plain_env(), VR_SIM_CACHE=str(cache)), capture_output=True, text=True
    )
    elapsed, cpu = time.monotonic() - started, _cpu_of_children() - cpu
    lines = [line for line in (done.stdout + done.stderr).splitlines() if line.strip()]
    if done.returncode == 0:
        verdict = next((line for line in reversed(lines) if "combinations planned" in line), "passed")
    else:
        verdict = next((line for line in reversed(lines) if "error:" in line), f"exit {done.returncode}")
    return elapsed, cpu, verdict


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--arms", nargs="+", choices=ARMS, default=list(ARMS))
    parser.add_argument("--design", type=Path, help="another design file than the bundled one")
    args = parser.parse_args(argv)
    print(f"check of {args.design or 'the bundled design'}: wall time cold (empty cache) and warm, per arm")
    print(f"{'arm':<20}{'cold s':>8}{'cpu s':>8}{'warm s':>8}{'cpu s':>8}  verdict")
    slowest = 0.0
    with tempfile.TemporaryDirectory(prefix="check-bench-") as folder:
        for name in args.arms:
            if name == "panda":
                robot_args: list[str] = []
            else:
                robot_args = ["--robot", str(write_example_arm(Path(folder) / "arms", name))]
                if name in LAB_ARM_EE_LINKS:
                    robot_args += ["--ee-link", LAB_ARM_EE_LINKS[name]]
            cache = Path(folder) / "cache" / name
            cold, cold_cpu, _ = check(robot_args, cache, args.design)
            warm, warm_cpu, verdict = check(robot_args, cache, args.design)
            slowest = max(slowest, cold)
            print(f"{name:<20}{cold:>8.1f}{cold_cpu:>8.1f}{warm:>8.1f}{warm_cpu:>8.1f}  {verdict}", flush=True)
    met = "met" if slowest <= COLD_TARGET_S else "NOT met"
    print(f"slowest cold check {slowest:.1f} s (target {COLD_TARGET_S:.0f} s): {met}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
