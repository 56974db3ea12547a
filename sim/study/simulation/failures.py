"""What a failed part of a simulated session said, in one line: the line the part itself ended with. Pure logic.

Every command of sim/ ends a failure with one line, `<prog>: error: <problem>` (sim.entry.fail); a crash ends with a
traceback, whose last line is the exception. Either is the part's own word on what went wrong."""

from __future__ import annotations

from pathlib import Path

__all__ = ["ERROR_MARK", "failed_line", "one_line", "problem_line"]

ERROR_MARK = ": error: "  # sim.entry.fail's form


def problem_line(output: str) -> str:
    """The problem a part's output ends with: its last `<prog>: error: <problem>` line's problem, else its last
    line that is not empty (a traceback's exception); "" for no output."""
    lines = [line.strip() for line in output.splitlines() if line.strip()]
    for line in reversed(lines):
        if ERROR_MARK in line:
            return line.split(ERROR_MARK, 1)[1]
    return lines[-1] if lines else ""


def failed_line(name: str, code: int, output: str, log: Path) -> str:
    """One line: which part ended, how, with its own problem, and where its log is."""
    problem = problem_line(output) or "no output"
    how = f"exited with {code}" if code >= 0 else f"was killed by signal {-code}"
    return f"{name} {how}: {problem} (its log: {log})"


def one_line(message: str) -> str:
    """A process error's message (a first line, then the output's tail) as one line: the first line and the tail's
    problem (problem_line)."""
    head, _, tail = message.partition("\n")
    problem = problem_line(tail)
    return f"{head.rstrip(':')}: {problem}" if problem else head
