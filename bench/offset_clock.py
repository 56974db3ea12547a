"""`python bench/offset_clock.py SECONDS MODULE ARGS...`: `python -m MODULE ARGS...` in a process whose wall clock is
SECONDS off this machine's (negative: behind), as a robot PC's clock that chrony does not keep: the physics node's
trajectory controller run through it starts its goals, and stamps its joint states, on that clock, as ros_control on
the robot's PC does. time.time, which rospy's time and every wall-clock reading go through, is offset before anything
else is imported; the monotonic clock is not."""

from __future__ import annotations

import runpy
import sys
import time


def main() -> None:
    try:
        offset = float(sys.argv[1])
        module = sys.argv[2]
    except (IndexError, ValueError):
        print("usage: python bench/offset_clock.py SECONDS MODULE [ARGS...]", file=sys.stderr)
        raise SystemExit(2) from None
    wall = time.time
    time.time = lambda: wall() + offset
    sys.argv = [module, *sys.argv[3:]]
    runpy.run_module(module, run_name="__main__", alter_sys=True)


if __name__ == "__main__":
    main()
