"""The one place where every exit of a motion brakes. No ROS.

A trajectory-controller link runs each motion it commands (an approach, a move to a path's start) inside
`brakes_on_exit`. However the motion's code is left (an exception of any kind, the observer's Ctrl-C or a SIGTERM
turned into an interruption, a return with the arm still moving), the arm is braked before the exit goes on: the
link sends a braking replacement, from the controller's desired state when it answers, else along the path the link
commanded, and watches it to rest. An exit with the arm at rest, or with a stop already in force, sends nothing
more. So a new path through a motion's code cannot leave an approach running on to its stand-off: only the loss of
the runner's process itself (SIGKILL, a power cut) can, and then the controller ends the goal at the stand-off at
rest, as the plan does.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Protocol

__all__ = ["Stoppable", "brakes_on_exit"]


class Stoppable(Protocol):
    def settled(self) -> bool:
        """The motion has ended at rest, or a stop is in force: nothing more need be sent."""
        ...

    def fail_safe(self, why: str) -> None:
        """Brake now and watch the arm to rest; never raises (it says what it could not do)."""
        ...


@contextmanager
def brakes_on_exit(motion: Stoppable) -> Iterator[None]:
    try:
        yield
    except BaseException as error:  # every exit: KeyboardInterrupt and SystemExit too
        if not motion.settled():
            motion.fail_safe(f"{type(error).__name__}: {error}" if str(error) else type(error).__name__)
        raise
    if not motion.settled():
        motion.fail_safe("the motion's code ended with the arm still commanded to move")
