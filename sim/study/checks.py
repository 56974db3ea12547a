"""Checks of the numbers a study command is given, each failing with one line that names the option. Pure logic."""

from __future__ import annotations

from sim.study.errors import StudyError

__all__ = ["check_fault_trial", "check_positive", "check_port", "check_workers", "participant_counts"]


def check_positive(value: float, option: str) -> None:
    if not value > 0:
        raise StudyError(f"{option} must be > 0, got {value}")


def check_port(value: int, option: str, zero: bool = False) -> None:
    """A TCP port; 0 (pick a free one) only where `zero` allows it."""
    if not (0 if zero else 1) <= value <= 65535:
        raise StudyError(f"{option} must be {0 if zero else 1}..65535, got {value}")


def check_fault_trial(trial: int | None) -> None:
    """--fault-trial (tests only): a trial's number, from 1."""
    if trial is not None and trial < 1:
        raise StudyError(f"--fault-trial must be a trial's number (1 or more), got {trial}")


def check_workers(workers: int) -> None:
    if not 0 <= workers <= 64:
        raise StudyError(f"--workers must be 0..64 (0: one per core, at most 2), got {workers}")


def participant_counts(text: str) -> tuple[int, ...]:
    """--participants as typed: numbers of participants, comma-separated."""
    try:
        return tuple(int(part) for part in text.split(","))
    except ValueError:
        raise StudyError(f"--participants must be whole numbers separated by commas, got {text!r}") from None
