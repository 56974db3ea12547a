"""What the robot's trajectory controller did, per condition, from the records' link columns: the tracking error,
the leads its goals were stamped with (sim.study.run.links.lead), the press-to-braking latency (to the replacement's
sending, and to the first achieved state whose speed had fallen), the braking distance planned against achieved, the
goals' results and the runner's own stops; and whether a tracker followed the hand for the speed and separation
monitoring, with the least separations. Only conditions run on a trajectory controller (sim.study.run.links) have
these; the stream's rows are left out. Pure: records in, lines out."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence

import numpy as np

from sim.study.run.records import TrialRecord

__all__ = ["link_lines"]


def _cell(values: Sequence[float], scale: float, digits: int) -> str:
    """median / p95 of the finite values, scaled; – when there are none."""
    finite = np.array([v for v in values if math.isfinite(v)], dtype=float) * scale
    if finite.size == 0:
        return "–"
    return f"{np.median(finite):.{digits}f} / {np.percentile(finite, 95):.{digits}f}"


def link_lines(records: Sequence[TrialRecord]) -> list[str]:
    """The report's section on the trajectory controller's conditions; [] when every condition streamed."""
    controlled = [r for r in records if r.link != "stream"]
    if not controlled:
        return []
    lines = [
        "## The robot's trajectory controller",
        "",
        "Per condition run on a trajectory controller: each trial's largest joint error against the commanded path "
        "(tracking, mrad), how far ahead of its sending the approach was stamped and ahead of its preparation the "
        "stop was (the leads measured on the link, ms), the press to the braking replacement's sending and to the "
        "first joint state whose speed had fallen (ms), and the braking distance along the path, planned and "
        "achieved, with the achieved minus the planned (mm). Medians / 95th percentiles.",
        "",
        "| condition | link | trials | goals | tracking | start lead | stop lead | to replacement | to braking | "
        "braking planned | braking achieved | achieved − planned | runner's stops |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for condition in dict.fromkeys(r.condition for r in controlled):
        rows = [r for r in controlled if r.condition == condition]
        pressed = [r for r in rows if r.pressed]
        goals = ", ".join(f"{n} {result or 'none'}" for result, n in Counter(r.goal_result for r in rows).items())
        errors = [r.braking_distance_achieved - r.braking_distance for r in pressed]
        stops = sum(1 for r in rows if r.safety_stop)
        lines.append(
            f"| {condition} | {', '.join(dict.fromkeys(r.link for r in rows))} | {len(rows)} | {goals} | "
            f"{_cell([r.tracking_error for r in rows], 1000, 1)} | "
            f"{_cell([r.start_lead for r in rows], 1000, 1)} | {_cell([r.stop_lead for r in rows], 1000, 1)} | "
            f"{_cell([r.replacement_latency for r in pressed], 1000, 1)} | "
            f"{_cell([r.braking_latency for r in pressed], 1000, 1)} | "
            f"{_cell([r.braking_distance for r in pressed], 1000, 1)} | "
            f"{_cell([r.braking_distance_achieved for r in pressed], 1000, 1)} | {_cell(errors, 1000, 1)} | {stops} |"
        )
    lines.append("")
    reasons = [f"trial {r.index} of participant {r.participant}: {r.safety_stop}" for r in controlled if r.safety_stop]
    if reasons:
        lines += ["The runner stopped the arm on its own in " + "; ".join(reasons) + ".", ""]
    return lines + _separation_lines(controlled)


def _separation_lines(controlled: Sequence[TrialRecord]) -> list[str]:
    """Per condition: whether a tracker followed the hand (the speed and separation monitoring's input), and the least
    separations predicted and achieved (mm); [] for records written before the monitoring."""
    monitored = [r for r in controlled if r.hand_monitored]
    if not monitored:
        return []
    lines = [
        "Speed and separation monitoring (sim.study.safety.separation), per condition: the trials whose hand a tracker "
        "followed, and of the rest, whose hand was taken at the scene's place, at rest (not monitored); the least "
        "separation to the hand a stop decided then would have kept, and the least achieved while the arm moved, on "
        "the approach and on the move to its start before it (mm, the least of all trials / the median of the "
        "trials'; – where none was recorded).",
        "",
        "| condition | hand tracked | not monitored | least predicted | least achieved | least on the move |",
        "|---|---|---|---|---|---|",
    ]
    for condition in dict.fromkeys(r.condition for r in monitored):
        rows = [r for r in monitored if r.condition == condition]
        tracked = sum(1 for r in rows if r.hand_monitored == "tracked")
        cells = []
        for values in (
            [r.least_separation_predicted for r in rows],
            [r.least_separation for r in rows],
            [r.move_least_separation for r in rows],
        ):
            finite = [v * 1000 for v in values if math.isfinite(v)]
            cells.append(f"{min(finite):.1f} / {float(np.median(finite)):.1f}" if finite else "–")
        lines.append(f"| {condition} | {tracked} | {len(rows) - tracked} | {' | '.join(cells)} |")
    unmonitored = [c for c in dict.fromkeys(r.condition for r in monitored if r.hand_monitored == "untracked")]
    if unmonitored:
        lines.append("")
        lines.append(
            f"In {', '.join(unmonitored)}, no tracker followed the hand in some trials: the arm's separation was to "
            "the scene's hand, taken at rest; a hand that moved towards the arm was not seen."
        )
    return lines + [""]
