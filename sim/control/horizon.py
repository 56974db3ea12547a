"""The commander's schedule as a ros_control trajectory controller takes it: windows of a horizon, sent as
replacements, and the achieved joints read back at the schedule's times. Pure logic.

Every window is stamped with the same start (the wall time of the schedule's sample 0) and carries the schedule's
samples after its first step, each with `time_from_start` = its schedule time, positions and velocities. A window
sent while the one before is running replaces it seamlessly: the controller keeps the current trajectory up to now
and bridges from its desired state to the first sample still ahead, and that bridge is the very cubic the two
samples around now make (the rest of a cubic is the cubic through the same ends), as long as the window holds
every sample due after it goes out. The first window goes out `lead` steps before sample 0 (its stamp is in the
future: the controller holds until then), the next every `period` steps, each with the `horizon` samples due after
it goes out: the controller never runs out of trajectory as long as a window arrives within horizon - period
steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.errors import SimError

__all__ = ["HorizonError", "Window", "windows", "hermite_at", "achieved_at"]


class HorizonError(SimError, ValueError):
    """A horizon that cannot work (shorter than its period, no samples)."""


@dataclass(frozen=True)
class Window:
    first: int  # the schedule index of the window's first sample: the first due after it goes out (never 0)
    last: int  # its last, inclusive
    send_at: float  # s from sample 0 (negative: before it): when the window goes out

    @property
    def indices(self) -> range:
        return range(self.first, self.last + 1)


def windows(steps: int, dt: float, horizon: int, period: int, lead: int) -> list[Window]:
    """The windows that send a schedule of samples 0..`steps` (`dt` apart): the first goes out `lead` steps before
    sample 0 is due, the next every `period` steps after it; each holds the `horizon` samples due after it goes out
    (never sample 0: where the robot starts), and the last reaches sample `steps`."""
    if steps < 1 or not (math.isfinite(dt) and dt > 0):
        raise HorizonError(f"a schedule needs at least one step of a dt > 0, got {steps} steps of {dt!r} s")
    if period < 1 or lead < 1 or horizon <= period + 1:
        raise HorizonError(
            f"the horizon ({horizon} steps) must exceed the period ({period} >= 1) by 2 steps and the lead be >= 1 "
            f"({lead}): a window must still hold a sample to come when the next goes out"
        )
    out = []
    sent = -lead  # in steps from sample 0
    while True:
        first = max(1, sent + 1)
        last = min(first + horizon - 1, steps)
        out.append(Window(first, last, sent * dt))
        if last == steps:
            return out
        sent += period


def hermite_at(stamps: np.ndarray, positions: np.ndarray, velocities: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The positions at times `at` between joint states (stamps, positions, velocities per row): the cubic through
    the two states around each time, their positions and velocities. NaN outside the states' span."""
    stamps = np.asarray(stamps, dtype=float)
    positions = np.asarray(positions, dtype=float)
    velocities = np.asarray(velocities, dtype=float)
    at = np.asarray(at, dtype=float)
    out = np.full((len(at), positions.shape[1]), np.nan)
    if len(stamps) < 2:
        return out
    if np.any(np.diff(stamps) <= 0):
        raise HorizonError("joint-state stamps must increase strictly")
    inside = (at >= stamps[0]) & (at <= stamps[-1])
    k = np.clip(np.searchsorted(stamps, at[inside], side="right") - 1, 0, len(stamps) - 2)
    h = (stamps[k + 1] - stamps[k])[:, None]
    s = (at[inside] - stamps[k])[:, None] / h
    p0, p1, v0, v1 = positions[k], positions[k + 1], velocities[k] * h, velocities[k + 1] * h
    out[inside] = (
        (2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * v0 + (-2 * s**3 + 3 * s**2) * p1 + (s**3 - s**2) * v1
    )
    return out


def achieved_at(stamps: np.ndarray, positions: np.ndarray, velocities: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The achieved positions at times `at` from joint states as they came (a stamp no later than the one before is
    left out): `hermite_at` where every state has its velocities, linear between states otherwise (a driver that
    publishes none: NaN velocities). NaN outside the states' span."""
    stamps = np.asarray(stamps, dtype=float)
    at = np.asarray(at, dtype=float)
    keep = np.ones(len(stamps), dtype=bool)
    if len(stamps):
        keep[1:] = stamps[1:] > np.maximum.accumulate(stamps)[:-1]
    stamps, positions, velocities = stamps[keep], np.asarray(positions)[keep], np.asarray(velocities)[keep]
    if np.all(np.isfinite(velocities)):
        return hermite_at(stamps, positions, velocities, at)
    out = np.full((len(at), positions.shape[1]), np.nan)
    if len(stamps) >= 2:
        inside = (at >= stamps[0]) & (at <= stamps[-1])
        for j in range(positions.shape[1]):
            out[inside, j] = np.interp(at[inside], stamps, positions[:, j])
    return out
