"""How long each stop path took from the press to the runner, from the records' latency columns: per stop source,
the input delay (from the first reading that saw the input's change to its stamp, as the pressing client measured
it) and the arrival delay (the stamp to its arrival at the runner), each as a median and a 95th percentile; the
button's minus the trigger's; and which participants' presses came from the observer's keyboard, whose latency
includes the observer's reaction and is measured by nobody. Pure: records in, numbers and lines out.

Why it matters: a press is applied at its stamp, so what delays the stamp (the input delay) moves the stop along
the path by that delay times the speed, in one condition only if the two paths differ. The arrival delay does not
move the stop as long as the press arrives before the runner commands past its stamp (else `press_late`).

Both pages measure the input delay the same way, from the first reading that saw the change: the button page from
the browser's gamepad poll that saw it (the Gamepad API's timestamp) to the page's frame that read it; the VR page
from the headset's frame that read the trigger (the time of its input event) to the stamp. Neither sees the press
itself: the time from the press to that first reading, up to one reading interval (UNSEEN_MAX_S), is measured by
neither, so the paths' difference is the measured parts' and the true one lies within ±UNSEEN_MAX_S of it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.study.run.protocol import PROTOCOL
from sim.study.run.records import TrialRecord

__all__ = [
    "UNSEEN_MAX_S",
    "Spread",
    "PathLatency",
    "LatencySummary",
    "summarise_latency",
    "keyboard_flag",
    "latency_lines",
]

# s: the longest time from a press to the first reading that sees it, which no page can measure: a frame of the
# headset at 72 Hz (Quest's lowest rate), 14 ms; the browser's gamepad polling, some 4-16 ms in Chromium
UNSEEN_MAX_S = 0.016


@dataclass(frozen=True)
class Spread:
    measured: int  # presses that had this delay measured
    median: float  # s; NaN when none
    p95: float  # s; NaN when none

    @staticmethod
    def of(values: Sequence[float]) -> Spread:
        finite = [value for value in values if math.isfinite(value)]
        if not finite:
            return Spread(0, math.nan, math.nan)
        return Spread(len(finite), float(np.median(finite)), float(np.percentile(finite, 95)))


@dataclass(frozen=True)
class PathLatency:
    source: str  # the stop source (the records' press_source)
    presses: int
    input_delay: Spread
    arrival_delay: Spread
    total: Spread  # input + arrival, per press where both were measured


@dataclass(frozen=True)
class LatencySummary:
    paths: tuple[PathLatency, ...]  # by source, the protocol's stop sources first, in its order
    vr_source: str  # the participant's own path in each condition (the protocol's)
    reality_source: str
    observer_sources: tuple[str, ...]  # sources of no condition: the observer's (the keyboard)
    observer_presses: dict[int, dict[str, int]]  # participant -> condition -> presses from an observer source
    fastest_speed: float  # m/s, the highest peak speed of a pressed trial (NaN without presses)

    def path(self, source: str) -> PathLatency | None:
        return next((path for path in self.paths if path.source == source), None)


def summarise_latency(records: Sequence[TrialRecord]) -> LatencySummary:
    pressed = [r for r in records if r.pressed]
    known = list(PROTOCOL.stop_sources)
    sources = known + sorted({r.press_source for r in pressed} - set(known))
    paths = []
    for source in sources:
        rows = [r for r in pressed if r.press_source == source]
        if rows:
            paths.append(
                PathLatency(
                    source,
                    len(rows),
                    Spread.of([r.press_input_delay for r in rows]),
                    Spread.of([r.press_arrival_delay for r in rows]),
                    Spread.of([r.press_input_delay + r.press_arrival_delay for r in rows]),
                )
            )
    observers = tuple(name for name, condition in PROTOCOL.stop_sources.items() if condition is None)
    flagged: dict[int, dict[str, int]] = {}
    for r in pressed:
        if r.press_source in observers:
            by_condition = flagged.setdefault(r.participant, {})
            by_condition[r.condition] = by_condition.get(r.condition, 0) + 1
    return LatencySummary(
        tuple(paths),
        PROTOCOL.stop_source("vr"),
        PROTOCOL.stop_source("reality"),
        observers,
        dict(sorted(flagged.items())),
        max((r.peak_speed for r in pressed), default=math.nan),
    )


def _ms(value: float) -> str:
    return "–" if math.isnan(value) else f"{value * 1000:.1f}"


def _spread(spread: Spread) -> str:
    return f"{_ms(spread.median)} | {_ms(spread.p95)} | {spread.measured}"


def keyboard_flag(summary: LatencySummary) -> str:
    """One line naming the participants whose presses came from the observer, or "" when none did."""
    if not summary.observer_presses:
        return ""
    named = "; ".join(
        f"participant {participant} ({', '.join(f'{n} in {condition}' for condition, n in counts.items())})"
        for participant, counts in summary.observer_presses.items()
    )
    return (
        f"**Presses from the observer's {' or '.join(summary.observer_sources)}**: {named}. Their latency includes "
        "the observer's reaction (some 0.2–0.3 s), in that condition only: for pilots, not for the contrast."
    )


def latency_lines(summary: LatencySummary) -> list[str]:
    """The report's section on the stop paths' latency."""
    lines = [
        "## Stop presses: latency",
        "",
        "Each press's latency in two parts: the **input delay**, from the first reading that saw the input's change "
        "to the press's stamp, as the pressing page measured it, the same way on both pages (the button page: from "
        "the browser's gamepad poll that saw it, the Gamepad API's timestamp, to the page's frame that read it; the "
        "VR page: from the headset's frame that read the trigger, its input event's time, to the stamp), and the "
        "**arrival delay**, from the stamp to the press's arrival at the runner (its ROS time then). A press is "
        "applied at its stamp, so the input delay moves the stop; the arrival delay does not, unless the press "
        "came after the runner had passed its stamp (applied late). ms; – where not measured.",
        "",
        "| source | presses | input median | input p95 | measured | arrival median | arrival p95 | measured | "
        "total median | total p95 | measured |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {p.source} | {p.presses} | {_spread(p.input_delay)} | {_spread(p.arrival_delay)} | {_spread(p.total)} |"
        for p in summary.paths
    ]
    lines.append("")
    button, trigger = summary.path(summary.reality_source), summary.path(summary.vr_source)
    if button is not None and trigger is not None:
        differences = [
            (name, getattr(button, name).median - getattr(trigger, name).median)
            for name in ("input_delay", "arrival_delay", "total")
        ]
        said = ", ".join(f"{name.replace('_', ' ')} {_ms(value)} ms" for name, value in differences)
        lines.append(f"The {button.source} path minus the {trigger.source} path, medians: {said}.")
        shift = differences[0][1] * summary.fastest_speed
        if math.isfinite(shift):
            bound = UNSEEN_MAX_S * summary.fastest_speed
            lines.append(
                f"At the fastest approach's peak speed ({summary.fastest_speed:g} m/s) the measured input delays' "
                f"difference puts reality's stops {shift * 1000:+.1f} mm further along the path than VR's. Neither "
                "page sees the time from the press to the first reading of it (up to a headset frame or a gamepad "
                f"poll, {UNSEEN_MAX_S * 1000:.0f} ms at most), so the paths' whole difference is bounded, not "
                f"measured: it lies within ±{bound * 1000:.1f} mm of this one."
            )
    else:
        lines.append(
            f"No difference between the paths: presses from both {summary.reality_source} and "
            f"{summary.vr_source} are needed."
        )
    if any(p.arrival_delay.median < 0 for p in summary.paths):
        lines.append(
            "A negative arrival delay is a press sent ahead of its stamp: a client that anticipates the robot, as "
            "the simulated participant does; it is applied at its stamp."
        )
    lines.append("")
    flag = keyboard_flag(summary)
    if flag:
        lines += [flag, ""]
    return lines
