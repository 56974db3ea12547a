"""The joint CSV format of the engine's offline mode (the thesis's Manual_Test), its log, and the commander's export.

A header row `time,<joint name>,...`, then one row per sample: time in s, positions in rad or m. A file may name a
subset of a robot's joints. Logs are written rounded (1 µs, 1e-9); files meant to be read back as the same
doubles (the commander's export) exactly. Pure file I/O: no ROS, no physics.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sim.errors import SimError
from sim.robots import RobotSpec

__all__ = ["JointCsvError", "read_joint_csv", "write_joint_csv"]


class JointCsvError(SimError, ValueError):
    """A joint CSV that cannot be used; the message names the file, line, column or value."""


def read_joint_csv(path: Path, robot: RobotSpec) -> tuple[np.ndarray, list[str], np.ndarray]:
    """(times, joint names of the columns, positions[time, column]) with the checks a user needs named."""
    try:
        with open(path, newline="") as handle:
            rows = list(csv.reader(handle))
    except OSError as error:
        raise JointCsvError(f"cannot read {path}: {error}") from None
    if len(rows) < 2:
        raise JointCsvError(f"{path}: needs a header row and at least one data row")
    header = [cell.strip() for cell in rows[0]]
    if not header or header[0] != "time":
        raise JointCsvError(f"{path}: the first column must be 'time', got {header[:1]}")
    names = header[1:]
    unknown = [name for name in names if name not in robot.joint_names]
    if unknown or not names:
        raise JointCsvError(f"{path}: unknown joint column(s) {unknown}; {robot.name} has {list(robot.joint_names)}")
    if len(set(names)) != len(names):
        raise JointCsvError(f"{path}: a joint column appears twice: {names}")
    values = []
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise JointCsvError(f"{path}: line {line} has {len(row)} cells, the header has {len(header)}")
        try:
            values.append([float(cell) for cell in row])
        except ValueError:
            bad = next(i for i, cell in enumerate(row) if not _is_number(cell))
            raise JointCsvError(f"{path}: line {line}, column {header[bad]!r}: {row[bad]!r} is not a number") from None
    if not values:
        raise JointCsvError(f"{path}: needs a header row and at least one data row")
    data = np.array(values, dtype=float)
    times = data[:, 0]
    if np.any(np.diff(times) <= 0):
        k = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
        raise JointCsvError(
            f"{path}: times must be strictly increasing; data row {k + 1} has time {times[k]:g} after {times[k - 1]:g}"
        )
    if not np.all(np.isfinite(data)):
        raise JointCsvError(f"{path}: all values must be finite numbers")
    return times, names, data[:, 1:]


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def write_joint_csv(
    path: Path, names: Sequence[str], times: np.ndarray, positions: np.ndarray, exact: bool = False
) -> None:
    """Write the format. By default times to 1 µs and positions to 1e-9 (a log, readable, free of float noise);
    `exact` writes Python's shortest round-trip repr, for a file that must be read back as the same doubles."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    time_text, value_text = (_exact, _exact) if exact else ("{:.6f}".format, "{:.9f}".format)
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["time", *names])
        for t, row in zip(times, positions):
            writer.writerow([time_text(t), *(value_text(value) for value in row)])


def _exact(value: float) -> str:
    return repr(float(value))
