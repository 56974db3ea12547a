"""A stop's run-on: how much further the arm braked than its braking replacement planned (a trial record's
braking_distance_achieved − braking_distance), and the bound it must keep. Pure; the fault bench applies it to
each pressed trial of its sweep and faults.

The two distances start at different places (sim.study.run.links.trajectory). The planned braking starts at the
replacement's stamp, from the controller's desired state then; the achieved one starts at the press, from the
achieved state then, and ends at the achieved rest. So the run-on is made of, and bounded by:

  - the commanded travel from the press to the stamp. The arm follows its approach until the stamp, at most at the
    plan's highest path speed over that interval. The interval is at most the replacement's latency (the press to
    its sending; its preparation began before it was sent) plus its stop lead (the preparation to the stamp): the
    measured lead's slack is in both.
  - the tracking error, as the achieved arc measures it. The arc is the projection of a joint state on the path in
    joint space. A joint error of at most e on each joint (the record's tracking_error) moves it by at most
    √dof · e / min |dq/ds| (the path's least joint-space rate, rad per m). This happens twice: at the press and at
    rest.
  - the state at the press, interpolated between joint states h s apart (sim.study.run.trial.state_at), which is off
    by at most a · h² / 8 for a path acceleration of at most a.

A run-on past this bound is one the toolkit cannot account for: a stop stamped later than it said, or a braking the
controller did not execute as sent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["RunOn", "run_on_bound", "distribution"]


@dataclass(frozen=True)
class RunOn:
    """One stop's run-on and its bound (m)."""

    value: float  # achieved − planned braking
    bound: float

    @property
    def within(self) -> bool:
        return self.value <= self.bound


def run_on_bound(
    times: np.ndarray,
    speeds: np.ndarray,
    press_time: float,
    latency: float,
    lead: float,
    tracking_error: float,
    dof: int,
    joint_rate: float,
    acceleration: float,
    state_interval: float,
) -> float:
    """m: the largest run-on the module's doc accounts for. A press `press_time` s into a plan of path `speeds` (m/s)
    at `times`; the replacement sent `latency` s after the press and stamped `lead` s after its preparation began; a
    joint tracking error of at most `tracking_error` rad on each of `dof` joints, on a path of least joint-space rate
    `joint_rate` (rad/m); a path acceleration of at most `acceleration` (m/s²); joint states `state_interval` s
    apart."""
    values = (press_time, latency, lead, tracking_error, joint_rate, acceleration, state_interval)
    if not all(math.isfinite(v) and v >= 0 for v in values) or joint_rate <= 0:
        raise ValueError(f"a run-on's bound needs finite figures >= 0 (a joint rate > 0), got {values}")
    reaction = latency + lead
    end = press_time + reaction
    inside = speeds[(times > press_time) & (times < end)]
    fastest = float(max(np.interp([press_time, end], times, speeds).max(), inside.max() if inside.size else 0.0))
    travel = fastest * reaction
    tracking = 2 * math.sqrt(dof) * tracking_error / joint_rate
    interpolation = acceleration * state_interval**2 / 8
    return travel + tracking + interpolation


def distribution(run_ons: list[RunOn]) -> str:
    """One line: the run-ons' median, 95th percentile and largest (mm), and the least margin to their bounds."""
    if not run_ons:
        return "run-on: no stop measured"
    values = np.array([r.value for r in run_ons]) * 1e3
    margins = np.array([r.bound - r.value for r in run_ons]) * 1e3
    worst = int(np.argmin(margins))
    return (
        f"run-on (achieved − planned braking) of {len(run_ons)} stops [mm]: median {np.median(values):.1f}, "
        f"p95 {np.percentile(values, 95):.1f}, max {values.max():.1f}; bound per stop (module bench.run_on) "
        f"{np.median([r.bound * 1e3 for r in run_ons]):.1f} median, least margin {margins[worst]:.1f} "
        f"({values[worst]:.1f} of {run_ons[worst].bound * 1e3:.1f})"
    )
