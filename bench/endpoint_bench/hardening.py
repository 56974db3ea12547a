"""Phase 6: hardening. (a) a 4 GiB length prefix beside a client's 1 kHz stream: the endpoint's RSS and that
client's longest gap; (b) a client that subscribes and never reads: RSS growth, and what a good client still gets."""

from __future__ import annotations

import socket
import struct
import time

from bench.endpoint_bench.harness import Harness
from bench.endpoint_bench.records import Arrivals, Row
from bench.messages import MESSAGE_NAME
from bridge import protocol
from measuring.procfs import MiB, RssSampler
from measuring.stats import percentile

FREEZE_GAP_MS = 50.0  # a 1 kHz stream pausing longer than this counts as frozen


def huge_prefix(harness: Harness) -> None:
    topic = "/bench/stream_a"
    victim = Arrivals(keep_detail=True)
    outcomes: list[str] = []
    with harness.clients_closed():
        harness.client().subscribe(topic, MESSAGE_NAME, victim)
        time.sleep(0.3)
        rate = harness.node("rate", "--topic", topic, "--hz", "1000", "--seconds", "8", "--delay", "0.5")
        rate.wait_for_output("PUBLISHING", 30)
        sampler = RssSampler(harness.pid, 0.005).start()
        time.sleep(1.5)
        event_start = time.monotonic()
        destination = b"/bench/evil"
        outcomes.append(
            huge_length_attack(
                harness.endpoint.port,
                struct.pack("<I", len(destination)) + destination + struct.pack("<I", 0xFFFFFFF0),
            )
        )
        outcomes.append(huge_length_attack(harness.endpoint.port, struct.pack("<I", 0xFFFFFFF0)))
        event_end = time.monotonic()
        time.sleep(1.0)
        sampler.stop()
        harness.result(rate, 40)
    baseline = sampler.between(event_start - 1.0, event_start)
    during = sampler.between(event_start, event_end + 1.0)
    increase = (max(during) - min(baseline)) / MiB if baseline and during else float("nan")
    gap_during = max_gap_ms(victim.times_ns, event_start, event_end + 1.0)
    gap_before = max_gap_ms(victim.times_ns, event_start - 1.0, event_start)
    harness.rows.append(
        Row(
            "4 GiB length prefix: endpoint RSS increase [MiB]",
            f"{increase:.2f}",
            target="< 10 MiB",
            ok=increase < 10.0,
        )
    )
    harness.rows.append(
        Row(
            "4 GiB prefix: other client's max gap [ms]",
            f"{gap_during:.1f}",
            f"{gap_before:.1f} before",
            target=f"< {FREEZE_GAP_MS:.0f} ms (no freeze)",
            ok=gap_during < FREEZE_GAP_MS,
        )
    )
    harness.rows.append(Row("  attacker connection (payload len, dest len)", "; ".join(outcomes)))


def never_reader(harness: Harness) -> None:
    topic = "/bench/stream_b"
    soak = harness.settings.soak_s
    good = Arrivals(keep_detail=True)
    with harness.clients_closed():
        harness.client().subscribe(topic, MESSAGE_NAME, good)
        stalled = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        try:
            stalled.connect(("127.0.0.1", harness.endpoint.port))
            stalled.sendall(
                protocol.KEEPALIVE_FRAME
                + protocol.encode_syscommand("__subscribe", {"topic": topic, "message_name": MESSAGE_NAME})
            )
            time.sleep(0.5)
            baseline = harness.rss()
            rate = harness.node("rate", "--topic", topic, "--hz", "1000", "--seconds", str(soak), "--delay", "0.5")
            rate.wait_for_output("PUBLISHING", 30)
            samples: list[int] = []
            deadline = time.monotonic() + soak
            while time.monotonic() < deadline:
                samples.append(harness.rss())
                time.sleep(0.5)
            sent = harness.result(rate, 40)["sent"]
            good.wait_idle(1.0, 10.0)
            samples.append(harness.rss())
        finally:
            stalled.close()
    growth = (max(samples) - baseline) / MiB
    delivered = len({seq for seq in good.seqs if seq < sent}) / max(sent, 1)
    harness.rows.append(
        Row(
            f"Never-reading client, {soak:.0f} s @ 1 kHz: RSS growth [MiB]",
            f"{growth:.2f}",
            target="< 10 MiB",
            ok=growth < 10.0,
        )
    )
    harness.rows.append(Row("  RSS at end - at start [MiB]", f"{(samples[-1] - baseline) / MiB:.2f}"))
    harness.rows.append(
        Row("  well-behaved client on the same topic: delivered", f"{delivered:.4f}", target=f"({sent:,} published)")
    )
    if good.latencies_us:
        harness.rows.append(
            Row(
                "  its one-way latency p99/max [ms]",
                "/".join(f"{percentile(good.latencies_us, q) / 1000:.2f}" for q in (99, 100)),
            )
        )


def huge_length_attack(port: int, header: bytes) -> str:
    """Send a keepalive and then a frame header announcing ~4 GiB; describe how the endpoint answers."""
    with socket.create_connection(("127.0.0.1", port), timeout=5.0) as sock:
        sock.sendall(protocol.KEEPALIVE_FRAME + header)
        received = b""
        deadline = time.monotonic() + 3.0
        closed = False
        try:
            while time.monotonic() < deadline:
                sock.settimeout(max(0.01, deadline - time.monotonic()))
                data = sock.recv(65536)
                if not data:
                    closed = True
                    break
                received += data
        except socket.timeout:
            pass
        except ConnectionResetError:
            closed = True
        error = b"__error" in received
        if not closed:  # still open: push 1 MiB of junk, as a client streaming a huge body would
            try:
                sock.sendall(b"\xab" * MiB)
            except OSError:
                pass
        return ("__error" if error else "no __error") + (" + closed" if closed else ", still open")


def max_gap_ms(times_ns: list[int], start: float, end: float) -> float:
    """Longest gap between consecutive arrivals, over arrivals in [start, end] (monotonic seconds)."""
    window = [t for t in times_ns if start * 1e9 <= t <= end * 1e9]
    if len(window) < 2:
        return float("inf")
    return max(b - a for a, b in zip(window, window[1:])) / 1e6
