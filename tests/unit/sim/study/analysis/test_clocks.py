"""sim.study.analysis.clocks on records of known values: per condition, the robot's clock offset and its drift, the
page's stamps' uncertainty and how far its offset moved; – where a condition has no such clock (never 0); nothing
for records without any clock."""

from __future__ import annotations

from dataclasses import replace

from sim.study.analysis.clocks import clock_lines
from tests.unit.sim.study.analysis.test_latency import PRESS


def test_each_condition_has_its_clocks_and_a_clock_it_has_not_is_a_dash_not_zero() -> None:
    assert clock_lines([PRESS]) == []  # written before the clocks' columns, or without any clock
    vr = [replace(PRESS, index=k, page_clock_offset=12.0 + 0.001 * k, page_clock_uncertainty=0.002 * k) for k in (1, 2)]
    reality = [
        replace(PRESS, condition="reality", index=k, robot_clock_offset=0.030 + 0.001 * k, robot_clock_drift=0.0005 * k)
        for k in (3, 4, 5)
    ]
    lines = clock_lines([*vr, *reality])
    assert lines[0] == "## The clocks"
    (vr_row,) = [line for line in lines if line.startswith("| vr |")]
    (reality_row,) = [line for line in lines if line.startswith("| reality |")]
    assert vr_row == "| vr | 2 | – | – | 3.0 / 4.0 | 1.0 |"  # the stream's robot has no clock of its own
    assert reality_row == "| reality | 3 | +34.0 / +35.0 | 2.0 / 2.5 | – | – |"  # no page said its clock
