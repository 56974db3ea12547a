"""The session's clocks beside the runner's: the pages' (a VR page, the stop button's), which stamp presses and poses
on ROS time by an offset they estimate, and the robot's (sim.study.run.links.clock, measured by its link). Pure
logic, thread-safe (announcements come on rospy's threads), and one small writer.

A page estimates ROS time minus its own clock NTP-style, from the endpoint's ping answers: ROS time at the middle of
the quickest recent round trip (views/vr/web/clock.js). It announces its estimate after every answer on
PAGE_CLOCK_TOPIC (sim.study.run.protocol): the estimate, that round trip, the offset it stamps with now (slewed
towards the estimate, so its readings never run backwards) and how many samples it has. A stamp it makes is off the
runner's clock by at most half the round trip plus the applied offset's lag behind the estimate: its uncertainty.
Two estimates further apart than their half round trips (and ROS time's own step) explain mean a clock stepped (the
page's, or ROS time restarted): its stamps in between were off by the step.

The runner judges the pages at go before each approach: a page whose clock as it stands (its latest announcement's
uncertainty), or a step between two of its estimates since the last check (from the session's first approach on),
exceeds PAGE_CLOCK_LIMIT refuses the session (ClockError, one line). In real time, a clock beyond the limit as it
stands is first given PAGE_CLOCK_SETTLE_S to come within it, the arm held at the approach's start
(sim.study.run.runner).
"""

from __future__ import annotations

import json
import math
import threading
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable

from sim.study.run.errors import RunError

__all__ = [
    "FOLDER",
    "PAGE_CLOCK_LIMIT",
    "PAGE_CLOCK_SETTLE_S",
    "ClockError",
    "PageClock",
    "PageClocks",
    "page_clock_from_json",
    "page_clock_to_json",
    "write_session_clocks",
]

FOLDER = "clocks"  # beside the records: clocks/participant_NN.json
# s: the most a page's stamps may be off the runner's clock. A press stamped 20 ms off reads the arm 20 ms early or
# late: 4 mm of its approach at 0.2 m/s (the study's fastest speed set), 6 mm at 0.3 m/s, on the primary measure,
# already at the edge of what the interpolated state at the press is trusted to (sim.study.run.trial); a headset on
# a quiet Wi-Fi measures round trips of a few ms, so a page beyond this has a network or a browser that is not fit.
PAGE_CLOCK_LIMIT = 0.02
# s: how long the runner holds the arm at an approach's start, in real time, for a page's clock beyond the limit as it
# stands to come within it before the session is refused. A page's stamps are only as good as its quickest round trip,
# and a page reads a ping's answer only when its main thread is free: at the first go, a page whose clock started with
# the runner's /clock has a few seconds of samples, taken as the runner, the endpoint and its own frames compete for
# the CPU (software-rendered Chromium beside other work once had none quicker than 60 ms then). It pings 4 times a
# second while unsettled (views/vr/web/clock.js): 20 more chances to see an answer between two frames. A step between
# its estimates is refused at once: waiting does not undo stamps already off.
PAGE_CLOCK_SETTLE_S = 5.0


class ClockError(RunError):
    """A clock of the session cannot be trusted: the session is refused (before its next trial)."""


@dataclass(frozen=True)
class PageClock:
    """A page's announcement of its clock."""

    source: str  # the page's stop source (the protocol's stop_sources: vr_trigger, button), which names the page
    offset: float  # s: ROS time minus the page's clock, its estimate
    round_trip: float  # s: the quickest recent round trip, the estimate's
    applied: float  # s: the offset the page stamps with now
    samples: int  # ping answers the estimate is of

    @property
    def uncertainty(self) -> float:
        """s: the most a stamp the page makes now is off the runner's clock."""
        return self.round_trip / 2 + abs(self.applied - self.offset)


def page_clock_to_json(clock: PageClock) -> str:
    return json.dumps({"source": clock.source, **{k: v for k, v in asdict(clock).items() if k != "source"}})


def page_clock_from_json(text: str) -> PageClock:
    """An announcement as it comes; RunError naming what is wrong with it."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise RunError(f"a page's clock is not JSON: {error}") from None
    names = ["source", "offset", "round_trip", "applied", "samples"]
    if not isinstance(data, dict) or sorted(data) != sorted(names):
        raise RunError(f"a page's clock must have exactly {', '.join(names)}, got {text[:200]!r}")
    numbers = [data[name] for name in ("offset", "round_trip", "applied")]
    if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in numbers):
        raise RunError(f"a page's clock needs finite numbers, got {text[:200]!r}")
    if not (isinstance(data["source"], str) and data["source"] and data["round_trip"] >= 0):
        raise RunError(f"a page's clock needs a source and a round trip >= 0, got {text[:200]!r}")
    if not (isinstance(data["samples"], int) and data["samples"] >= 1):
        raise RunError(f"a page's clock needs samples >= 1, got {text[:200]!r}")
    return PageClock(data["source"], float(data["offset"]), float(data["round_trip"]), float(data["applied"]),
                     data["samples"])  # fmt: skip


def step_between(before: PageClock, after: PageClock, quantum: float = 0.0) -> float:
    """s the estimate moved from `before` to `after` beyond what their half round trips and ROS time's own step
    (`quantum`) explain (0: within them)."""
    explained = (before.round_trip + after.round_trip) / 2 + quantum
    return max(0.0, abs(after.offset - before.offset) - explained)


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.1f} ms"


class PageClocks:
    """The pages' announcements heard in a session, by page; what they say of each trial, and whether to go on."""

    def __init__(self, limit: float = PAGE_CLOCK_LIMIT, quantum: float = 0.0) -> None:
        # quantum, s: ROS time's own step as the endpoint answers pings with it (the runner's /clock in real time
        # steps every dt, and the endpoint answers with its latest, up to a step behind): two estimates may differ by
        # it with no clock stepping
        self.limit, self.quantum = limit, quantum
        self._lock = threading.Lock()
        self._heard: dict[str, list[PageClock]] = {}  # by source, in order
        self._checked: dict[str, int] = {}  # by source: announcements judged by check()
        self._marked: dict[str, int] = {}  # by source: announcements before the current approach's (trial())
        # by source: announcements before the session's first approach began (None until it has): a step before it
        # was off for no press, and the pages' first estimates ride on the runner's /clock as it starts
        self._first_go: dict[str, int] | None = None

    def heard(self, clock: PageClock) -> None:
        with self._lock:
            self._heard.setdefault(clock.source, []).append(clock)

    def check(self) -> str:
        """Why the session cannot go on ("" when it can), judging what was heard since the last check: a page whose
        clock as it stands (its latest announcement) is off by more than the limit, or a step beyond it between two of
        its estimates from the one in force as the session's first approach began (before it, no press counted: a
        page's first estimate once carried the runner's /clock as it started, 80 ms stale). A transient that has
        settled by the check (a slewing offset catching up, one slow round trip) refuses nothing: each trial records
        its page's worst uncertainty during it (`trial`)."""
        with self._lock:
            for source, clocks in self._heard.items():
                first = self._checked.get(source, 0)
                self._checked[source] = len(clocks)
                if first == len(clocks):
                    continue  # nothing new: judged already
                clock = clocks[-1]
                if clock.uncertainty > self.limit:
                    return (
                        f"the {source} page's clock cannot be trusted: its stamps {self._skew(clock)}: bring the page "
                        "nearer the runner (a quieter network)"
                    )
                if self._first_go is None:
                    continue  # no approach yet: no press was stamped, whatever a step did to the stamps
                # each pair not judged yet, from the estimate in force as the first approach began
                for k in range(max(first, self._first_go.get(source, 0), 1), len(clocks)):
                    step = step_between(clocks[k - 1], clocks[k], self.quantum)
                    if step > self.limit:
                        return (
                            f"the {source} page's clock stepped {_ms(step)} beyond its round trips (its offset "
                            f"{clocks[k - 1].offset:+.4f} s, then {clocks[k].offset:+.4f} s; limit "
                            f"{_ms(self.limit)}): presses stamped in between were off by as much"
                        )
        return ""

    def unsettled(self) -> str:
        """Which pages' clocks as they stand (their latest announcements) are beyond the limit, and by how much
        ("": none). It judges nothing: check() still will."""
        with self._lock:
            latest = [clocks[-1] for clocks in self._heard.values()]
        return "; ".join(
            f"the {clock.source} page's stamps {self._skew(clock)}"
            for clock in latest
            if clock.uncertainty > self.limit
        )

    def _skew(self, clock: PageClock) -> str:
        return (
            f"may be off by {_ms(clock.uncertainty)} (half its best round trip {_ms(clock.round_trip / 2)}, "
            f"its applied offset {_ms(abs(clock.applied - clock.offset))} off its estimate; limit {_ms(self.limit)})"
        )

    def heard_json(self, text: str, log: Callable[[str], None]) -> None:
        """An announcement as it comes on the topic; one that is none is logged and dropped."""
        try:
            self.heard(page_clock_from_json(text))
        except RunError as error:
            log(f"a page's clock was refused: {error}")

    def refuse(self) -> None:
        """ClockError with check()'s reason when the session cannot go on."""
        reason = self.check()
        if reason:
            raise ClockError(reason)

    def approach_begins(self) -> None:
        """The runner trusted the pages' clocks at go: the trial's record (trial()) counts from each page's estimate in
        force now. A press counts only from the approach on, so a clock that settled while the arm held at the start
        was off for no press of the trial."""
        with self._lock:
            self._marked = {source: len(clocks) for source, clocks in self._heard.items()}
            if self._first_go is None:
                self._first_go = dict(self._marked)

    def trial(self, source: str) -> tuple[float, float]:
        """The `source` page's clock over the trial that ends now, and the next one begins: (its offset as it ended,
        s; the most its stamps were off during it, s: the uncertainty of the estimate in force as its approach began
        (approach_begins; without it, as the trial began) and of those heard since). NaN, NaN when that page never
        announced its clock."""
        with self._lock:
            clocks = self._heard.get(source, [])
            began = self._marked.get(source, 0)
            self._marked[source] = len(clocks)
        if not clocks:
            return math.nan, math.nan
        during = clocks[max(began - 1, 0) :]  # the one in force as the approach (or the trial) began, and each since
        return clocks[-1].offset, max(clock.uncertainty for clock in during)

    def summary(self) -> dict[str, dict[str, Any]]:
        """By page: how many announcements, its first and last offset (s), its least round trip and its largest
        uncertainty and step (s)."""
        with self._lock:
            heard = {source: list(clocks) for source, clocks in self._heard.items()}
        return {
            source: {
                "announcements": len(clocks),
                "offset_first_s": clocks[0].offset,
                "offset_last_s": clocks[-1].offset,
                "round_trip_least_s": min(clock.round_trip for clock in clocks),
                "uncertainty_largest_s": max(clock.uncertainty for clock in clocks),
                "step_largest_s": max(
                    (step_between(a, b, self.quantum) for a, b in zip(clocks, clocks[1:])), default=0.0
                ),
            }
            for source, clocks in heard.items()
        }


def write_session_clocks(path: Path, participant: int, robots: dict[str, float], pages: PageClocks) -> None:
    """The session's clocks in `path` (JSON): the robot links' offsets at connect (s, by link; NaN: no clock of its
    own, written null), the pages' summary and the limit they were held to."""
    record = {
        "participant": participant,
        "robot_clock_offset_at_connect_s": {
            name: (offset if math.isfinite(offset) else None) for name, offset in robots.items()
        },
        "page_clock_limit_s": pages.limit,
        "pages": pages.summary(),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=2) + "\n")
