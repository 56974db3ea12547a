"""sim.study.design.holding: a joint whose static load exceeds its effort limit anywhere is named once, at its
worst sample, with the load and the limit in the joint's own unit. Pure logic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.study.design.holding import Shortfall, holding_line, shortfalls

NAMES = ("lift", "shoulder", "elbow")
TYPES = ("prismatic", "revolute", "continuous")


def test_every_joint_within_its_limit_holds_the_arm() -> None:
    loads = np.array([[103.0, 5.0, -2.0], [103.0, -40.0, 1.0]])
    assert shortfalls(NAMES, TYPES, loads, np.array([400.0, 40.0, math.inf])) == []


def test_a_joint_beyond_its_limit_is_named_at_its_worst_sample_in_its_unit() -> None:
    loads = np.array([[103.0, 5.0, 0.0], [103.5, -45.0, 0.0], [103.0, -41.0, 0.0]])
    found = shortfalls(NAMES, TYPES, loads, np.array([100.0, 40.0, 1.0]))
    assert found == [Shortfall("lift", "N", 103.5, 100.0, 1), Shortfall("shoulder", "N·m", 45.0, 40.0, 1)]
    assert holding_line(found[0], "at t = 0.02 s") == (
        "lift cannot hold the arm at t = 0.02 s: it needs 103.5 N, its effort limit is 100 N"
    )
    assert holding_line(found[1], "at home") == (
        "shoulder cannot hold the arm at home: it needs 45.0 N·m, its effort limit is 40 N·m"
    )


def test_no_samples_hold_nothing_back_and_shapes_must_match() -> None:
    assert shortfalls(NAMES, TYPES, np.zeros((0, 3)), np.ones(3)) == []
    with pytest.raises(ValueError, match="3 joints"):
        shortfalls(NAMES, TYPES, np.zeros((2, 2)), np.ones(3))
