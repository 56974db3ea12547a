"""The endpoint in a hostile world, at length: what abusive clients and a failing master cost it, in figures.

Run: `.venv/bin/python -m bench.chaos_bench [--quick] [--only PHASE ...] [--fuzz-s S] [--seconds S]` from the
repository root.

Each phase starts its own roscore (free port, private ROS_HOME) and endpoint, and prints the endpoint's threads,
descriptors and RSS (measuring.procfs.figures) before, at the worst moment and after, plus what a well-behaved client
saw beside the abuse. The short, asserting variants of the same abuse are tests (tests/integration/test_bridge_*):
this script measures; it judges nothing.

  churn      2,000 connections reset abruptly (RST) beside a steady client streaming 100 Hz each way
  flood      one client publishes 10,000 topics and another subscribes 1,100 (the per-client limit stops them)
  unread     a client sends __topic_list 50 at a time for 30 s and never reads the answers (big graph)
  slow       200 connections, one byte a second, never completing a frame (from 10 loopback addresses)
  tokens     2,000 wrong tokens as fast as the verdicts come, one connection at a time
  master     roscore killed and started again on its port, 5 times: seconds until every registration is back
  fuzz       4 clients send mutated streams for --fuzz-s (default 120 s) beside a 100 Hz client that pings:
             RSS over time, the good client's longest gap between messages and its ping p99
  capacity   100 slow senders that come back at once hold the 64 slots; a fresh client probes once a second
  services   seven cases of service calls, each call ended within --service-timeout + 2 s, threads back
             (capacity and services: bench/chaos_cases.py, best run beside CPU burners that oversubscribe the cores)
Every loop is bounded in count and time; every process is stopped by PID.

One concern, and a long one: each phase is a short script of its own abuse, read top to bottom where it is; they share
only the set-up, the measuring and the rows (two more phases are bench/chaos_cases.py).
"""

from __future__ import annotations

import argparse
import logging
import os
import socket
import sys
import threading
import time
import xmlrpc.client
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from bench import chaos_cases
from bridge import protocol
from bridge.client import TcpClient
from measuring.abuse import LOOPBACK, FuzzStats, churn, fuzz_client
from measuring.endpoint import settled
from measuring.errors import MeasuringError
from measuring.frames import Frame, feed
from measuring.procfs import ProcessFigures, figures
from measuring.stats import percentile
from sim.processes import EndpointProcess, ManagedProcess, RosCore, wait_for

PHASES = ("churn", "flood", "unread", "slow", "tokens", "master", "fuzz", "capacity", "services")
STRING = "std_msgs/String"
TOKEN = "bench-secret"


def string_payload(text: str) -> bytes:
    data = text.encode()
    return len(data).to_bytes(4, "little") + data


@contextmanager
def endpoint_on_own_core(*options: str, name: str = "chaos_endpoint") -> Iterator[tuple[RosCore, EndpointProcess]]:
    core = RosCore()
    endpoint = None
    try:
        endpoint = EndpointProcess(core.env, core.tmp, name=name, extra=options)
        settled(core, f"/{name}")
        yield core, endpoint
    finally:
        if endpoint is not None:
            endpoint.stop()
        core.stop()


def system_state(master_uri: str) -> Any:
    """The master's publishers, subscribers and services, each a list of [name, [node, ...]] (untyped XML-RPC)."""
    master: Any = xmlrpc.client.ServerProxy(master_uri)
    return master.getSystemState("/bench")[2]


def settle(pid: int, baseline: ProcessFigures, timeout: float = 30.0) -> ProcessFigures:
    """The figures once threads and descriptors stop falling (or `timeout`), for the 'after' column."""
    deadline = time.monotonic() + timeout
    last = figures(pid)
    while time.monotonic() < deadline:
        time.sleep(1)
        now = figures(pid)
        if (now.threads, now.descriptors) == (last.threads, last.descriptors) and now.threads <= baseline.threads + 3:
            return now
        last = now
    return last


def row(phase: str, before: ProcessFigures, worst: ProcessFigures, after: ProcessFigures, note: str) -> None:
    print(f"{phase:<8} before: {before}\n{'':<8} worst:  {worst}\n{'':<8} after:  {after}\n{'':<8} {note}", flush=True)


class Worst:
    """The largest threads, descriptors and RSS seen, sampled on a thread of its own every 0.2 s."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.figures = figures(pid)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(0.2):
            try:
                now = figures(self.pid)
            except MeasuringError:  # the process has gone
                return
            self.figures = ProcessFigures(
                max(now.threads, self.figures.threads),
                max(now.descriptors, self.figures.descriptors),
                max(now.rss_mib, self.figures.rss_mib),
            )

    def stop(self) -> ProcessFigures:
        self._stop.set()
        self._thread.join()
        return self.figures


# --- phases ------------------------------------------------------------------------------------------------------


def phase_churn(quick: bool, limit_s: float) -> None:
    count = 300 if quick else 2000
    with endpoint_on_own_core("--publisher-grace", "0") as (core, endpoint):
        received: list[bytes] = []
        steady = TcpClient(LOOPBACK, endpoint.port, reconnect=False).connect(10)
        steady.subscribe("/steady", STRING, received.append)
        steady.register_publisher("/steady", STRING, queue_size=1000)
        steady.topic_list()
        before = figures(endpoint.pid)
        worst = Worst(endpoint.pid)
        made: list[int] = []  # how many resets churn made (fewer than `count` when cut short)
        deadline = time.monotonic() + min(300, limit_s)
        churner = threading.Thread(target=lambda: made.append(churn(endpoint.port, count, 1, deadline)))
        started = time.monotonic()
        churner.start()
        sent = 0
        while churner.is_alive():  # the client's own messages come back to it (another client would see them)
            steady.publish("/steady", string_payload(f"{sent}"))
            sent += 1
            time.sleep(0.01)
        churner.join()
        took = time.monotonic() - started
        steady.close()
        after = settle(endpoint.pid, before)
        row(
            "churn",
            before,
            worst.stop(),
            after,
            f"{made[0]} resets in {took:.1f} s ({made[0] / took:.0f}/s); steady client: {sent} published, "
            f"{steady.connections} connection(s), {len(steady.errors)} errors",
        )


def phase_flood(quick: bool) -> None:
    publish_count, subscribe_count = (1000, 400) if quick else (10_000, 1_100)
    with endpoint_on_own_core("--publisher-grace", "0") as (core, endpoint):
        before = figures(endpoint.pid)
        worst = Worst(endpoint.pid)
        publisher = TcpClient(LOOPBACK, endpoint.port, reconnect=False).connect(10)
        subscriber = TcpClient(LOOPBACK, endpoint.port, reconnect=False).connect(10)
        started = time.monotonic()
        for index in range(publish_count):
            publisher.register_publisher(f"/flood/p{index}", STRING)
        for index in range(subscribe_count):
            subscriber.subscribe(f"/flood/s{index}", STRING, lambda payload: None)
        publisher.topic_list(timeout=120)
        subscriber.topic_list(timeout=120)
        took = time.monotonic() - started

        def registered() -> int:  # the master link registers in the background: count once it is done
            state = system_state(core.uri)
            return sum(
                1
                for part in state[:2]
                for name, nodes in part
                if name.startswith("/flood/") and "/chaos_endpoint" in nodes
            )

        limit = 2 * 256
        wait_for(lambda: registered() >= limit, 60, f"{limit} registrations on the master")
        on_master = registered()
        publisher.close()
        subscriber.close()
        after = settle(endpoint.pid, before)
        row(
            "flood",
            before,
            worst.stop(),
            after,
            f"{publish_count} publishers + {subscribe_count} subscriptions asked for in {took:.1f} s; "
            f"{on_master} registered with the master, the rest refused past the per-client limit",
        )


def phase_unread(quick: bool, limit_s: float) -> None:
    duration = min(8 if quick else 30, limit_s)
    with endpoint_on_own_core() as (core, endpoint):
        helper = TcpClient(LOOPBACK, endpoint.port, reconnect=False).connect(10)
        for index in range(200):  # a graph whose topic list is some 40 kB
            helper.register_publisher(f"/unread/topic_{index}_" + "x" * 160, STRING)
        helper.topic_list(timeout=60)
        before = figures(endpoint.pid)
        worst = Worst(endpoint.pid)
        silent = socket.socket()
        silent.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        silent.connect((LOOPBACK, endpoint.port))
        query = protocol.encode_syscommand("__topic_list", {}) * 50
        sent = 0
        started = time.monotonic()
        dropped_after = None
        while time.monotonic() - started < duration:
            try:
                silent.sendall(query)
            except OSError:  # its receive window shut for --dead-peer-timeout: the endpoint let it go
                dropped_after = time.monotonic() - started
                break
            sent += 50
            time.sleep(0.02)
        during = worst.stop()
        helper.topic_list()  # still served
        silent.close()
        helper.close()
        after = settle(endpoint.pid, before)
        row(
            "unread",
            before,
            during,
            after,
            f"{sent} __topic_list, never read: RSS grew {during.rss_mib - before.rss_mib:.1f} MiB at most (the "
            "original grew about 6 MiB/s); "
            + (
                f"the endpoint dropped the client after {dropped_after:.0f} s (its window shut for --dead-peer-timeout)"
                if dropped_after
                else f"connected for all {duration} s"
            ),
        )


def phase_slow(quick: bool, limit_s: float) -> None:
    count = 50 if quick else 200
    with endpoint_on_own_core("--frame-timeout", "10") as (core, endpoint):
        before = figures(endpoint.pid)
        worst = Worst(endpoint.pid)
        frame = protocol.encode_syscommand("__topic_list", {})
        sockets = []
        for index in range(count):
            sock = socket.socket()
            sock.bind((f"127.0.0.{2 + index % 10}", 0))
            sock.settimeout(1)
            try:
                sock.connect((LOOPBACK, endpoint.port))
                sockets.append(sock)
            except OSError:
                sock.close()
        started = time.monotonic()
        alive = len(sockets)
        position = 0
        held_figures: ProcessFigures | None = None
        probes = served = 0
        while alive and time.monotonic() - started < min(45, limit_s) and position < len(frame) - 1:
            alive = 0
            for sock in sockets:  # one byte a second each, never the last one
                try:
                    sock.send(frame[position : position + 1])
                    alive += 1
                except OSError:
                    pass
            position += 1
            time.sleep(1)
            if position == 2:
                held_figures = figures(endpoint.pid)
            elif position > 2:  # a fresh client from another address, once a second
                probes += 1
                served += fresh_client_served(endpoint.port, "127.0.0.100")
        held = alive
        cut_after = time.monotonic() - started
        for sock in sockets:
            sock.close()
        after = settle(endpoint.pid, before)
        row(
            "slow",
            before,
            worst.stop(),
            after,
            f"{count} connections dribbling a byte a second from 10 addresses (16 per address served, the rest "
            f"turned away): {held} still open after {cut_after:.0f} s (--frame-timeout 10); a fresh client from "
            f"another address, once a second: served {served}/{probes}",
        )
        if held_figures is not None:
            connections = held_figures.descriptors - before.descriptors  # one descriptor each
            print(
                f"{'':12} per slow connection held ({connections} held): "
                f"{(held_figures.threads - before.threads) / max(connections, 1):.2f} threads, "
                f"{(held_figures.rss_mib - before.rss_mib) * 1024 / max(connections, 1):.0f} KiB RSS"
            )


def fresh_client_served(port: int, source: str) -> bool:
    """A new connection from `source` gets the handshake (it is closed again at once)."""
    with socket.socket() as sock:
        sock.bind((source, 0))
        sock.settimeout(5)
        try:
            sock.connect((LOOPBACK, port))
            decoder = protocol.FrameDecoder()
            while True:
                data = sock.recv(65536)
                if not data:
                    return False
                frames = feed(decoder, data)
                if frames:
                    return isinstance(frames[0], Frame) and frames[0].destination == "__handshake"
        except OSError:
            return False


def phase_tokens(quick: bool, limit_s: float) -> None:
    duration = min(10 if quick else 30, limit_s)
    with endpoint_on_own_core("--auth-token", TOKEN) as (core, endpoint):
        before = figures(endpoint.pid)
        verdicts = 0
        started = time.monotonic()
        while verdicts < 2000 and time.monotonic() - started < duration:
            with socket.create_connection((LOOPBACK, endpoint.port), timeout=60) as sock:
                sock.sendall(protocol.encode_syscommand("__auth", {"token": f"guess{verdicts}"}))
                while sock.recv(65536):
                    pass
            verdicts += 1
        took = time.monotonic() - started
        right_started = time.monotonic()
        client = TcpClient(LOOPBACK, endpoint.port, reconnect=False, auth_token=TOKEN).connect(10)
        client.topic_list()
        right_took = time.monotonic() - right_started
        client.close()
        logged = sum(
            1
            for line in endpoint.output().splitlines()
            if "authentication failed" in line and "disconnected" not in line
        )
        row(
            "tokens",
            before,
            figures(endpoint.pid),
            figures(endpoint.pid),
            f"{verdicts} wrong-token verdicts in {took:.1f} s (the original answered ~900/s); {logged} log lines; "
            f"the right token from the same address answered in {right_took * 1000:.0f} ms",
        )


def phase_master(quick: bool) -> None:
    rounds = 2 if quick else 5
    core = RosCore()
    endpoint = EndpointProcess(core.env, core.tmp, name="master_endpoint")
    client = TcpClient(LOOPBACK, endpoint.port, reconnect=False).connect(10)
    try:
        for index in range(20):
            client.register_publisher(f"/restart/p{index}", STRING, latch=True)
            client.subscribe(f"/restart/s{index}", STRING, lambda payload: None)
        client.implement_service("/restart/srv", "std_srvs/Trigger", lambda request: b"\x01\x00\x00\x00\x00")
        client.topic_list()
        recoveries = []
        for _ in range(rounds):
            core.stop(keep_logs=True)
            core = RosCore(port=core.port, tmp=core.tmp, remove_tmp=True)
            started = time.monotonic()

            def registered(core: RosCore = core) -> bool:
                state = system_state(core.uri)
                publishers = {name for name, nodes in state[0] if "/master_endpoint" in nodes}
                subscribers = {name for name, nodes in state[1] if "/master_endpoint" in nodes}
                services = {name for name, nodes in state[2] if "/master_endpoint" in nodes}
                return (
                    all(f"/restart/p{i}" in publishers for i in range(20))
                    and all(f"/restart/s{i}" in subscribers for i in range(20))
                    and "/restart/srv" in services
                )

            wait_for(registered, 30, "every registration on the new master")
            recoveries.append(time.monotonic() - started)
        print(
            f"master   20 publishers (latched), 20 subscriptions, 1 service; roscore restarted {rounds} times: "
            f"registered again {min(recoveries):.2f}-{max(recoveries):.2f} s after the new roscore was up "
            f"(the master's identity is checked once a second); client connected throughout: "
            f"{client.is_connected and client.connections == 1}",
            flush=True,
        )
    finally:
        client.close()
        endpoint.stop()
        core.stop()


def phase_fuzz(quick: bool, duration: float) -> None:
    duration = min(duration, 20) if quick else duration
    with endpoint_on_own_core("--publisher-grace", "0", "--service-timeout", "2") as (core, endpoint):
        stream = ManagedProcess([sys.executable, "-c", _STREAM_NODE], core.env, core.tmp, "stream")
        arrivals: list[float] = []
        good = TcpClient(LOOPBACK, endpoint.port, reconnect=False).connect(10)
        good.subscribe("/good_stream", STRING, lambda payload: arrivals.append(time.monotonic()))
        good.topic_list()
        wait_for(lambda: len(arrivals) > 10, 30, "the 100 Hz stream")
        before = figures(endpoint.pid)
        worst = Worst(endpoint.pid)
        stop = threading.Event()
        stats = [FuzzStats() for _ in range(4)]
        fuzzers = [
            threading.Thread(target=fuzz_client, args=(endpoint.port, 7 + i, stop, stats[i]), daemon=True)
            for i in range(4)
        ]
        for fuzzer in fuzzers:
            fuzzer.start()
        first = len(arrivals)
        round_trips: list[float] = []
        rss_samples: list[tuple[float, float]] = []
        started = time.monotonic()
        while time.monotonic() - started < duration:
            round_trips.append(good.ping(timeout=10).round_trip_s)
            if not rss_samples or time.monotonic() - rss_samples[-1][0] - started >= duration / 6:
                rss_samples.append((time.monotonic() - started, figures(endpoint.pid).rss_mib))
            time.sleep(0.1)
        stop.set()
        for fuzzer in fuzzers:
            fuzzer.join(30)
        seen = arrivals[first:]
        gap = max(b - a for a, b in zip(seen, seen[1:])) if len(seen) > 1 else float("nan")
        p99 = percentile(round_trips, 99) if round_trips else float("nan")
        during = worst.stop()
        good.close()
        stream.stop()
        after = settle(endpoint.pid, before)
        curve = ", ".join(f"{at:.0f} s {rss:.0f}" for at, rss in rss_samples)
        row(
            "fuzz",
            before,
            during,
            after,
            f"4 fuzzers, {duration:.0f} s: {sum(s.connections for s in stats)} connections, "
            f"{sum(s.bytes_sent for s in stats) / 2**20:.0f} MiB of mutated streams; RSS MiB over time: {curve}; "
            f"good client: longest gap {gap * 1000:.0f} ms between 100 Hz messages, ping p99 {p99 * 1000:.1f} ms, "
            f"{good.connections} connection(s), {len(good.errors)} errors",
        )


_STREAM_NODE = """
import rospy
from std_msgs.msg import String
rospy.init_node("good_stream", disable_signals=True)
publisher = rospy.Publisher("/good_stream", String, queue_size=100)
rate = rospy.Rate(100)
for index in range(100 * 3600):
    publisher.publish(String(str(index)))
    rate.sleep()
"""


def phase_capacity(quick: bool, limit_s: float) -> None:
    with endpoint_on_own_core("--frame-timeout", "10", name="capacity_endpoint") as (core, endpoint):
        before = figures(endpoint.pid)
        worst = Worst(endpoint.pid)
        note = chaos_cases.phase_capacity(endpoint, min(10 if quick else 40, limit_s))
        row("capacity", before, worst.stop(), settle(endpoint.pid, before), note)


def phase_services() -> None:
    timeout = f"{chaos_cases.SERVICE_TIMEOUT_S:g}"
    with endpoint_on_own_core("--service-timeout", timeout, name="services_endpoint") as (core, endpoint):
        for line in chaos_cases.phase_services(core, endpoint):
            print(f"services {line}", flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smoke run: smaller counts, shorter windows")
    parser.add_argument("--only", nargs="+", choices=PHASES, help="run only these phases")
    parser.add_argument("--fuzz-s", type=float, default=120.0, help="seconds of mutated streams (default 120)")
    parser.add_argument(
        "--seconds",
        type=float,
        help="cut churn, unread, slow and tokens short after this long (a smoke run; their figures then cover less)",
    )
    args = parser.parse_args(argv)
    if args.seconds is not None and args.seconds <= 0:
        parser.error(f"--seconds must be positive, got {args.seconds}")
    limit_s = args.seconds or float("inf")
    if args.fuzz_s <= 0:
        parser.error(f"--fuzz-s must be positive, got {args.fuzz_s}")
    runs: dict[str, Callable[[], None]] = {
        "churn": lambda: phase_churn(args.quick, limit_s),
        "flood": lambda: phase_flood(args.quick),
        "unread": lambda: phase_unread(args.quick, limit_s),
        "slow": lambda: phase_slow(args.quick, limit_s),
        "tokens": lambda: phase_tokens(args.quick, limit_s),
        "master": lambda: phase_master(args.quick),
        "fuzz": lambda: phase_fuzz(args.quick, args.fuzz_s),
        "capacity": lambda: phase_capacity(args.quick, limit_s),
        "services": phase_services,
    }
    logging.getLogger("bridge.client").setLevel(logging.ERROR)  # the refusals are counted, not printed one by one
    print(f"chaos bench, {time.strftime('%Y-%m-%d %H:%M')}, {os.cpu_count()} cores", flush=True)
    for phase in args.only or PHASES:
        runs[phase]()
    return 0


if __name__ == "__main__":
    sys.exit(main())
