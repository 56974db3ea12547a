"""The command line: `python -m bench.endpoint_bench --help` (the method is in the package's docstring)."""

from __future__ import annotations

import argparse
import contextlib
import gc
import subprocess
import sys
from pathlib import Path

import bench.endpoint_bench
from bench.endpoint_bench.driver import PHASES, run, worktree_of
from bench.endpoint_bench.settings import settings_for
from sim.processes import REPO


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(bench.endpoint_bench.__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short run: 2 s windows, fewer RTT samples, 10 s soak")
    parser.add_argument(
        "--seconds", type=float, help="every window and the soak this long (the RTT samples scaled to match)"
    )
    parser.add_argument("--keep-logs", action="store_true", help="keep roscore/endpoint/node logs (path printed)")
    parser.add_argument("--bridge-dir", type=Path, help="benchmark the `bridge` package in this directory instead")
    parser.add_argument(
        "--ab",
        metavar="REVISION",
        help="also run REVISION's endpoint (a git worktree), phase by phase alternately on one roscore, and compare",
    )
    parser.add_argument(
        "--their-first",
        action="store_true",
        help="with --ab: REVISION's endpoint runs first in every phase (a phase's first side may meet a different "
        "machine than its second: run both orders to tell)",
    )
    parser.add_argument("--endpoint-arg", action="append", default=[], help="extra endpoint argument (repeatable)")
    parser.add_argument("--only", nargs="+", choices=tuple(PHASES), help="run only these phases")
    parser.add_argument(
        "--markdown",
        action="store_true",
        help="also print README's tables of these figures as markdown (tests.doc_figures rewrites README with them)",
    )
    args = parser.parse_args(argv)
    if args.ab is not None and args.bridge_dir is not None:
        parser.error("--ab compares this tree with REVISION; it takes no --bridge-dir")
    if args.their_first and args.ab is None:
        parser.error("--their-first orders the two sides of --ab REVISION")
    if args.ab is not None:
        known = subprocess.run(
            ["git", "-C", str(REPO), "rev-parse", "--verify", "--quiet", args.ab + "^{commit}"],
            capture_output=True,
            text=True,
        )
        if known.returncode != 0:
            parser.error(f"--ab: {args.ab!r} is not a commit of this repository")
    if args.seconds is not None and not 0.1 <= args.seconds <= 600:
        parser.error(f"--seconds must be 0.1..600, not {args.seconds:g}")
    settings = settings_for(args.quick, args.seconds, tuple(args.endpoint_arg))
    # Harness processes (this one stands in for Unity; bench.endpoint_rosnode for the rospy nodes) freeze what
    # start-up made, as the endpoint does, so no side is charged for a harness's full GC pass over its modules.
    gc.collect()
    gc.freeze()
    with contextlib.ExitStack() as stack:
        sides = [("this tree" if args.ab else str(args.bridge_dir or REPO), args.bridge_dir)]
        if args.ab is not None:
            sides.append((args.ab, stack.enter_context(worktree_of(args.ab))))
        if args.their_first:
            sides.reverse()
        return run(settings, sides, tuple(args.only or PHASES), args.keep_logs, args.markdown)


if __name__ == "__main__":
    sys.exit(main())
