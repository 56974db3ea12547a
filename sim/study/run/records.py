"""The tidy per-participant CSV: one row per trial, what was planned, measured and answered. Reading checks every
column, so the analysis never works on a half-written or edited-by-hand file without saying so.

Distances are the end effector's (its FK from the achieved joint states) to the hand's surface, in metres. The
press's latency columns came last, so a file written before them is still read (with them NaN).
"""

from __future__ import annotations

import csv
import math
from dataclasses import astuple, dataclass, fields
from pathlib import Path

from sim.study.run.errors import RunError

__all__ = ["TrialRecord", "write_records", "read_records"]


@dataclass(frozen=True)
class TrialRecord:
    participant: int
    index: int
    condition: str
    condition_position: int  # 1 if the participant did this condition first, else 2
    test: int
    path: str
    standoff: float  # m, planned end (test 2: on top of the hand)
    peak_speed: float  # m/s
    speed_set: str
    group: int
    motion_start: float  # s, ROS time
    pressed: bool
    press_time: float  # s from the motion's start; NaN without a press
    press_source: str  # the press's frame_id; "" without a press
    press_late: float  # s by which a press arrived after its stamp had passed (applied at arrival); 0 if in time
    distance_at_press: float  # m, FK of the achieved state at the press
    distance_at_rest: float  # m, FK of the last achieved state
    distance_extrapolated: float  # m, the plan's distance at the press time (the thesis's estimate from time)
    braking_distance: float  # m along the path
    perceived_distance: float  # m, test 1's answer; NaN otherwise
    preferred_path: str  # test 2: the group's preferred path, on each of its rows; "" otherwise
    # The press's latency in two parts (NaN where it was not measured: the keyboard's, a client that does not say):
    press_input_delay: float = math.nan  # s from the input's change to its stamp, as the pressing client measured it
    press_arrival_delay: float = math.nan  # s from its stamp to its arrival at the runner (ROS time); NaN unstamped


_FIELDS = fields(TrialRecord)
# Columns a file written before they were recorded lacks: it is read with them NaN
_ADDED_LATER = ("press_input_delay", "press_arrival_delay")


def write_records(path: Path, records: list[TrialRecord]) -> None:
    """Write the rows at once (to a temporary file, then renamed): a reader never sees half a session."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    with open(partial, "w", newline="") as out:
        writer = csv.writer(out)
        writer.writerow([field.name for field in _FIELDS])
        for record in records:
            writer.writerow([_text(value) for value in astuple(record)])
    partial.replace(path)


def _text(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return str(value)


def _value(text: str, kind: object, column: str, where: str) -> object:
    try:
        if kind in (int, "int"):
            return int(text)
        if kind in (float, "float"):
            return math.nan if text == "" else float(text)
        if kind in (bool, "bool"):
            if text not in ("true", "false"):
                raise ValueError(text)
            return text == "true"
        return text
    except ValueError:
        raise RunError(f"{where}: column {column} has {text!r}, not a {kind}") from None


def read_records(path: Path) -> list[TrialRecord]:
    try:
        with open(path, newline="") as source:
            rows = list(csv.reader(source))
    except OSError as error:
        raise RunError(f"cannot read {path}: {error.strerror}") from None
    names = [field.name for field in _FIELDS]
    earlier = [name for name in names if name not in _ADDED_LATER]
    if not rows or rows[0] not in (names, earlier):
        raise RunError(f"{path} is not a study record file: its header must be {','.join(names)}")
    columns = _FIELDS[: len(rows[0])]
    records = []
    for number, row in enumerate(rows[1:], start=2):
        where = f"{path}:{number}"
        if len(row) != len(columns):
            raise RunError(f"{where}: {len(row)} columns where {len(columns)} belong")
        values = [_value(text, field.type, field.name, where) for text, field in zip(row, columns)]
        records.append(TrialRecord(*values))  # type: ignore[arg-type]
    return records
