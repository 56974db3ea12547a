"""`python bench/stepped_clock.py ARGS...`: `python -m sim.study ARGS...` in a process whose wall clock steps, +2 s on
SIGUSR1 and -2 s on SIGUSR2, as an NTP step on the runner's machine would: a fault the fault bench and the fault
tests inject into the real runner, with nothing in the runner's code for it. time.time, which rospy's time and every
wall-clock reading go through, is stepped before anything else is imported; the monotonic clock is not, as the
kernel's is not."""

from __future__ import annotations

import runpy
import signal
import sys
import time

STEP = 2.0  # s

_wall = time.time
_offset = [0.0]


def _stepped() -> float:
    return _wall() + _offset[0]


def _step(by: float) -> None:
    _offset[0] += by


time.time = _stepped
signal.signal(signal.SIGUSR1, lambda *_: _step(STEP))
signal.signal(signal.SIGUSR2, lambda *_: _step(-STEP))
sys.argv = ["sim.study", *sys.argv[1:]]
runpy.run_module("sim.study", run_name="__main__", alter_sys=True)
