"""The pose sources (trackers) of each condition, from the sessions' tracking records (the runner's
tracking/participant_NN.json): which tracker each condition used, each one's jitter at rest and calibration, and the
caveat on every motion measure's VR − reality contrast when the two conditions' trackers differ. Pure but for
load_trackers, which reads the records.

A tracker's jitter adds to a still hand's apparent motion, so the withdrawal's peak speed is sensitive to it, and a
tracker's calibration moves every position by up to its residual: a contrast between two trackers mixes them with the
condition.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.study.analysis.errors import AnalysisError
from sim.study.design.spec import CONDITIONS
from sim.study.run.protocol import BODIES

__all__ = [
    "ConditionTrackers",
    "TrackerSummary",
    "load_trackers",
    "summarise_trackers",
    "tracker_caveat",
    "tracker_lines",
]

UNNAMED = "unnamed"  # a condition whose poses came from a source that did not say which


@dataclass(frozen=True)
class ConditionTrackers:
    sources: dict[str, int]  # tracker -> participants whose trials in this condition it tracked
    jitter: dict[
        str, tuple[float, float, int]
    ]  # body -> (mean, most) m over the sessions that measured it, and how many
    residual_rms: float  # m: the largest calibration RMS residual among its sessions; NaN: none calibrated
    residual_max: float  # m: the largest single residual
    calibrated: int  # sessions with a calibration


@dataclass(frozen=True)
class TrackerSummary:
    conditions: dict[str, ConditionTrackers]  # per condition that any session tracked
    differing: tuple[int, ...]  # participants tracked in both conditions, by different (or unnamed) trackers
    paired: int  # participants tracked in both conditions


def load_trackers(directory: Path) -> list[dict[str, Any]]:
    """Every session's tracking record in `directory`/tracking; AnalysisError on one that cannot be read."""
    sessions = []
    for path in sorted((Path(directory) / "tracking").glob("participant_*.json")):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as error:
            raise AnalysisError(f"cannot read the tracking record {path}: {error}") from None
        if not (isinstance(data, dict) and isinstance(data.get("conditions"), dict)):
            raise AnalysisError(f"{path} is not a session's tracking record")
        sessions.append(data)
    return sessions


def _source(entry: Mapping[str, Any]) -> str:
    return str(entry.get("source") or UNNAMED)


def summarise_trackers(sessions: Sequence[Mapping[str, Any]]) -> TrackerSummary | None:
    """The trackers per condition over the sessions' records; None without any record."""
    if not sessions:
        return None
    conditions = {}
    for condition in CONDITIONS:
        entries = [s["conditions"][condition] for s in sessions if condition in s["conditions"]]
        if not entries:
            continue
        jitter = {}
        for body in BODIES:
            values = [float(v) for e in entries if (v := (e.get("jitter_m") or {}).get(body)) is not None]
            if values:
                jitter[body] = (sum(values) / len(values), max(values), len(values))
        fits = [e["calibration"] for e in entries if e.get("calibration")]
        conditions[condition] = ConditionTrackers(
            sources=dict(sorted(Counter(_source(e) for e in entries).items())),
            jitter=jitter,
            residual_rms=max((float(f["residual_rms_m"]) for f in fits), default=math.nan),
            residual_max=max((float(f["residual_max_m"]) for f in fits), default=math.nan),
            calibrated=len(fits),
        )
    both = [s for s in sessions if all(c in s["conditions"] for c in CONDITIONS)]
    differing = tuple(
        sorted(
            int(s["participant"])
            for s in both
            if len({_source(s["conditions"][c]) for c in CONDITIONS}) > 1
            or UNNAMED in {_source(s["conditions"][c]) for c in CONDITIONS}
        )
    )
    return TrackerSummary(conditions, differing, len(both))


def _sources(trackers: ConditionTrackers) -> str:
    return ", ".join(f"{name} ({n})" for name, n in trackers.sources.items())


def tracker_caveat(summary: TrackerSummary | None) -> str:
    """The caveat every motion measure's VR − reality contrast carries when the conditions' trackers differ (or one
    is unnamed) for any participant; "" when each participant's two conditions had the same tracker."""
    if summary is None or not summary.differing:
        return ""
    named = "; ".join(f"{c}: {_sources(t)}" for c, t in summary.conditions.items())
    return (
        f"the two conditions were tracked by different trackers (or one unnamed) for {len(summary.differing)} of "
        f"{summary.paired} participants ({named}). Each VR − reality contrast of the participant's motion is also "
        "a contrast between the trackers: their jitter (which raises the withdrawal's peak speed), latency and "
        "calibration differ with the condition"
    )


def _mm(value: float) -> str:
    return "–" if math.isnan(value) else f"{value * 1000:.2f}"


def tracker_lines(summary: TrackerSummary | None) -> list[str]:
    """The report's lines on the trackers: per condition, which tracked it, their jitter and calibration."""
    if summary is None:
        return []
    lines = [
        "Trackers (pose sources) per condition, from the sessions' tracking records: the participants each tracked, "
        "each body's jitter at rest at the session's start (the RMS distance from its mean; mean and most over the "
        "sessions that measured it, mm) and the calibration's largest residuals (mm, over the calibrated sessions):",
        "",
        "| condition | tracker (participants) | "
        + " | ".join(f"{body} jitter" for body in BODIES)
        + " | calibrated | residual RMS | residual max |",
        "|---|---|" + "---|" * (len(BODIES) + 3),
    ]
    for condition, t in summary.conditions.items():
        cells = " | ".join(
            f"{_mm(t.jitter[body][0])} (most {_mm(t.jitter[body][1])}, n {t.jitter[body][2]})"
            if body in t.jitter
            else "not measured"
            for body in BODIES
        )
        lines.append(
            f"| {condition} | {_sources(t)} | {cells} | {t.calibrated} | {_mm(t.residual_rms)} | "
            f"{_mm(t.residual_max)} |"
        )
    lines.append("")
    if summary.paired and not summary.differing:
        lines += [
            f"Each of the {summary.paired} participants tracked in both conditions had the same tracker in both.",
            "",
        ]
    return lines
