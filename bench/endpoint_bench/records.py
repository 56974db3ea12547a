"""What a phase records: a table row, the arrivals a TcpClient counts, one throughput flow and the median of several."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from bench.messages import read_stamp


@dataclass
class Row:
    name: str
    value: str
    ceiling: str = ""
    ratio: str = ""
    target: str = ""
    ok: bool | None = None  # None: informational


@dataclass
class Arrivals:
    """TcpClient callback recording arrival count, first/last time, sequence numbers and one-way latency."""

    keep_detail: bool = False
    count: int = 0
    first_ns: int = 0
    last_ns: int = 0
    seqs: set[int] = field(default_factory=set)
    times_ns: list[int] = field(default_factory=list)
    latencies_us: list[float] = field(default_factory=list)

    def __call__(self, payload: bytes) -> None:
        now = time.monotonic_ns()
        if self.count == 0:
            self.first_ns = now
        self.count += 1
        self.last_ns = now
        if self.keep_detail:
            seq, stamp_ns = read_stamp(payload)
            self.seqs.add(seq)
            self.times_ns.append(now)
            self.latencies_us.append((now - stamp_ns) / 1000.0)

    def rate(self) -> float:
        return rate_of(self.count, self.first_ns, self.last_ns)

    def wait_idle(self, idle_s: float, timeout_s: float) -> None:
        """Until nothing arrived for `idle_s` (or `timeout_s` passed)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.count and time.monotonic_ns() - self.last_ns > idle_s * 1e9:
                return
            time.sleep(0.05)


@dataclass(frozen=True)
class Flow:
    """One throughput run: arrival rate [msg/s], messages received and sent, endpoint CPU seconds used."""

    rate: float
    received: int
    sent: int
    cpu_s: float


def median_flow(flows: list[Flow]) -> Flow:
    """The round with the median rate (the lower middle one for an even count)."""
    ordered = sorted(flows, key=lambda flow: flow.rate)
    return ordered[(len(ordered) - 1) // 2]


def rate_range(flows: list[Flow]) -> str:
    """The range of several rounds' rates, " [lowest-highest]", shown beside their median; "" for one round."""
    rates = sorted(flow.rate for flow in flows)
    return f" [{rates[0]:.1f}-{rates[-1]:.1f}]" if len(rates) > 1 else ""


def rate_of(count: int, first_ns: int, last_ns: int) -> float:
    return (count - 1) / ((last_ns - first_ns) / 1e9) if count > 1 and last_ns > first_ns else 0.0
