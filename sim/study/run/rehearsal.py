"""The rehearsal with the hand out of reach: the whole plan, every trial on its own path at its own speed, with each
approach ending a declared clearance further from the hand than planned, as if the hand had been moved that far
back along the approach. The lab watches the arm make every approach of the session before anybody sits down, and
no approach comes within the clearance of where the hand will rest. Pure."""

from __future__ import annotations

import math
from dataclasses import replace

from sim.study.design.plan import SessionPlan
from sim.study.run.errors import RunError

__all__ = ["out_of_reach"]


def out_of_reach(plan: SessionPlan, clearance: float) -> SessionPlan:
    """`plan` with every trial's stand-off `clearance` m larger (the rest as planned)."""
    if not (math.isfinite(clearance) and clearance > 0):
        raise RunError(f"--rehearsal-clearance must be > 0 m, got {clearance!r}")
    trials = tuple(replace(trial, standoff=round(trial.standoff + clearance, 6)) for trial in plan.trials)
    return replace(plan, trials=trials)
