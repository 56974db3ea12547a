"""The session's clocks, per condition, from the records' clock columns (sim.study.run.clocks and
sim.study.run.links.clock): the robot's clock behind the runner's as each approach began, applied to its start and
press, and how far it moved during the approach (on a trajectory controller; the stream has no clock of its own);
and the clock of the page whose presses stop the condition (the VR page, the stop button's): the most its stamps
could be off in a trial, and how far its offset moved over the condition. Pure: records in, lines out."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from sim.study.run.records import TrialRecord

__all__ = ["clock_lines"]


def _finite(values: Sequence[float]) -> np.ndarray:
    return np.array([v for v in values if math.isfinite(v)], dtype=float) * 1000  # ms


def _median_max(values: Sequence[float], signed: bool = False) -> str:
    """median / largest (of magnitude when `signed`) in ms, of the finite values; – when none is."""
    finite = _finite(values)
    if finite.size == 0:
        return "–"
    largest = finite[np.argmax(np.abs(finite))] if signed else finite.max()
    return f"{np.median(finite):+.1f} / {largest:+.1f}" if signed else f"{np.median(finite):.1f} / {largest:.1f}"


def _span(values: Sequence[float]) -> str:
    finite = _finite(values)
    return "–" if finite.size == 0 else f"{np.ptp(finite):.1f}"


def clock_lines(records: Sequence[TrialRecord]) -> list[str]:
    """The report's section on the clocks; [] when no row has any (every condition streamed without a page that said
    its clock, or the records were written before the clocks' columns)."""
    columns = ("robot_clock_offset", "robot_clock_drift", "page_clock_offset", "page_clock_uncertainty")
    if not any(math.isfinite(getattr(r, column)) for r in records for column in columns):
        return []
    lines = [
        "## The clocks",
        "",
        "Per condition: the robot's clock behind the runner's as each approach began (its joint states' least arrival "
        "minus stamp, applied to the approach's start and press; the quickest delivery included) and how far it moved "
        "during the approach; the page whose presses stop the condition: the most its stamps could be off the "
        "runner's clock in a trial (half its best round trip plus its applied offset's lag), and how far its offset "
        "moved over the condition. Medians / largest, ms; – where there is no such clock (the stream's robot, a "
        "condition without a page).",
        "",
        "| condition | trials | robot clock behind | its drift in an approach | page stamps off by | "
        "page offset moved |",
        "|---|---|---|---|---|---|",
    ]
    for condition in dict.fromkeys(r.condition for r in records):
        rows = [r for r in records if r.condition == condition]
        lines.append(
            f"| {condition} | {len(rows)} | {_median_max([r.robot_clock_offset for r in rows], signed=True)} | "
            f"{_median_max([r.robot_clock_drift for r in rows])} | "
            f"{_median_max([r.page_clock_uncertainty for r in rows])} | {_span([r.page_clock_offset for r in rows])} |"
        )
    return lines + [""]
