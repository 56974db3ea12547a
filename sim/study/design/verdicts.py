"""The plans a scene's fit made, handed to whatever plans the same combinations next in the same process.

A fit (sim.study.design.fit) plans and checks every combination of the design on the candidate that fits; a command
given --robot and no --scene (check, simulate, run) then plans the same combinations in that scene again. The fit's
plans are kept here, each under a key made of everything a plan depends on (verdict_key: the robot's content, every
field of the scene, the combination and the control step), and the next planner of exactly that input takes it
instead of planning again. Any other input (another stand-off, step, scene or URDF) has another key and is planned
afresh. A kept plan is taken once (then it is the taker's), and only the last fit's plans are kept.

`exact_text` and `verdict_key` are pure; `Kept` holds the plans.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping, Sequence
from typing import Any, Generic, TypeVar

import numpy as np

__all__ = ["Kept", "exact_text", "verdict_key"]

Plan = TypeVar("Plan")


def _exact(value: Any) -> Any:
    """`value` as JSON-ready data that tells every distinct value apart (a float by its repr, which round-trips);
    TypeError for a kind of value it does not know, so that no field is left out of a key unnoticed."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {field.name: _exact(getattr(value, field.name)) for field in dataclasses.fields(value)}
    if isinstance(value, np.ndarray):
        return {"shape": list(value.shape), "values": [_exact(v) for v in value.ravel().tolist()]}
    if isinstance(value, (list, tuple)):
        return [_exact(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, str) or value is None:
        return value
    if isinstance(value, (float, np.floating)):
        return repr(float(value))  # (a string: NaN and the infinities too, -0.0 apart from 0.0)
    raise TypeError(f"no exact text for {type(value).__name__} {value!r}")


def exact_text(value: Any) -> str:
    """One text for `value` (a scene, a combination, ...): equal texts for equal values, down to the last bit."""
    return json.dumps(_exact(value), sort_keys=True)


def verdict_key(robot_identity: str, scene: Any, combination: Sequence[Any], dt: float) -> str:
    """The key of one combination's plan: the robot's content (sim.robots.identity), every field of the scene, the
    combination (path, stand-off, peak speed) and the control step (s)."""
    text = json.dumps([robot_identity, exact_text(scene), exact_text(tuple(combination)), exact_text(dt)])
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


class Kept(Generic[Plan]):
    """The last fit's plans by verdict_key, each taken at most once."""

    def __init__(self) -> None:
        self._plans: dict[str, Plan] = {}

    def keep(self, plans: Mapping[str, Plan]) -> None:
        """These plans in place of any kept before."""
        self._plans = dict(plans)

    def take(self, key: str) -> Plan | None:
        """The plan kept under `key`, no longer kept; None where there is none."""
        return self._plans.pop(key, None)

    def __bool__(self) -> bool:
        return bool(self._plans)
