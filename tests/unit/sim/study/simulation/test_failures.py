"""sim.study.simulation.failures: a failed part of a simulated session named in one line, with its own error."""

from __future__ import annotations

from pathlib import Path

from sim.study.simulation.failures import failed_line, one_line, problem_line

PARTICIPANT_LOG = """participant 1: connected; comfort 0.120 m (VR 0.100 m)
[WARNING] [bridge.client.connector] endpoint: something said on the way
sim.study participant: error: trial 3 (distance): an actual distance must be >= 0 m, got inf
"""
TRACEBACK = """Traceback (most recent call last):
  File "x.py", line 1, in <module>
ValueError: q has shape (3,), expected (7,)

"""


def test_a_parts_problem_is_its_last_error_line_else_its_last_line() -> None:
    assert problem_line(PARTICIPANT_LOG) == "trial 3 (distance): an actual distance must be >= 0 m, got inf"
    assert problem_line(TRACEBACK) == "ValueError: q has shape (3,), expected (7,)"
    assert problem_line("\n  \n") == ""


def test_a_failed_part_is_one_line_naming_it_how_it_ended_its_problem_and_its_log() -> None:
    line = failed_line("participant_01", 1, PARTICIPANT_LOG, Path("/out/logs/participant_01-1.log"))
    assert line == (
        "participant_01 exited with 1: trial 3 (distance): an actual distance must be >= 0 m, got inf "
        "(its log: /out/logs/participant_01-1.log)"
    )
    assert failed_line("engine", -9, "", Path("e.log")) == "engine was killed by signal 9: no output (its log: e.log)"
    assert "\n" not in line


def test_a_process_errors_message_and_tail_become_one_line() -> None:
    message = f"engine exited (1) before printing 'connected to':\n{TRACEBACK}"
    assert (
        one_line(message)
        == "engine exited (1) before printing 'connected to': ValueError: q has shape (3,), expected (7,)"
    )
    assert one_line("runner still running after 600 s:") == "runner still running after 600 s:"
