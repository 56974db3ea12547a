"""`python -m bench.fault_query_relay FROM TO`: a node of its own offering TO/query_state, answered by
FROM/query_state: the controller's query_state as the runner sees it, in a process the fault bench and the fault
tests can kill (the service gone, its connections closed) or start anew (a controller restarted). Prints "ready" once
it serves."""

from __future__ import annotations

import signal
import sys
import threading

import rospy

from sim.wire.control_types import control_types
from sim.wire.rosnode import init_node


def main() -> None:
    source, target = sys.argv[1], sys.argv[2]
    types = control_types()
    init_node("fault_query_relay")
    ask = rospy.ServiceProxy(f"{source}/query_state", types.query_state, persistent=True)
    rospy.Service(f"{target}/query_state", types.query_state, lambda request: ask(request.time))
    done = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: done.set())
    print("ready", flush=True)
    done.wait()
    rospy.signal_shutdown("query relay done")


if __name__ == "__main__":
    main()
