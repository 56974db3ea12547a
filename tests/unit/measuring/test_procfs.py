"""A process's figures from /proc, read on this test's own process and on one that has gone."""

from __future__ import annotations

import mmap
import os
import socket
import subprocess
import sys
import threading
import time

import pytest

from measuring.errors import MeasuringError
from measuring.procfs import (
    MiB,
    RssSampler,
    bytes_read,
    command_lines,
    cpu_seconds,
    figures,
    listening_addresses,
    rss_bytes,
)


def test_cpu_seconds_count_the_work_of_every_thread() -> None:
    before = cpu_seconds(os.getpid())

    def spin() -> None:
        deadline = time.process_time() + 0.1
        while time.process_time() < deadline:
            pass

    worker = threading.Thread(target=spin)
    worker.start()
    worker.join(10)
    assert cpu_seconds(os.getpid()) - before >= 0.05


def test_rss_grows_with_memory_touched() -> None:
    # A mapping of its own: a bytearray may come from heap pages the process already holds (glibc raises its mmap
    # threshold after a large block is freed), and touching those adds nothing to the RSS.
    with mmap.mmap(-1, 32 * MiB) as block:
        before = rss_bytes(os.getpid())
        for page in range(0, len(block), mmap.PAGESIZE):
            block[page] = 1  # the kernel backs a page of an anonymous mapping once it is written
        assert rss_bytes(os.getpid()) - before >= 16 * MiB


def test_figures_count_threads_and_descriptors() -> None:
    here = figures(os.getpid())
    stop = threading.Event()
    worker = threading.Thread(target=stop.wait)
    worker.start()
    try:
        with socket.socket() as extra:
            now = figures(os.getpid())
            assert (now.threads, now.descriptors) >= (here.threads + 1, here.descriptors + 1)
            assert extra.fileno() >= 0
    finally:
        stop.set()
        worker.join(10)
    assert "threads" in str(here) and "MiB RSS" in str(here)


def test_bytes_read_count_what_the_process_read(tmp_path) -> None:
    data = tmp_path / "data"
    data.write_bytes(b"x" * 100_000)
    before = bytes_read(os.getpid())
    assert len(data.read_bytes()) == 100_000
    assert bytes_read(os.getpid()) - before >= 100_000


def test_command_lines_hold_every_process_by_pid_as_it_was_started() -> None:
    with subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)", "an argument"]) as child:
        try:
            lines = command_lines()
            assert lines[child.pid] == [
                os.fsencode(sys.executable),
                b"-c",
                b"import time; time.sleep(30)",
                b"an argument",
            ]
            assert os.getpid() in lines
        finally:
            child.kill()


def test_a_process_that_has_gone_is_a_measuring_error() -> None:
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait(30)  # reaped: its pid names no process now
    for read in (cpu_seconds, rss_bytes, figures, bytes_read):
        with pytest.raises(MeasuringError, match=str(gone.pid)):
            read(gone.pid)


def test_the_sampler_keeps_samples_in_time_order_and_stops() -> None:
    sampler = RssSampler(os.getpid(), 0.01).start()
    # until it has three samples (a fixed 0.1 s got one under SCHED_IDLE beside the suite's other lanes), bounded
    deadline = time.monotonic() + 30
    while len(sampler.samples) < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    sampler.stop()
    stopped = len(sampler.samples)
    time.sleep(0.05)
    assert len(sampler.samples) == stopped  # stopped: no sample after stop()
    times = [at for at, _ in sampler.samples]
    assert len(times) >= 3 and times == sorted(times)
    assert sampler.between(times[1], times[-1]) == [rss for _, rss in sampler.samples[1:]]


def test_the_sockets_listening_on_a_port() -> None:
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        port = server.getsockname()[1]
        assert listening_addresses(port) == set()  # bound, not yet listening
        server.listen(1)
        assert listening_addresses(port) == {"0100007F"}  # 127.0.0.1, little-endian hex
