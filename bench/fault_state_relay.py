"""`python -m bench.fault_state_relay FROM TO FAULT [--from-start]`: a node of its own relaying the arm's joint states
from FROM to TO, with FAULT injected on SIGUSR1 (or from the first state with --from-start): the robot's driver as a
faulty network or a faulty driver would make it look to the runner. Prints "ready" once it relays. FAULT is one of:
- six-positions: the next state has one position fewer than its names (once per signal);
- nan: the next state's first position is NaN (once per signal);
- silence: no state is passed on any more (a feed gone stale);
- restamp: every state is stamped 0.5 s later than the robot's clock says (a robot PC whose clock is off).

A process of its own, as the robot's driver is: a relay inside the test's or the bench's own process shares its
interpreter with their listeners, and a relay starved of it delivers late, which the runner rightly takes for the
robot's clock falling behind.
"""

from __future__ import annotations

import math
import signal
import sys
import threading
from typing import Any

import rospy
from sensor_msgs.msg import JointState

from sim.wire.rosnode import init_node

FAULTS = ("six-positions", "nan", "silence", "restamp")
RESTAMP_S = 0.5  # s: how far the restamped states' clock is off the robot's


class Relay:
    """The states from `source` on `target`, `fault` applied once `inject()` was called."""

    def __init__(self, source: str, target: str, fault: str) -> None:
        self.fault = fault
        self._injected = threading.Event()
        self._pending = 0  # malformed states still owed (one per injection)
        self._lock = threading.Lock()
        self._out = rospy.Publisher(target, JointState, queue_size=10, tcp_nodelay=True)
        self._in = rospy.Subscriber(source, JointState, self._relay, queue_size=10, tcp_nodelay=True)

    def inject(self) -> None:
        with self._lock:
            self._pending += 1
        self._injected.set()

    def _relay(self, message: Any) -> None:
        if self._injected.is_set():
            message = self._changed(message)
        if message is not None:
            self._out.publish(message)

    def _changed(self, message: Any) -> Any:
        if self.fault == "silence":
            return None
        if self.fault == "restamp":
            header = type(message.header)(message.header.seq, message.header.stamp + rospy.Duration(RESTAMP_S), "")
            return JointState(header, message.name, message.position, message.velocity, message.effort)
        with self._lock:
            if self._pending == 0:
                return message
            self._pending -= 1
        positions = list(message.position)
        positions = positions[:-1] if self.fault == "six-positions" else [math.nan, *positions[1:]]
        return JointState(message.header, message.name, positions, message.velocity, message.effort)


def main() -> None:
    args = sys.argv[1:]
    from_start = "--from-start" in args
    args = [arg for arg in args if arg != "--from-start"]
    if len(args) != 3 or args[2] not in FAULTS:
        faults = ",".join(FAULTS)
        print(f"usage: python -m bench.fault_state_relay FROM TO {{{faults}}} [--from-start]", file=sys.stderr)
        raise SystemExit(2)
    source, target, fault = args
    init_node("fault_state_relay")
    relay = Relay(source, target, fault)
    if from_start:
        relay.inject()
    signal.signal(signal.SIGUSR1, lambda *_: relay.inject())
    done = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: done.set())
    print("ready", flush=True)
    while not done.wait(0.1):  # short waits: the signal handlers run between them
        pass
    rospy.signal_shutdown("state relay done")


if __name__ == "__main__":
    main()
