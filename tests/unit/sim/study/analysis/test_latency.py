"""sim.study.analysis.latency on records of known latencies: each path's median and 95th percentile, the button's
minus the trigger's, and the participants whose presses came from the observer's keyboard, flagged in the report."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sim.study.analysis.latency import Spread, keyboard_flag, latency_lines, summarise_latency
from sim.study.analysis.report import write_report
from sim.study.run.records import TrialRecord
from tests.unit.sim.study.analysis.test_summary import study

PRESS = TrialRecord(
    1, 1, "vr", 1, 2, "straight", 0.0, 0.2, "medium", 1, 10.0, True, 2.0, "vr_trigger", 0.0,
    0.05, 0.04, 0.05, 0.01, math.nan, "",
)  # fmt: skip


def presses(participant: int, condition: str, source: str, inputs: list[float], arrivals: list[float]):
    return [
        replace(PRESS, participant=participant, condition=condition, press_source=source, index=k + 1,
                press_input_delay=i, press_arrival_delay=a)
        for k, (i, a) in enumerate(zip(inputs, arrivals))
    ]  # fmt: skip


def test_a_spread_is_the_median_and_95th_percentile_of_what_was_measured() -> None:
    spread = Spread.of([0.010, math.nan, 0.030, 0.020] + [0.001 * k for k in range(1, 18)])
    values = [0.010, 0.030, 0.020] + [0.001 * k for k in range(1, 18)]
    assert spread.measured == 20
    assert spread.median == pytest.approx(np.median(values)) and spread.p95 == pytest.approx(np.percentile(values, 95))
    empty = Spread.of([math.nan])
    assert empty.measured == 0 and math.isnan(empty.median) and math.isnan(empty.p95)


def test_each_path_is_summarised_and_the_buttons_minus_the_triggers_is_stated() -> None:
    records = presses(1, "vr", "vr_trigger", [0.011, 0.013, 0.012], [0.004, 0.006, 0.005]) + presses(
        1, "reality", "button", [0.008, 0.007, 0.009], [0.003, math.nan, 0.002]
    )
    records.append(replace(PRESS, pressed=False, press_source="", press_input_delay=0.5))  # no press: not counted
    summary = summarise_latency(records)
    assert [p.source for p in summary.paths] == ["vr_trigger", "button"]  # the protocol's order
    trigger, button = summary.path("vr_trigger"), summary.path("button")
    assert trigger is not None and button is not None
    assert trigger.presses == 3 and trigger.input_delay.median == pytest.approx(0.012)
    assert trigger.total.median == pytest.approx(0.017)
    assert button.arrival_delay.measured == 2 and button.arrival_delay.median == pytest.approx(0.0025)
    assert button.total.measured == 2 and button.total.median == pytest.approx(0.011)  # (0.011 + 0.011) / 2
    lines = "\n".join(latency_lines(summary))
    assert "| button | 3 | 8.0 | 8.9 | 3 | 2.5 |" in lines
    assert "medians: input delay -4.0 ms, arrival delay -2.5 ms, total -6.0 ms" in lines
    assert "(0.2 m/s) the measured input delays' difference puts reality's stops -0.8 mm further" in lines
    # what neither page measures (the press to its first reading, 16 ms at most) makes it a bound, said so
    assert "bounded, not measured: it lies within ±3.2 mm of this one" in lines
    assert keyboard_flag(summary) == "" and "observer" not in lines


def test_presses_from_the_keyboard_are_flagged_by_participant_and_condition_first_in_the_report(
    tmp_path: Path,
) -> None:
    records = [
        replace(r, press_source="keyboard") if r.participant == 3 and r.condition == "reality" and r.pressed else r
        for r in study(participants=4)
    ]
    summary = summarise_latency(records)
    assert summary.observer_presses == {3: {"reality": 9}}
    keyboard = summary.path("keyboard")
    assert keyboard is not None and keyboard.input_delay.measured == 0  # nobody measures the observer
    assert "No difference between the paths" in "\n".join(latency_lines(summary))  # test_summary's are all button
    report = write_report(records, tmp_path).read_text()
    flag = "**Presses from the observer's keyboard**: participant 3 (9 in reality)"
    assert report.index(flag) < report.index("## Test 1") < report.index("## Stop presses: latency")
    assert report.count(flag) == 2  # at the top, and in the latency section
