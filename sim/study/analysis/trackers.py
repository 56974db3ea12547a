"""The pose sources (trackers) of each condition: from the sessions' tracking records (the runner's
tracking/participant_NN.json), which tracker each condition used last, each one's jitter at rest and calibration;
from the trials' rows (their pose_source and calibration_id), which tracked each trial, and the caveat on every motion
measure's VR − reality contrast when a participant's two conditions were not tracked by one source with one
calibration throughout. A row written before those columns takes its session record's source for its condition.
Pure but for load_trackers, which reads the records.

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
from sim.study.run.records import TrialRecord
from sim.study.run.tracking import UNNAMED, calibration_id

__all__ = [
    "ConditionTrackers",
    "TrackerSummary",
    "TrialSources",
    "load_trackers",
    "summarise_trackers",
    "source_label",
    "trial_sources",
    "tracker_caveat",
    "tracker_lines",
]


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
    sessions: dict[int, dict[str, str]]  # participant -> condition -> its record's source (source_label)


@dataclass(frozen=True)
class TrialSources:
    """What tracked the trials that had poses, from their rows."""

    conditions: dict[str, dict[str, tuple[int, int]]]  # condition -> source_label -> (participants, trials)
    differing: tuple[int, ...]  # participants tracked in both conditions not by one named source, one calibration
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


def source_label(source: str, calibration: str) -> str:
    """A source as the caveat names it: with its calibration's id when it has one, as two fits of one tracker differ
    by up to their residuals."""
    return f"{source} (calibration {calibration})" if calibration else source


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
    recorded = {
        int(s["participant"]): {
            c: source_label(_source(e), calibration_id(e.get("calibration"))) for c, e in s["conditions"].items()
        }
        for s in sessions
    }
    return TrackerSummary(conditions, recorded)


def _had_poses(record: TrialRecord) -> bool:
    """Whether poses came in the trial: its source is named, or (a row written before the source's columns) a body's
    untracked time is a number."""
    return bool(record.pose_source) or math.isfinite(record.hand_untracked) or math.isfinite(record.head_untracked)


def trial_sources(records: Sequence[TrialRecord], trackers: TrackerSummary | None = None) -> TrialSources | None:
    """What tracked each condition's trials that had poses, by their rows; a row written before the source's columns
    by its session's record for its condition in `trackers` (without one, it is left out: nothing says which
    tracked it). None when no trial is left."""
    counts: dict[int, dict[str, Counter[str]]] = {}
    for record in records:
        if not _had_poses(record):
            continue
        if record.pose_source:
            label = source_label(record.pose_source, record.calibration_id)
        else:  # a row written before the source's columns: its session's record, if there is one, says
            recorded = trackers.sessions.get(record.participant, {}) if trackers is not None else {}
            if record.condition not in recorded:
                continue
            label = recorded[record.condition]
        counts.setdefault(record.participant, {}).setdefault(record.condition, Counter())[label] += 1
    if not counts:
        return None
    conditions: dict[str, dict[str, tuple[int, int]]] = {}
    for condition in CONDITIONS:
        seen = [by[condition] for by in counts.values() if condition in by]  # each participant's trials by source
        labels = sorted({label for trials in seen for label in trials})
        if labels:
            conditions[condition] = {
                label: (sum(label in trials for trials in seen), sum(trials[label] for trials in seen))
                for label in labels
            }
    paired = [p for p, by in counts.items() if all(c in by for c in CONDITIONS)]
    labels_of = {p: {label for c in CONDITIONS for label in counts[p][c]} for p in paired}
    differing = [p for p, labels in labels_of.items() if len(labels) > 1 or UNNAMED in labels]
    return TrialSources(conditions, tuple(sorted(differing)), len(paired))


def _sources(trackers: ConditionTrackers) -> str:
    return ", ".join(f"{name} ({n})" for name, n in trackers.sources.items())


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def tracker_caveat(sources: TrialSources | None) -> str:
    """The caveat every motion measure's VR − reality contrast carries when, for any participant, the two
    conditions' trials were not all tracked by one named source with one calibration (by the trials' rows); ""
    when each participant's were."""
    if sources is None or not sources.differing:
        return ""
    named = "; ".join(
        f"{c}: "
        + ", ".join(f"{label} ({_count(p, 'participant')}, {_count(t, 'trial')})" for label, (p, t) in by.items())
        for c, by in sources.conditions.items()
    )
    return (
        f"the two conditions were tracked by different trackers or calibrations (or one unnamed) for "
        f"{len(sources.differing)} of {sources.paired} participants, by their trials' records ({named}). Each "
        "VR − reality contrast of the participant's motion is also a contrast between the trackers: their jitter "
        "(which raises the withdrawal's peak speed), latency and calibration differ with the condition"
    )


def _mm(value: float) -> str:
    return "–" if math.isnan(value) else f"{value * 1000:.2f}"


def tracker_lines(summary: TrackerSummary | None, sources: TrialSources | None = None) -> list[str]:
    """The report's lines on the trackers: per condition, which tracked it (each session's latest), their jitter and
    calibration; and, when the trials' rows (`sources`) say so, that each participant had one tracker throughout."""
    if summary is None:
        return []
    lines = [
        "Trackers (pose sources) per condition, from the sessions' tracking records (each session's latest source "
        "per condition; the trials' own are in the caveat when they differ): the participants each tracked, "
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
    if sources is not None and sources.paired and not sources.differing:
        lines += [
            f"Each of the {sources.paired} participants tracked in both conditions had the same tracker (and "
            "calibration) in every trial of both, by their trials' records.",
            "",
        ]
    return lines
