"""Freshness over a slow link: how old the messages are that a Unity-like client gets through the endpoint over a
Wi-Fi-like link, and that ROS gets from it, per topic, over a minute.

Run: `.venv/bin/python -m bench.freshness_bench [--quick] [--seconds S] [--ab REVISION] [--original DIR]`.

The link (measuring.link.SlowLink): 100 Mbit/s, 8 ms each way, a 64 KiB queue, between the client (this process,
bridge.client.TcpClient, the Python twin of Unity's client) and the endpoint; roscore and the rospy nodes
(bench.endpoint_rosnode) are local to the endpoint, as on a robot's computer.

  down  a rospy node publishes 640x480 RGB images at 30 Hz (more than the link carries), a 7-joint JointState at
        100 Hz and an 8-transform TF at 100 Hz; the client subscribes to all three through the link.
  up    the client publishes images at 30 Hz and joint states at 100 Hz through the link, sending as a game engine
        should (EngineSender: small messages first, the newest image); a rospy node receives.

Every message carries a CLOCK_MONOTONIC stamp in its header (one machine's clock): its age is arrival time minus
stamp. Per topic: messages received and their rate, age p50/p99/max, and the median age in the first and the last
10 s (creep). The bars, with T_img the transmission time of one image on the link, T_buf the link's queue time and D
the one-way delay: no creep (last 10 s at most first 10 s + 10 %); small topics p99 <= T_img + T_buf + 2 D + 10 ms;
images p99 <= 2 T_img + T_buf + D + one frame period, at no less than 85 % of the images the link can carry.

`--ab REVISION` runs REVISION's endpoint (a git worktree) after this tree's; `--original DIR` also runs Unity's
original endpoint from DIR (a directory holding its `ros_tcp_endpoint` Python package), each on the same roscore.
`--markdown` also prints README's table of the client's side (down), each side's column, the original's "not run"
without `--original`.
Every loop is bounded in count and time; every process is stopped by PID.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.endpoint_bench.driver import stop_core, worktree_of
from bench.endpoint_bench.harness import ROSNODE, start_endpoint
from bench.messages import HEADER_OFFSETS, MESSAGE_KINDS, paced, read_stamp, stamped
from bridge.client import TcpClient
from measuring.link import SlowLink
from measuring.stats import percentile
from sim.processes import ManagedProcess, RosCore, free_port, kill_process

LINK_RATE_BPS = 100e6
LINK_DELAY_S = 0.008
LINK_BUFFER_BYTES = 64 * 1024
IMAGE_HZ, SMALL_HZ = 30, 100
WINDOW_S = 10.0  # the first and last windows compared for creep
AGES_IDLE_S = 3.0  # the receiving node stops this long after the last message: the client has stopped sending
DOWN = (
    ("vga_image", "/fresh/image", IMAGE_HZ),
    ("joint_state", "/fresh/joint_states", SMALL_HZ),
    ("tf", "/fresh/tf", SMALL_HZ),
)
UP = (("vga_image", "/fresh_up/image", IMAGE_HZ), ("joint_state", "/fresh_up/joint_states", SMALL_HZ))


@dataclass
class Received:
    """Arrivals of one topic: (arrival ns, age ns) each, monotonic clock."""

    kind: str
    sent: int = 0
    arrivals: list[tuple[int, int]] = field(default_factory=list)


@dataclass(frozen=True)
class Bars:
    image_s: float  # T_img
    buffer_s: float  # T_buf
    delay_s: float  # D

    @property
    def small_p99_s(self) -> float:
        return self.image_s + self.buffer_s + 2 * self.delay_s + 0.010

    @property
    def image_p99_s(self) -> float:
        return 2 * self.image_s + self.buffer_s + self.delay_s + 1.0 / IMAGE_HZ

    @property
    def images_per_s(self) -> float:
        """What the link carries, of images alone."""
        return 1.0 / self.image_s


def summary(topic: str, received: Received, bars: Bars, duration_s: float) -> list[tuple[str, str, str, bool | None]]:
    """Rows (measurement, value, bar, met) for one topic (pure)."""
    arrivals = received.arrivals
    if len(arrivals) < 2:
        return [(f"{topic}: received", f"{len(arrivals)}/{received.sent}", "", False)]
    start, end = arrivals[0][0], arrivals[-1][0]
    ages_ms = [age / 1e6 for _, age in arrivals]
    first = [age / 1e6 for at, age in arrivals if at - start <= WINDOW_S * 1e9]
    last = [age / 1e6 for at, age in arrivals if end - at <= WINDOW_S * 1e9]
    rate = (len(arrivals) - 1) / ((end - start) / 1e9)
    small = received.kind != "vga_image"
    bar_ms = (bars.small_p99_s if small else bars.image_p99_s) * 1000
    p99 = percentile(ages_ms, 99)
    first_p50, last_p50 = percentile(first, 50), percentile(last, 50)
    rows: list[tuple[str, str, str, bool | None]] = [
        (
            f"{topic}: received, rate [Hz]",
            f"{len(arrivals)}/{received.sent}, {rate:.1f}",
            "" if small else f">= {0.85 * bars.images_per_s:.1f} (85 % of the link's)",
            None if small else rate >= 0.85 * bars.images_per_s,
        ),
        (
            "  age p50 / p99 / max [ms]",
            f"{percentile(ages_ms, 50):.1f} / {p99:.1f} / {max(ages_ms):.1f}",
            f"p99 <= {bar_ms:.0f}",
            p99 <= bar_ms,
        ),
        (
            f"  age p50, first / last {WINDOW_S:g} s [ms]",
            f"{first_p50:.1f} / {last_p50:.1f}",
            "last <= first + 10 %",
            last_p50 <= 1.1 * first_p50,
        ),
    ]
    if duration_s < 3 * WINDOW_S:
        rows[-1] = (*rows[-1][:3], None)  # windows overlap: shown, not judged
    return rows


class Run:
    """One endpoint, both directions through its own slow link."""

    def __init__(self, core: RosCore, log_dir: Path, endpoint: Any, duration_s: float) -> None:
        self.core, self.log_dir, self.endpoint, self.duration_s = core, log_dir, endpoint, duration_s

    def node(self, name: str, *args: str) -> ManagedProcess:
        return ManagedProcess([*ROSNODE, *args], self.core.env, self.log_dir, name)

    def _link(self) -> SlowLink:
        """The Wi-Fi-like link between the client and the endpoint, the same both ways."""
        return SlowLink(
            ("127.0.0.1", self.endpoint.port),
            LINK_RATE_BPS,
            LINK_DELAY_S,
            LINK_BUFFER_BYTES,
            max_seconds=self.duration_s + 120,
        )

    def down(self) -> dict[str, Received]:
        received = {topic: Received(kind) for kind, topic, _ in DOWN}
        with self._link() as link:
            client = TcpClient("127.0.0.1", link.port, reconnect=False).connect(timeout=10.0)
            try:
                for kind, topic, _ in DOWN:
                    offset = HEADER_OFFSETS.get(kind, 0)
                    arrivals = received[topic].arrivals

                    def record(payload: bytes, arrivals: list = arrivals, offset: int = offset) -> None:
                        now = time.monotonic_ns()
                        arrivals.append((now, now - read_stamp(payload, offset)[1]))

                    client.subscribe(topic, MESSAGE_KINDS[kind][0], record)
                stream = self.node(
                    "stream",
                    "stream",
                    "--seconds",
                    str(self.duration_s),
                    *[arg for kind, topic, hz in DOWN for arg in ("--stream", f"{kind}:{topic}:{hz}")],
                )
                result = wait_result(stream, self.duration_s + 60)
                time.sleep(1.0)  # what is still on the link
            finally:
                client.close()
        for topic, count in result["sent"].items():
            received[topic].sent = count
        return received

    def up(self) -> dict[str, Received]:
        listener = self.node(
            "ages",
            "ages",
            "--seconds",
            str(self.duration_s + 8),
            "--idle",
            str(AGES_IDLE_S),
            *[arg for kind, topic, _ in UP for arg in ("--listen", f"{kind}:{topic}")],
        )
        received = {topic: Received(kind) for kind, topic, _ in UP}
        with self._link() as link:
            client = TcpClient("127.0.0.1", link.port, reconnect=False).connect(timeout=10.0)
            sender = EngineSender(client)
            try:
                for kind, topic, _ in UP:
                    client.register_publisher(topic, MESSAGE_KINDS[kind][0], queue_size=10)
                listener.wait_for_output("CONNECTED", 30)
                sender.start()
                producers = [
                    threading.Thread(target=self._produce, args=(sender, kind, topic, hz, received[topic]))
                    for kind, topic, hz in UP
                ]
                for producer in producers:
                    producer.start()
                for producer in producers:
                    producer.join(self.duration_s + 30)
                time.sleep(1.0)
            finally:
                sender.stop()
                client.close()
        result = wait_result(listener, self.duration_s + 60)
        for topic, pairs in result["arrivals"].items():
            received[topic].arrivals = [(at, age) for at, age in pairs]
        return received

    def _produce(self, sender: EngineSender, kind: str, topic: str, hz: int, received: Received) -> None:
        """Messages stamped on a fixed schedule, handed to the engine's sender."""
        template, offset = MESSAGE_KINDS[kind][1](), HEADER_OFFSETS.get(kind, 0)
        for seq in paced(hz, int(self.duration_s * hz), self.duration_s + 5):
            sender.put(topic, stamped(template, seq, offset=offset), latest_only=kind == "vga_image")
            received.sent += 1


class EngineSender:
    """How a game engine's ROS connection should send (the up direction's client): one thread writes, small
    messages first, and of a camera's frames only the newest waiting one (a send queue of one per image topic)."""

    def __init__(self, client: TcpClient) -> None:
        self.client = client
        self._small: list[tuple[str, bytes]] = []
        self._latest: dict[str, bytes] = {}
        self._ready = threading.Condition()
        self._stopped = False
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        with self._ready:
            self._stopped = True
            self._ready.notify()
        self._thread.join(10)

    def put(self, topic: str, payload: bytes, latest_only: bool) -> None:
        with self._ready:
            if latest_only:
                self._latest[topic] = payload
            else:
                self._small.append((topic, payload))
            self._ready.notify()

    def _run(self) -> None:
        while True:
            with self._ready:
                while not (self._small or self._latest or self._stopped):
                    self._ready.wait(1.0)
                if self._stopped:
                    return
                if self._small:
                    batch, self._small = self._small, []
                else:
                    topic = next(iter(self._latest))
                    batch = [(topic, self._latest.pop(topic))]
            for topic, payload in batch:
                self.client.publish(topic, payload)


def wait_result(process: ManagedProcess, timeout: float) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while process.process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    if process.process.poll() is None:
        kill_process(process.process)
        raise RuntimeError(f"{process.log_path.name} did not finish within {timeout:.0f} s")
    for line in process.output().splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT ") :])
    raise RuntimeError(f"{process.log_path.name} printed no RESULT:\n{process.output()[-2000:]}")


def start_original(core: RosCore, log_dir: Path, source: Path) -> ManagedProcess:
    """Unity's original endpoint from `source` (its Python package directory's parent), on a free port."""
    port = free_port()
    env = dict(core.env, PYTHONPATH=os.pathsep.join([str(source), core.env.get("PYTHONPATH", "")]))
    launcher = (
        "import rospy; from ros_tcp_endpoint import TcpServer; rospy.init_node('unity_endpoint'); "
        "server = TcpServer(rospy.get_name()); server.start(); rospy.spin()"
    )
    process = ManagedProcess(
        ["/usr/bin/python3", "-c", launcher, "_tcp_ip:=127.0.0.1", f"_tcp_port:={port}"], env, log_dir, "unity_endpoint"
    )
    time.sleep(3.0)  # it prints nothing when it listens
    process.port = port  # type: ignore[attr-defined]
    return process


ORIGINAL = "Unity's original"


def _ages(first_ms: float, second_ms: float) -> str:
    """Two ages in one unit: ms, or s once the larger is a second or more."""
    if max(first_ms, second_ms) >= 1000:
        return f"{first_ms / 1000:.1f} / {second_ms / 1000:.1f} s"
    return f"{first_ms:.0f} / {second_ms:.0f} ms"


def down_table(sides: list[tuple[str, dict[str, Received] | None]], bars: Bars) -> str:
    """README's table of the client's side (down) as markdown (pure): per topic, each side's arrivals and ages, and
    the bar; the image's median age in the first and last window. A side that did not run (None: no --original)
    reads "not run", so the table's columns are the same with or without it."""
    header = ["topic", *(f"{name}: received, age p50 / p99" for name, _ in sides), "bar (p99)"]
    rows = []
    for kind, topic, _ in DOWN:
        cells = [topic.rsplit("/", 1)[-1]]
        for _, received in sides:
            got = None if received is None else received[topic]
            if got is None or len(got.arrivals) < 2:
                cells.append("not run" if got is None else f"{len(got.arrivals)}/{got.sent}")
                continue
            ages_ms = [age / 1e6 for _, age in got.arrivals]
            start, end = got.arrivals[0][0], got.arrivals[-1][0]
            count = f"{(len(got.arrivals) - 1) / ((end - start) / 1e9):.1f} Hz" if kind == "vga_image" else ""
            count = count or f"{len(got.arrivals)}/{got.sent}"
            cells.append(f"{count}, {_ages(percentile(ages_ms, 50), percentile(ages_ms, 99))}")
        bar_s = bars.image_p99_s if kind == "vga_image" else bars.small_p99_s
        rows.append([*cells, f"{bar_s * 1000:.0f} ms"])
    image = DOWN[0][1]
    creep = [f"image age p50, first / last {WINDOW_S:g} s"]
    for _, received in sides:
        got = None if received is None else received[image]
        if got is None or len(got.arrivals) < 2:
            creep.append("not run" if got is None else "")
            continue
        start, end = got.arrivals[0][0], got.arrivals[-1][0]
        first = [age / 1e6 for at, age in got.arrivals if at - start <= WINDOW_S * 1e9]
        last = [age / 1e6 for at, age in got.arrivals if end - at <= WINDOW_S * 1e9]
        creep.append(_ages(percentile(first, 50), percentile(last, 50)))
    rows.append([*creep, "last <= first + 10 %"])
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in rows])


def print_rows(title: str, rows: list[tuple[str, str, str, bool | None]]) -> None:
    widths = [
        max(len(name) for name, _, _, _ in rows),
        max(len(value) for _, value, _, _ in rows),
        max(len(bar) for _, _, bar, _ in rows),
    ]
    print(title)
    for name, value, bar, met in rows:
        verdict = "" if met is None else "PASS" if met else "MISS"
        print(f"  {name.ljust(widths[0])}  {value.ljust(widths[1])}  {bar.ljust(widths[2])}  {verdict}".rstrip())
    verdicts = [met for *_, met in rows if met is not None]
    print(f"  {sum(verdicts)}/{len(verdicts)} bars met")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="15 s each way instead of 60 s")
    parser.add_argument("--seconds", type=float, help="seconds each way (default 60, --quick 15)")
    parser.add_argument("--ab", metavar="REVISION", help="also run REVISION's endpoint (a git worktree)")
    parser.add_argument(
        "--original",
        type=Path,
        metavar="DIR",
        help="also run Unity's original endpoint, its ros_tcp_endpoint package in DIR",
    )
    parser.add_argument("--only", choices=("down", "up"), help="one direction only")
    parser.add_argument("--keep-logs", action="store_true")
    parser.add_argument(
        "--markdown",
        action="store_true",
        help="also print README's table of the client's side as markdown (tests.doc_figures rewrites README with it)",
    )
    args = parser.parse_args(argv)
    duration = args.seconds or (15.0 if args.quick else 60.0)
    if duration <= 0 or duration > 600:
        parser.error(f"--seconds must be in (0, 600], not {duration:g}")
    if args.original is not None and not (args.original / "ros_tcp_endpoint").is_dir():
        parser.error(f"--original: no ros_tcp_endpoint package in {args.original}")
    image_bytes = len(MESSAGE_KINDS["vga_image"][1]())
    bars = Bars(image_bytes * 8 / LINK_RATE_BPS, LINK_BUFFER_BYTES * 8 / LINK_RATE_BPS, LINK_DELAY_S)
    print(
        f"Freshness over a slow link: {LINK_RATE_BPS / 1e6:g} Mbit/s, {LINK_DELAY_S * 1000:g} ms each way, "
        f"{LINK_BUFFER_BYTES // 1024} KiB queue; T_img {bars.image_s * 1000:.1f} ms ({image_bytes:,} B), "
        f"T_buf {bars.buffer_s * 1000:.1f} ms, D {bars.delay_s * 1000:g} ms; {duration:g} s each way; "
        f"{os.cpu_count()} CPUs",
        flush=True,
    )
    core = RosCore()
    failed = True
    try:
        with contextlib.ExitStack() as stack:
            sides: list[tuple[str, Any]] = [("this tree", None)]
            if args.ab is not None:
                sides.append((args.ab, stack.enter_context(worktree_of(args.ab))))
            if args.original is not None:
                sides.append((ORIGINAL, args.original))
            downs: dict[str, dict[str, Received]] = {}
            for index, (name, where) in enumerate(sides):
                log_dir = core.tmp / f"side{index}"
                log_dir.mkdir()
                endpoint = (
                    start_original(core, log_dir, where)
                    if name == ORIGINAL
                    else start_endpoint(core.env, log_dir, where, (), f"fresh_endpoint_{index}")
                )
                try:
                    run = Run(core, log_dir, endpoint, duration)
                    for direction in (args.only,) if args.only else ("down", "up"):
                        print(f"[{name}: {direction} ...]", file=sys.stderr, flush=True)
                        received = getattr(run, direction)()
                        if direction == "down":
                            downs[name] = received
                        rows = [row for topic, got in received.items() for row in summary(topic, got, bars, duration)]
                        print_rows(f"{name}, {direction}:", rows)
                finally:
                    kill_process(endpoint.process)
            if args.markdown:  # a side whose down direction did not run reads "not run"
                shown = [(name, downs.get(name)) for name, _ in sides]
                if args.original is None:
                    shown.append((ORIGINAL, None))
                print("\n" + down_table(shown, bars))
        failed = False
    finally:
        stop_core(core, args.keep_logs or failed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
