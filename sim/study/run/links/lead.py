"""How far ahead a link's goals are stamped, from the delays this session measured: a braking replacement, and an
approach. Pure.

A stop is a replacement stamped `lead` s after the moment its preparation begins: the controller starts it at its
stamp, so the controller must have it by then. Sent later, the controller drops the points already due and bridges
from where its desired state has gone meanwhile (a jump), or refuses it when every point is due (the link then plans
it anew, later still). A longer lead than needed lets the arm run on at speed that much longer before it brakes. The
delay the lead covers differs between a loopback and a lab's network to the driver, and with the machine's load, so
it is measured on the link's own connection, in three parts:

  query      query_state's round trip (the controller's desired state at the stamp): probed at connect, and each stop
  planning   the stop's planning on this machine (sim.study.safety.braking): one timed before every approach, from its
             fastest planned state, and each stop
  delivery   each goal the link sends, from just before send_goal to the controller's status saying it took it
             (accepted or refused): a round trip, so it bounds the goal's one-way delivery and the controller's
             handling from above. A stop's goal (tens of points) goes faster than a motion's (hundreds), so each is
             kept apart: `delivery` for goals of up to STOP_SIZED points (the stops), `motion_delivery` for the
             longer ones (the moves to a start and the approaches). Until a part has a sample, the other's stands in
             for it (a motion's delivery bounds a stop's from above; the describe() says so)

lead = each part's QUANTILE (the largest while a part has fewer than 1 / (1 - QUANTILE) samples) summed, plus MARGIN,
within [FLOOR, CEILING]; CEILING while a part has no sample. A lead held at the ceiling is said: the stop will then
likely come late.

An approach is planned before it is sent, and its start's state is known, so only its delivery delays it: its lead
is the same rule over a motion's delivery alone (START). Too short, and the controller drops its first points and the
delivery's delay counts as tracking error; too long only starts the approach later.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from sim.study.run.errors import RunError
from sim.study.safety.separation import STOP_LEAD_CEILING

__all__ = [
    "PARTS",
    "STOP",
    "START",
    "STOP_SIZED",
    "QUANTILE",
    "MARGIN",
    "FLOOR",
    "CEILING",
    "KEPT",
    "START_FLOOR",
    "Leads",
    "LeadChoice",
    "delivery_part",
]

PARTS = ("query", "planning", "delivery", "motion_delivery")
STOP = ("query", "planning", "delivery")  # what a stop's preparation waits for
START = ("motion_delivery",)  # what an approach's start waits for
STOP_SIZED = 80  # points: a stop from 0.5 m/s at 1 m/s² has ~55 of 10 ms; a motion's goal has 100 and more
_STANDS_IN = {"delivery": "motion_delivery", "motion_delivery": "delivery"}  # until a part has a sample
QUANTILE = 0.99  # of each part's samples: a stop is rare and must not be late
MARGIN = 0.005  # s on top: the sum's own scatter (the next delay may be the worst yet)
FLOOR = 0.01  # s: no shorter, whatever was measured (a loopback's sub-millisecond round trips)
CEILING = STOP_LEAD_CEILING  # s: no longer; at 0.5 m/s the arm runs on 0.125 m before it brakes
KEPT = 500  # the latest samples of each part: the session's recent network and load
# s: the least a motion's start is stamped ahead. A motion delivered after its stamp has its first points dropped and
# is bridged from rest to the first one left, over what may be a fraction of a millisecond: an arbitrary acceleration
# (seen: 16x joint 4's limit on a loaded machine). Nothing waits on a motion's start as a stop's brake does, so it is
# given room beyond the measured delivery's tail: it only starts later.
START_FLOOR = 0.25


@dataclass(frozen=True)
class LeadChoice:
    lead: float  # s
    parts: dict[str, float]  # s, each part's quantile (NaN: no sample yet)
    samples: dict[str, int]
    limited: str  # "" or why the lead is not the measured sum: "floor", "ceiling", "no <part> measured"

    def describe(self) -> str:
        """One line: the lead and what it is made of."""
        parts = ", ".join(
            f"{name} {value * 1e3:.1f} ms of {self.samples[name]}" if math.isfinite(value) else f"{name} unmeasured"
            for name, value in self.parts.items()
        )
        if self.limited.startswith("no "):
            said = f" ({self.limited}: the ceiling)"
        else:
            said = f" (held at the {self.limited})" if self.limited else ""
        return f"{self.lead * 1e3:.1f} ms{said}: p{QUANTILE * 100:g} {parts}, margin {MARGIN * 1e3:g} ms"


class Leads:
    """The measured delays of one link, and the leads they give."""

    def __init__(
        self,
        quantile: float = QUANTILE,
        margin: float = MARGIN,
        floor: float = FLOOR,
        ceiling: float = CEILING,
        kept: int = KEPT,
    ) -> None:
        if not (0.5 <= quantile <= 1.0 and 0.0 <= margin and 0.0 < floor <= ceiling and math.isfinite(ceiling)):
            raise RunError(
                f"a stop's lead needs a quantile in [0.5, 1], a margin >= 0 and 0 < floor <= ceiling, got "
                f"{quantile!r}, {margin!r}, [{floor!r}, {ceiling!r}]"
            )
        self.quantile, self.margin, self.floor, self.ceiling = quantile, margin, floor, ceiling
        self._samples: dict[str, deque[float]] = {part: deque(maxlen=kept) for part in PARTS}

    def add(self, part: str, seconds: float) -> None:
        """A measured delay of `part` (one of PARTS)."""
        if part not in self._samples:
            raise RunError(f"a stop's lead has the parts {', '.join(PARTS)}, not {part!r}")
        if not (math.isfinite(seconds) and seconds >= 0):
            raise RunError(f"a measured {part} delay must be finite and >= 0 s, got {seconds!r}")
        self._samples[part].append(float(seconds))

    def part(self, part: str) -> float:
        """s: the part's QUANTILE (the largest while it has too few samples to resolve it); NaN unmeasured."""
        samples = self._samples[part]
        if not samples:
            return math.nan
        if len(samples) < 1.0 / max(1.0 - self.quantile, 1e-9):
            return max(samples)
        ordered = sorted(samples)
        return ordered[math.ceil(self.quantile * (len(ordered) - 1))]  # the sample at or above the quantile

    def choose(self, parts_waited_for: tuple[str, ...] = STOP) -> LeadChoice:
        """The lead of a goal whose preparation waits for `parts_waited_for` (STOP or START)."""
        parts: dict[str, float] = {}
        samples: dict[str, int] = {}
        for part in parts_waited_for:
            measured = part
            if not self._samples[part] and self._samples.get(_STANDS_IN.get(part, part)):
                measured = _STANDS_IN[part]  # unmeasured yet: the other goals' delivery stands in
            name = part if measured == part else f"{part} (as {measured})"
            parts[name], samples[name] = self.part(measured), len(self._samples[measured])
        missing = [part for part, value in parts.items() if math.isnan(value)]
        if missing:
            return LeadChoice(self.ceiling, parts, samples, f"no {' or '.join(missing)} measured")
        wanted = sum(parts.values()) + self.margin
        lead = min(max(wanted, self.floor), self.ceiling)
        limited = "floor" if wanted < self.floor else "ceiling" if wanted > self.ceiling else ""
        return LeadChoice(lead, parts, samples, limited)


def delivery_part(points: int) -> str:
    """The part a goal of `points` points measures: a stop's `delivery`, or a motion's."""
    return "delivery" if points <= STOP_SIZED else "motion_delivery"
