"""Phases 3 and 4: small round trips through a rospy relay against rospy alone, and one topic fanned out to ten
clients: delivery, latency and the endpoint's CPU."""

from __future__ import annotations

import time

from bench.endpoint_bench.harness import Harness
from bench.endpoint_bench.records import Arrivals, Row
from bench.endpoint_bench.settings import PUBLISH_QUEUE
from bench.messages import MESSAGE_NAME, paced, read_stamp, stamped
from measuring.procfs import cpu_seconds
from measuring.stats import percentile

FAN_CLIENTS = 10


def round_trips(harness: Harness) -> None:
    relay = harness.node("relay", "--pair", "/bench/ping:/bench/pong", "--pair", "/bench/rping:/bench/rpong")
    relay.wait_for_output("READY", 30)
    relay_pid = relay.process.pid
    tcp: dict[int, tuple[list[float], int, float]] = {}
    with harness.clients_closed():
        client = harness.client()
        rtts_us: list[float] = []

        def on_pong(payload: bytes) -> None:
            rtts_us.append((time.monotonic_ns() - read_stamp(payload)[1]) / 1000.0)

        client.subscribe("/bench/pong", MESSAGE_NAME, on_pong)
        client.register_publisher("/bench/ping", MESSAGE_NAME, queue_size=PUBLISH_QUEUE)
        for seq in paced(100, 3000, 30.0):  # warm-up until the whole loop is connected
            if rtts_us:
                break
            client.publish("/bench/ping", stamped(harness.payload, seq))
        time.sleep(0.5)
        for hz, count in harness.settings.rtt_samples.items():
            rtts_us.clear()
            cpu_before = harness.cpu()
            sent = 0
            for seq in paced(hz, count, count / hz * 1.5 + 2.0):
                client.publish("/bench/ping", stamped(harness.payload, seq))
                sent += 1
            time.sleep(0.5)
            tcp[hz] = (list(rtts_us), sent, harness.cpu() - cpu_before)
    ros: dict[int, tuple[list[float], int, float]] = {}
    for hz, count in harness.settings.rtt_samples.items():
        relay_before = cpu_seconds(relay_pid)
        ping = harness.node(
            "ping", "--out-topic", "/bench/rping", "--in-topic", "/bench/rpong", "--rates", f"{hz}:{count}"
        )
        result = harness.result(ping, count / hz * 1.5 + 60)["rates"][str(hz)]
        ros[hz] = (result["rtts_us"], result["sent"], cpu_seconds(relay_pid) - relay_before)
    relay.stop()

    for hz in harness.settings.rtt_samples:
        mine, sent, cpu_used = tcp[hz]
        theirs, their_sent, relay_cpu = ros[hz]
        if not mine or not theirs:
            harness.rows.append(Row(f"RTT @ {hz} Hz", "no pongs", ok=False))
            continue
        for label, q in (("p50", 50.0), ("p99", 99.0), ("max", 100.0)):
            value, reference = percentile(mine, q) / 1000.0, percentile(theirs, q) / 1000.0
            target, ok = "", None
            if hz == 1000 and label == "p99":
                target, ok = "<= 1.0 ms", value <= 1.0
            if hz == 1000 and label == "max":
                target, ok = "< 10 ms", value < 10.0
            harness.rows.append(
                Row(
                    f"RTT @ {hz} Hz {label} [ms]",
                    f"{value:.3f}",
                    f"{reference:.3f}",
                    f"{value / reference:.2f}",
                    target,
                    ok,
                )
            )
        harness.rows.append(Row(f"  pongs received @ {hz} Hz", f"{len(mine)}/{sent}", f"{len(theirs)}/{their_sent}"))
        harness.rows.append(
            Row(
                f"  CPU s / 10k round trips @ {hz} Hz",
                f"{cpu_used / sent * 1e4:.3f}",
                f"{relay_cpu / their_sent * 1e4:.3f}",
                f"{cpu_used / sent / (relay_cpu / their_sent):.2f}",
                "(ceiling: relay node)",
            )
        )


def fan_out(harness: Harness) -> None:
    window = harness.settings.window_s
    topic = "/bench/fan"
    recorders = [Arrivals(keep_detail=True) for _ in range(FAN_CLIENTS)]
    with harness.clients_closed():
        for recorder in recorders:
            harness.client().subscribe(topic, MESSAGE_NAME, recorder)
        time.sleep(0.5)
        cpu_before = harness.cpu()
        rate = harness.node("rate", "--topic", topic, "--hz", "1000", "--seconds", str(window), "--delay", "1.0")
        sent = harness.result(rate, window + 40)["sent"]
        for recorder in recorders:
            recorder.wait_idle(1.0, 10.0)
        cpu_used = harness.cpu() - cpu_before
    fractions = [len({seq for seq in r.seqs if seq < sent}) / sent for r in recorders]
    latencies = [latency for r in recorders for latency in r.latencies_us]
    harness.rows.append(
        Row(
            f"Fan-out {FAN_CLIENTS} clients x 1 kHz: min delivered",
            f"{min(fractions):.4f}",
            target="1.0000 (all)",
            ok=min(fractions) >= 1.0,
        )
    )
    harness.rows.append(
        Row("  delivered per client", " ".join(f"{f:.3f}" for f in fractions), target=f"({sent:,} published)")
    )
    if latencies:
        harness.rows.append(
            Row(
                "  one-way latency p50/p99/max [ms]",
                "/".join(f"{percentile(latencies, q) / 1000:.2f}" for q in (50, 99, 100)),
            )
        )
    delivered = sum(r.count for r in recorders)
    harness.rows.append(Row("  endpoint CPU s / 10k delivered frames", f"{cpu_used / max(delivered, 1) * 1e4:.3f}"))
