"""sim.study.analysis.links on records of known values: per condition on a trajectory controller, the tracking
error, the goals' leads, the press-to-braking latencies and the braking distance planned against achieved; nothing
for the stream."""

from __future__ import annotations

from dataclasses import replace

from sim.study.analysis.links import link_lines
from tests.unit.sim.study.analysis.test_latency import PRESS

LINK = "franka_ros (/position_joint_trajectory_controller)"


def test_only_conditions_on_a_trajectory_controller_are_reported_with_their_measures() -> None:
    assert link_lines([PRESS]) == []  # the stream's rows say nothing of a controller
    reality = [
        replace(
            PRESS, condition="reality", index=k, link=LINK, goal_result="SUCCEEDED", error_code=0,
            tracking_error=0.002 * k, replacement_latency=0.001 * k, braking_latency=0.030 + 0.001 * k,
            braking_distance=0.020, braking_distance_achieved=0.020 + 0.001 * k, start_lead=0.010 + 0.001 * k,
            stop_lead=0.020,
        )
        for k in (1, 2, 3)
    ]  # fmt: skip
    stopped = replace(
        reality[0], index=4, pressed=False, goal_result="ABORTED", safety_stop="tracking error 0.2 rad", stop_lead=0.030
    )
    lines = link_lines([PRESS, *reality, stopped])
    (row,) = [line for line in lines if line.startswith("| reality |")]
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    assert cells[:4] == ["reality", LINK, "4", "3 SUCCEEDED, 1 ABORTED"]
    assert cells[5] == "11.5 / 12.9"  # the start's lead, ms: every trial's 11, 12, 13, 11
    assert cells[6] == "20.0 / 28.5"  # the stop's, ms: every stop's, the runner's own included (20, 20, 20, 30)
    assert cells[7] == "2.0 / 2.9"  # to the replacement, ms: the pressed trials' 1, 2, 3
    assert cells[8] == "32.0 / 32.9"
    assert cells[9:13] == ["20.0 / 20.0", "22.0 / 22.9", "2.0 / 2.9", "1"]
    assert not any(line.startswith("| vr |") for line in lines)
    assert lines[-2] == "The runner stopped the arm on its own in trial 4 of participant 1: tracking error 0.2 rad."


def test_the_separation_monitoring_is_reported_per_condition_and_an_unmonitored_hand_is_said() -> None:
    tracked = [
        replace(
            PRESS, condition="reality", index=k, link=LINK, hand_monitored="tracked",
            least_separation_predicted=0.040 + 0.01 * k, least_separation=0.060 + 0.01 * k,
            move_least_separation=0.300 - 0.01 * k,
        )
        for k in (1, 2, 3)
    ]  # fmt: skip
    untracked = replace(tracked[0], index=4, hand_monitored="untracked", least_separation=0.2)
    lines = link_lines([PRESS, *tracked, untracked])
    (row,) = [line for line in lines if line.startswith("| reality | 3 |")]
    assert [cell.strip() for cell in row.strip("|").split("|")] == [
        "reality",
        "3",
        "1",
        "50.0 / 55.0",
        "70.0 / 85.0",
        "270.0 / 285.0",
    ]
    assert any(line.startswith("In reality, no tracker followed the hand in some trials") for line in lines)
    older = [replace(record, hand_monitored="") for record in tracked]  # written before the monitoring: nothing said
    assert not any("separation" in line for line in link_lines(older))
