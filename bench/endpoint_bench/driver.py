"""The run: the phases for one endpoint, or for two (this tree and another revision's, from a git worktree) phase
by phase alternately on one roscore; each endpoint's table, and their comparison."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

from bench.endpoint_bench import hardening, large, latency, mix, throughput, websocket
from bench.endpoint_bench.harness import Harness
from bench.endpoint_bench.markdown import markdown
from bench.endpoint_bench.records import Row
from bench.endpoint_bench.settings import Settings
from bench.endpoint_bench.tables import compare_tables, print_table
from bench.messages import MESSAGE_NAME
from sim.processes import REPO, RosCore

# the phases in the order they run; `--only` names them
PHASES: dict[str, Callable[[Harness], None]] = {
    "throughput": throughput.run,
    "large": large.run,
    "unity_mix": mix.run,
    "rtt": latency.round_trips,
    "fan_out": latency.fan_out,
    "huge_prefix": hardening.huge_prefix,
    "never_reader": hardening.never_reader,
    "websocket": websocket.run,
}


def run(
    settings: Settings,
    sides: list[tuple[str, Path | None]],
    phases: tuple[str, ...],
    keep_logs: bool,
    tables: bool = False,
) -> int:
    """Run the phases for every endpoint in `sides` ((name, bridge directory or None for this tree)), phase by phase
    alternately, on one roscore; print each endpoint's table, and the comparison when there are two; with `tables`,
    README's markdown tables of this tree's figures (and the other's beside them) last."""
    started = time.monotonic()
    load_at_start = os.getloadavg()[0]
    core = RosCore()
    log_dir = core.tmp / "bench"
    log_dir.mkdir()
    benches: list[Harness] = []
    failed = True
    try:
        for index, (_, bridge_dir) in enumerate(sides):
            side_logs = log_dir / f"side{index}"
            side_logs.mkdir()
            benches.append(
                Harness(replace(settings, bridge_dir=bridge_dir), core, side_logs, f"bench_endpoint_{index}")
            )
        for name in phases:
            for (side, _), bench in zip(sides, benches):
                print(f"[{time.monotonic() - started:5.0f} s] {name} ({side}) ...", file=sys.stderr, flush=True)
                PHASES[name](bench)
        for (side, _), bench in zip(sides, benches):
            alive = bench.endpoint.process.poll() is None
            bench.rows.append(Row("Endpoint alive at the end", "yes" if alive else "NO", ok=alive))
            header = (
                f"ROS-TCP endpoint benchmark ({'quick' if settings.quick else 'full'} run, "
                f"{time.monotonic() - started:.0f} s): {MESSAGE_NAME} 7 joints, {len(bench.payload)} B payload; "
                f"{os.cpu_count()} CPUs; Python {sys.version.split()[0]}; TCP congestion control "
                f"{congestion_control()} (rospy's connections; the endpoint's local clients are never paced); "
                f"endpoint: {side} "
                f"{' '.join(settings.endpoint_args)}\nload average (1 min) at start {load_at_start:.2f}, at end "
                f"{os.getloadavg()[0]:.2f} (other processes on these CPUs skew every figure)"
            )
            print_table(bench.rows, header)
            print()
        if len(benches) == 2:  # this tree's figures over the other's, whichever ran first
            (ours, our_bench), (theirs, their_bench) = sorted(
                zip(sides, benches), key=lambda side_bench: side_bench[0][1] is not None
            )
            compare_tables(our_bench.rows, their_bench.rows, ours[0], theirs[0])
            if tables:
                print("\n" + markdown(our_bench.rows, their_bench.rows))
        elif tables:
            print("\n" + markdown(benches[0].rows))
        failed = False
    finally:
        for bench in benches:
            bench.close()
        stop_core(core, keep_logs or failed)
    return 0


def congestion_control() -> str:
    """The kernel's default TCP congestion control: with BBR, rospy's loopback connections (the ceilings) are paced."""
    try:
        return Path("/proc/sys/net/ipv4/tcp_congestion_control").read_text().strip()
    except OSError:
        return "unknown"


def stop_core(core: RosCore, keep_logs: bool) -> None:
    """Stop the benchmark's roscore; its logs and the nodes' are kept (their path printed) or removed."""
    core.stop(keep_logs=keep_logs)
    if keep_logs:
        print(f"logs kept in {core.tmp}", file=sys.stderr)


@contextmanager
def worktree_of(revision: str) -> Iterator[Path]:
    """A detached git worktree of `revision` of this repository, removed afterwards."""
    path = Path(tempfile.mkdtemp(prefix="endpoint_bench_ab_"))
    subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "--quiet", str(path), revision], check=True)
    try:
        yield path
    finally:
        subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(path)], check=False)
        shutil.rmtree(path, ignore_errors=True)
