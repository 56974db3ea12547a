"""The engine's one clock: when to run the fixed physics steps, and the time each step ends at. Pure logic.

Two policies, like Unity's Physics.autoSimulate:
- **auto-simulate**: the engine's own wall clock drives the steps, `time_scale` times faster than real time. Once a
  /clock value has been seen, a step ends at the controller's time when it runs (its newest /clock, extrapolated
  along the wall clock × time_scale), so commands and joint states share one time base, and stamps never go back
  behind a /clock already seen; steps that fall due together end dt apart, the last one now. A /clock that comes
  late pulls that estimate back by its lateness: a step then ends just after the one before it (MIN_ADVANCE_S)
  instead of before it, as long as the fall is within max_jump (beyond it the controller's clock was restarted, and
  is followed). Before any /clock, steps end on the engine's own sim time (steps × dt).
- **clock-driven** (lockstep): the controller's /clock drives the steps. They end on the grid first value + k·dt,
  up to the newest /clock value.

Failsafe, both policies: when the driving clock (the wall clock, or /clock) moves by more than `max_jump` seconds at
once (a stalled machine, a paused controller, a restarted bag) or backwards, the missed steps are not run in a
burst. The clock re-anchors at the new value, runs no step, and says so (`ClockAdvance.resynced`) for the caller to
log.

Nothing here sleeps, reads a clock or steps anything: the caller passes the times in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.errors import SimError
from sim.wire.contract import STAMP_TOLERANCE_S

__all__ = ["ClockAdvance", "ClockError", "StepClock", "MIN_ADVANCE_S"]

MIN_ADVANCE_S = 1e-6  # how far a step's end is after the one before, at least, on the controller's time base


class ClockError(SimError, ValueError):
    """A clock setting or value that cannot drive the steps."""


@dataclass(frozen=True)
class ClockAdvance:
    """The steps to run now, by the times they end at (on the controller's time base where known)."""

    step_ends: tuple[float, ...] = ()
    anchored_at: float | None = None  # the driving clock value the step grid was (re-)anchored at, if it was
    resynced: bool = False  # re-anchored after a jump (not the first anchoring)
    jump: float = 0.0  # how far the driving clock moved since its previous value

    @property
    def steps(self) -> int:
        return len(self.step_ends)


class _Grid:
    """Fixed periods of a driving clock, counted from an anchor: which period ends a new reading has passed."""

    def __init__(self, period: float, max_jump: float) -> None:
        self.period = period
        self.max_jump = max_jump
        self.anchor: float | None = None  # driving clock value of the grid's origin
        self.last_seen: float | None = None
        self.done_since_anchor = 0

    def next_end(self) -> float | None:
        return None if self.anchor is None else self.anchor + (self.done_since_anchor + 1) * self.period

    def pending(self, t: float) -> int:
        """Periods advance_to(t) would complete; 1 when it would (re-)anchor instead (a waiting caller must not
        sleep through that either)."""
        if self.anchor is None or self._jumps(t):
            return 1
        return self._due(t)

    def advance_to(self, t: float) -> tuple[tuple[float, ...], float | None, float]:
        """(the period ends passed, marked done; the value the grid re-anchored at, if it did; the jump)."""
        if not math.isfinite(t):
            raise ClockError(f"clock value must be finite, got {t!r}")
        if self.anchor is None or self.last_seen is None or self._jumps(t):
            jump = 0.0 if self.last_seen is None else t - self.last_seen
            self.anchor, self.last_seen, self.done_since_anchor = t, t, 0
            return (), t, jump
        jump = t - self.last_seen
        self.last_seen = t
        due = self._due(t)
        first = self.done_since_anchor + 1
        ends = tuple(self.anchor + k * self.period for k in range(first, first + due))
        self.done_since_anchor += due
        return ends, None, jump

    def _jumps(self, t: float) -> bool:
        assert self.last_seen is not None
        return t < self.last_seen - 1e-12 or t - self.last_seen > self.max_jump

    def _due(self, t: float) -> int:
        assert self.anchor is not None
        return max(int(math.floor((t - self.anchor + STAMP_TOLERANCE_S) / self.period)) - self.done_since_anchor, 0)


class StepClock:
    """When to run fixed steps of `dt` s, by either policy (see the module). Reading /clock (`observe_clock`) may
    happen on another thread than the stepping: its value and arrival time are replaced together, as one tuple."""

    def __init__(self, dt: float, auto_simulate: bool = False, time_scale: float = 1.0, max_jump: float = 1.0) -> None:
        if not (math.isfinite(dt) and dt > 0):
            raise ClockError(f"the step dt must be > 0 s, got {dt!r}")
        if not (math.isfinite(time_scale) and time_scale > 0):
            raise ClockError(f"time_scale must be > 0, got {time_scale!r}")
        if not (math.isfinite(max_jump) and max_jump > 0):
            raise ClockError(f"max_jump must be > 0 s, got {max_jump!r}")
        self.dt = float(dt)
        self.auto_simulate = auto_simulate
        self.time_scale = float(time_scale)
        # auto-simulate: the wall clock drives, one step per dt / time_scale wall seconds; else /clock, one per dt.
        self._grid = _Grid(self.dt / self.time_scale if auto_simulate else self.dt, float(max_jump))
        self._controller: tuple[float, float] | None = None  # (newest /clock value, wall time it came)
        self._last_controller_end: float | None = None  # the last step's end on the controller's time base
        self.steps = 0  # steps run in total
        self.resyncs = 0
        self._anchored_before = False

    @property
    def time(self) -> float:
        """Sim seconds simulated so far (steps × dt), whatever the clock's origin and jumps."""
        return self.steps * self.dt

    # --- the controller's /clock (both policies) ----------------------------------------------------------------
    def observe_clock(self, value: float, wall_s: float) -> None:
        if not math.isfinite(value):
            raise ClockError(f"/clock value must be finite, got {value!r}")
        self._controller = (value, wall_s)

    @property
    def newest_clock(self) -> float | None:
        controller = self._controller
        return None if controller is None else controller[0]

    def controller_time(self, wall_s: float) -> float | None:
        """The controller's time at wall time `wall_s`: its newest /clock, extrapolated at time_scale (None before
        the first). It stays on that base while /clock pauses, so stamps never fall back to another one."""
        controller = self._controller
        if controller is None:
            return None
        value, seen_at = controller
        return value + (wall_s - seen_at) * self.time_scale

    # --- clock-driven -------------------------------------------------------------------------------------------
    def pending(self) -> int:
        """Non-zero when `advance()` has something to do: steps to run, or the grid to (re-)anchor."""
        self._require(auto_simulate=False)
        value = self.newest_clock
        return 0 if value is None else self._grid.pending(value)

    def advance(self) -> ClockAdvance:
        """The steps up to the newest /clock value, marked as done; they end on the /clock grid."""
        self._require(auto_simulate=False)
        value = self.newest_clock
        if value is None:
            return ClockAdvance()
        ends, anchored_at, jump = self._grid.advance_to(value)
        self.steps += len(ends)
        return self._advance(ends, anchored_at, jump)

    # --- auto-simulate ------------------------------------------------------------------------------------------
    def poll(self, wall_s: float) -> ClockAdvance:
        """The steps due by the wall clock, marked as done, stamped as the module says."""
        self._require(auto_simulate=True)
        wall_ends, anchored_at, jump = self._grid.advance_to(wall_s)
        first = self.steps + 1
        self.steps += len(wall_ends)
        controller = self._controller
        due = len(wall_ends)
        if controller is None:
            ends = tuple((first + k) * self.dt for k in range(due))
        else:
            # When the step runs, not when it was due: a late wake-up after a new /clock must not stamp behind it.
            now = controller[0] + (wall_s - controller[1]) * self.time_scale
            ends = self._after_last(tuple(now - (due - 1 - k) * self.dt for k in range(due)))
        return self._advance(ends, anchored_at, jump)

    def _after_last(self, ends: tuple[float, ...]) -> tuple[float, ...]:
        """`ends`, each after the end before it: a late /clock's fall within max_jump is not followed."""
        kept: list[float] = []
        last = self._last_controller_end
        for end in ends:
            if last is not None and 0 <= last - end <= self._grid.max_jump:
                end = last + MIN_ADVANCE_S
            kept.append(end)
            last = end
        self._last_controller_end = last
        return tuple(kept)

    def next_step_wall(self) -> float | None:
        """The wall time the next step is due at (None before the first poll)."""
        self._require(auto_simulate=True)
        return self._grid.next_end()

    def _advance(self, ends: tuple[float, ...], anchored_at: float | None, jump: float) -> ClockAdvance:
        resynced = anchored_at is not None and self._anchored_before
        if anchored_at is not None:
            self._anchored_before = True
        if resynced:
            self.resyncs += 1
        return ClockAdvance(ends, anchored_at, resynced, jump)

    def _require(self, auto_simulate: bool) -> None:
        if self.auto_simulate != auto_simulate:
            mine = "auto-simulated (poll)" if self.auto_simulate else "/clock-driven (pending, advance)"
            raise ClockError(f"this clock is {mine}")
