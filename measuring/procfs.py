"""A process's figures as Linux's /proc gives them: CPU seconds, resident memory, threads and descriptors, sampled
once or on a thread; and the sockets listening on a port. The one place the tests and benchmarks read /proc."""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from measuring.errors import MeasuringError

__all__ = [
    "MiB",
    "ProcessFigures",
    "RssSampler",
    "bytes_read",
    "command_lines",
    "cpu_seconds",
    "figures",
    "listening_addresses",
    "rss_bytes",
]

MiB = 1024 * 1024
_CLOCK_TICK_S = 1.0 / os.sysconf("SC_CLK_TCK")


def _read(path: str) -> str:
    try:
        return Path(path).read_text()
    except OSError as error:
        raise MeasuringError(f"cannot read {path}: {error.strerror}") from error


def cpu_seconds(pid: int) -> float:
    """utime + stime of the whole process (all its threads) so far."""
    # the command name in parentheses may hold spaces: the fields are counted after its closing parenthesis
    fields = _read(f"/proc/{pid}/stat").rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) * _CLOCK_TICK_S  # fields 14 and 15 of proc(5)


def rss_bytes(pid: int) -> int:
    """The process's resident memory (VmRSS)."""
    for line in _read(f"/proc/{pid}/status").splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise MeasuringError(f"process {pid} has no VmRSS (a zombie or a kernel thread)")


def bytes_read(pid: int) -> int:
    """What the process has read so far, its sockets and pipes included (rchar of /proc/PID/io)."""
    for line in _read(f"/proc/{pid}/io").splitlines():
        if line.startswith("rchar:"):
            return int(line.split()[1])
    raise MeasuringError(f"process {pid} has no rchar in its io")


def command_lines() -> dict[int, list[bytes]]:
    """Every process's argument vector, by PID (a process gone while they are read is left out)."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            found[int(entry.name)] = (entry / "cmdline").read_bytes().split(b"\0")[:-1]
        except OSError:
            continue
    return found


@dataclass(frozen=True)
class ProcessFigures:
    """What a process holds at one moment."""

    threads: int
    descriptors: int
    rss_mib: float

    def __str__(self) -> str:
        return f"{self.threads} threads, {self.descriptors} descriptors, {self.rss_mib:.1f} MiB RSS"


def figures(pid: int) -> ProcessFigures:
    """The process's threads, open descriptors and RSS now."""
    try:
        threads, descriptors = len(os.listdir(f"/proc/{pid}/task")), len(os.listdir(f"/proc/{pid}/fd"))
    except OSError as error:
        raise MeasuringError(f"cannot list process {pid}'s threads or descriptors: {error.strerror}") from error
    return ProcessFigures(threads, descriptors, rss_bytes(pid) / MiB)


class RssSampler:
    """Samples a process's RSS every `interval_s` on a thread of its own, between start() and stop(); a process
    that goes ends the sampling."""

    def __init__(self, pid: int, interval_s: float) -> None:
        self.pid = pid
        self.interval_s = interval_s
        self.samples: list[tuple[float, int]] = []  # (monotonic s, bytes)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="rss-sampler", daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self.samples.append((time.monotonic(), rss_bytes(self.pid)))
            except MeasuringError:
                return
            self._stop.wait(self.interval_s)

    def start(self) -> RssSampler:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)

    def between(self, start: float, end: float) -> list[int]:
        """The samples taken from `start` to `end` (monotonic s)."""
        return [rss for at, rss in self.samples if start <= at <= end]


def listening_addresses(port: int) -> set[str]:
    """Local addresses (hex, as /proc/net/tcp and tcp6 write them) of the sockets listening on `port`."""
    found = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        if not os.path.exists(table):
            continue
        for line in _read(table).splitlines()[1:]:
            fields = line.split()
            address, port_hex = fields[1].rsplit(":", 1)
            if int(port_hex, 16) == port and fields[3] == "0A":  # 0A = LISTEN
                found.add(address)
    return found
