"""How every command of sim/ reports a problem and ends: one line on stderr that names it, and a named exit code.

python -m sim.X ... ; echo $?    0 done, 1 the run failed, 2 bad input (as argparse), 3 a goal out of reach,
                                 4 ROS or the endpoint out of reach, 130 interrupted
"""

from __future__ import annotations

import importlib
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
    "without_ros_arguments",
    "run_as_ros_command",
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


def without_ros_arguments(argv: list[str]) -> list[str]:
    """The command's own arguments from those rosrun and roslaunch add: remappings and special keys such as
    `__name:=commander` and `__log:=...` all have `:=` in them, and no option of ours does (as rospy.myargv)."""
    return [arg for arg in argv if ":=" not in arg]


# pip's names where they differ from the module's
_PIP_NAMES = {"yaml": "PyYAML", "PIL": "Pillow"}


def run_as_ros_command(module: str, argv: list[str]) -> int:
    """`module`'s main as rosrun and roslaunch start it (vr_sim's scripts): with their arguments left out, and a
    package this Python lacks named in one line, with how to get it, rather than a traceback."""
    try:
        return int(importlib.import_module(module).main(without_ros_arguments(argv)))
    except ModuleNotFoundError as error:
        missing = (error.name or "").split(".")[0]
        if missing in ("", "sim", "bridge"):
            raise
        pip_name = _PIP_NAMES.get(missing, missing)
        return fail(
            module,
            f"{sys.executable} has no module {missing!r}; install vr_sim's dependencies: `rosdep install "
            f"--from-paths src --ignore-src` in the workspace, or `pip3 install --user {pip_name}`",
            EXIT_BAD_INPUT,
        )
