"""A braking replacement's lead, and an approach's, from the delays a link measured: each part's high quantile summed
plus a margin, within a floor and a ceiling."""

from __future__ import annotations

import math

import pytest

from sim.study.run.errors import RunError
from sim.study.run.links.lead import CEILING, FLOOR, MARGIN, START, STOP_SIZED, Leads, delivery_part


def measured(query: list[float], planning: list[float], delivery: list[float], **options: float) -> Leads:
    lead = Leads(**options)
    for part, samples in (("query", query), ("planning", planning), ("delivery", delivery)):
        for seconds in samples:
            lead.add(part, seconds)
    return lead


def test_the_lead_is_each_parts_worst_so_far_summed_plus_the_margin() -> None:
    chosen = measured([0.002, 0.004], [0.010], [0.003, 0.020, 0.005]).choose()
    assert chosen.lead == pytest.approx(0.004 + 0.010 + 0.020 + MARGIN)
    assert chosen.limited == "" and chosen.samples == {"query": 2, "planning": 1, "delivery": 3}
    assert chosen.describe().startswith(f"{chosen.lead * 1e3:.1f} ms: p99 query 4.0 ms of 2, planning 10.0 ms of 1")


def test_with_enough_samples_the_lead_takes_the_quantile_and_a_rare_outlier_falls_out() -> None:
    lead = measured([0.001] * 200, [0.002] * 200, [0.003] * 199 + [0.5], quantile=0.99)
    assert lead.part("delivery") == 0.003  # 1 of 200 is above the 99th percentile
    lead.add("delivery", 0.4)
    lead.add("delivery", 0.45)
    assert lead.part("delivery") == 0.4  # 3 of 202: the 99th percentile is among them
    assert lead.choose().lead == CEILING  # 0.408 s wanted


def test_a_lead_is_held_within_its_floor_and_ceiling() -> None:
    quick = measured([1e-4], [1e-4], [1e-4]).choose()
    assert (quick.lead, quick.limited) == (FLOOR, "floor")
    slow = measured([0.1], [0.1], [0.2]).choose()
    assert (slow.lead, slow.limited) == (CEILING, "ceiling") and "(held at the ceiling)" in slow.describe()


def test_a_part_not_yet_measured_gives_the_ceiling() -> None:
    chosen = measured([0.001], [], [0.002]).choose()
    assert (chosen.lead, chosen.limited) == (CEILING, "no planning measured")
    assert math.isnan(chosen.parts["planning"]) and "planning unmeasured" in chosen.describe()


def test_an_approachs_start_waits_for_a_motions_delivery_alone() -> None:
    lead = measured([0.030], [0.040], [])
    for seconds in (0.006, 0.012):
        lead.add("motion_delivery", seconds)
    chosen = lead.choose(START)
    assert chosen.lead == pytest.approx(0.012 + MARGIN) and list(chosen.parts) == ["motion_delivery"]
    assert chosen.describe().endswith(f"p99 motion_delivery 12.0 ms of 2, margin {MARGIN * 1e3:g} ms")
    assert measured([0.030], [0.040], []).choose(START).limited == "no motion_delivery measured"


def test_a_stop_is_led_by_the_stops_own_delivery_and_by_a_motions_until_one_is_measured() -> None:
    # A motion's goal (hundreds of points) is delivered slower than a stop's (tens): the stop's lead is sized by the
    # stops' own deliveries once there is one; before, by the motions' (an upper bound), and it says so.
    assert (delivery_part(STOP_SIZED), delivery_part(STOP_SIZED + 1)) == ("delivery", "motion_delivery")
    lead = measured([0.002], [0.001], [])
    lead.add("motion_delivery", 0.040)
    before = lead.choose()
    assert before.lead == pytest.approx(0.002 + 0.001 + 0.040 + MARGIN)
    assert "delivery (as motion_delivery) 40.0 ms of 1" in before.describe()
    lead.add("delivery", 0.008)
    assert lead.choose().lead == pytest.approx(0.002 + 0.001 + 0.008 + MARGIN)
    assert lead.choose(START).lead == pytest.approx(0.040 + MARGIN)  # the approach's own, unchanged


def test_only_the_latest_samples_are_kept() -> None:
    lead = measured([0.001], [0.001], [0.2] + [0.003] * 10, kept=10)
    assert lead.part("delivery") == 0.003  # the early slow one has gone


@pytest.mark.parametrize(
    ("part", "seconds", "said"),
    [("network", 0.1, "not 'network'"), ("query", -0.001, "got -0.001"), ("delivery", math.nan, "got nan")],
)
def test_a_delay_that_is_no_delay_is_refused(part: str, seconds: float, said: str) -> None:
    with pytest.raises(RunError, match=said):
        Leads().add(part, seconds)


def test_bounds_that_make_no_lead_are_refused() -> None:
    with pytest.raises(RunError, match=r"0 < floor <= ceiling, got 0.99, 0.005, \[0.3, 0.2\]"):
        Leads(floor=0.3, ceiling=0.2)
