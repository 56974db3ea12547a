"""bridge.memory: when the endpoint gives freed memory back (QuietTrim, pure), and that giving it back works."""

from __future__ import annotations

import subprocess
import sys

from bridge.memory import QuietTrim


def test_memory_goes_back_in_the_first_quiet_period_after_traffic() -> None:
    trim = QuietTrim(quiet_bytes=100)
    assert not trim.due(0)  # nothing moved yet: nothing to give back
    assert not trim.due(500)  # a busy period
    assert not trim.due(900)
    assert trim.due(950)  # quiet now, after 950 bytes moved
    assert not trim.due(960)  # still quiet: given back already, little moved since


def test_light_steady_traffic_gives_memory_back_once_per_quiet_bytes_moved() -> None:
    trim = QuietTrim(quiet_bytes=100)
    dues = [trim.due(total) for total in range(30, 601, 30)]  # 30 bytes a period: always quiet
    assert dues.count(True) == 5 and dues[3]  # at 120, 240, 360, 480, 600


# Run in a process of its own: keep_large_buffers changes the allocator for the whole process. Heap memory freed by
# 200 MiB of buffers goes back to the system; a second call, with nothing left to give, changes nothing (the data
# still held is intact, the process does not grow).
_GIVE_BACK = """
import os
from bridge.memory import give_back_free_memory, keep_large_buffers

def rss():
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

keep_large_buffers()
kept = bytes(range(256)) * 4096
buffers = [bytearray(1 << 20) for _ in range(200)]
for buffer in buffers:
    buffer[::4096] = b"x" * len(buffer[::4096])  # touched: resident
full = rss()
del buffers
given = give_back_free_memory()
after_first = rss()
again = give_back_free_memory()
after_second = rss()
print(given, again, full - after_first, after_second - after_first, kept == bytes(range(256)) * 4096)
"""


def test_freed_memory_goes_back_and_giving_it_back_again_is_harmless() -> None:
    result = subprocess.run([sys.executable, "-c", _GIVE_BACK], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    given, again, returned, grown, intact = result.stdout.split()
    assert given == "True" and int(returned) > 150 * (1 << 20), result.stdout  # most of the 200 MiB
    assert again in ("True", "False") and int(grown) < 1 << 20 and intact == "True", result.stdout
