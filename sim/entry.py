"""How every command of sim/ reports a problem and ends: one line on stderr that names it, and a named exit code.

python -m sim.X ... ; echo $?    0 done, 1 the run failed, 2 bad input (as argparse), 3 a goal out of reach,
                                 4 ROS or the endpoint out of reach, 130 interrupted
"""

from __future__ import annotations

import logging
import sys

__all__ = [
    "EXIT_OK",
    "EXIT_FAILED",
    "EXIT_BAD_INPUT",
    "EXIT_UNREACHABLE_GOAL",
    "EXIT_NO_CONNECTION",
    "EXIT_INTERRUPTED",
    "fail",
    "warn",
    "log_to_stderr",
]

EXIT_OK = 0
EXIT_FAILED = 1  # the run itself failed: a process, a trial, the analysis of what it recorded
EXIT_BAD_INPUT = 2  # options, a robot, a scenario, a file: found before anything runs (argparse's code too)
EXIT_UNREACHABLE_GOAL = 3  # an IK goal no configuration reaches (the commander; --nearest runs the nearest)
EXIT_NO_CONNECTION = 4  # ROS or the endpoint did not answer, or went away
EXIT_INTERRUPTED = 130  # stopped by a signal before the run was complete (128 + SIGINT, as shells report it)


def fail(prog: str, problem: object, code: int, label: str = "error") -> int:
    """Say what went wrong in one line, `<prog>: <label>: <problem>`, and return the exit code to end with."""
    print(f"{prog}: {label}: {problem}", file=sys.stderr)
    return code


def warn(prog: str, note: object) -> None:
    """A warning in the same one-line form: the run goes on."""
    print(f"{prog}: warning: {note}", file=sys.stderr)


def log_to_stderr(level: int = logging.WARNING) -> None:
    """The commands' log lines, on stderr: `[LEVEL] [logger] message`."""
    logging.basicConfig(level=level, format="[%(levelname)s] [%(name)s] %(message)s", stream=sys.stderr)
