"""End to end: a short campaign through `python -m sim.trials` (real roscore, endpoint, engine, commander,
rosbag record), its report checked against the bags.

The check is independent of sim.campaign.analysis: the bags are read with ROS's own `rosbag` module (not rosbags), and
the metrics are recomputed here with plain numpy.
"""

from __future__ import annotations

import os
import re
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

import numpy as np
import pytest
import rosbag

from measuring.errors import MeasuringError
from measuring.procfs import bytes_read, command_lines
from sim.campaign.analysis import scenario_start
from sim.robots import load_robot
from tests.doc_figures import figures_of, markdown_tables, shape_mismatch
from tests.integration.sim_helpers import mean_of, report_rows, run_campaign

# The alone lane, with the realtime lane beside it: a campaign's lockstep goes at 250 steps a second, so that rosbag
# record may fall 0.4 s behind (its queue: 100 messages per topic). Unpaced, it lost 52 beside the realtime lane.
pytestmark = pytest.mark.lane("alone", on=("project",))

ROBOTS = ("panda", "igt")
USE_CASES = ("auto_simulate_off", "no_ros")
TRIALS = 2


# The recorder of the first trial is held (SIGSTOP) for STALL_S once it has read STALL_AFTER bytes since it opened
# its bag, as a loaded machine held one for 0.12 s: unpaced, that trial lost 19 commands and clocks to rosbag
# record's queue of 100 per topic (and held 0.3 s here, 102 joint states and clocks). The campaign paces lockstep at
# 250 steps a second: the recorder may fall 0.4 s behind, and loses none.
STALL_AFTER = 400_000
STALL_S = 0.25


@pytest.fixture(scope="module")
def campaign(tmp_path_factory, roscore) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("campaign")
    with recorder_stalled_once(out, STALL_AFTER, STALL_S) as held:
        result = run_campaign(ROBOTS, USE_CASES, out, TRIALS, roscore.env, timeout=400)
    assert held, "the recorder was never held up: the fault was not injected"
    return out, result.stdout


@contextmanager
def recorder_stalled_once(out: Path, after_bytes: int, stall_s: float) -> Iterator[list[int]]:
    """Once the first `rosbag record` into `out` has read `after_bytes` since its bag appeared, stop its processes
    for `stall_s` s (SIGSTOP, then SIGCONT); yields the PIDs it held, once it has."""
    held: list[int] = []
    over = threading.Event()

    def stall() -> None:
        baseline: int | None = None
        while not over.wait(0.01):
            pids = recorder_pids(out)
            recorder = next((pid for pid, argv in pids.items() if argv[0].endswith(b"/record")), None)
            if recorder is None:
                continue
            try:
                read = bytes_read(recorder)
            except MeasuringError:  # it has just ended
                continue
            if baseline is None and any((out / "bags").glob("*.bag.active")):  # it has started: counted from here
                baseline = read
            if baseline is not None and read - baseline >= after_bytes:
                held.extend(pids)
                signal_each(held, signal.SIGSTOP)
                time.sleep(stall_s)
                signal_each(held, signal.SIGCONT)
                return

    staller = threading.Thread(target=stall, daemon=True)
    staller.start()
    try:
        yield held
    finally:
        over.set()
        staller.join(10)


def recorder_pids(out: Path) -> dict[int, list[bytes]]:
    """The processes of a `rosbag record` into `out` (rosbag's script and the recorder it runs), their argv by PID."""
    return {
        pid: argv
        for pid, argv in command_lines().items()
        if argv and (b"record" in argv or argv[0].endswith(b"/record")) and any(bytes(out) in arg for arg in argv)
    }


def signal_each(pids: list[int], signum: signal.Signals) -> None:
    """`signum` to each of `pids`, those that have gone left out (SIGCONT must reach every one that was stopped)."""
    for pid in pids:
        with suppress(ProcessLookupError):
            os.kill(pid, signum)


def bag_series(path: Path, robot_name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[int]]:
    """(command stamps, commanded positions, state stamps, state positions, command seqs) via ROS's rosbag."""
    robot = load_robot(robot_name)
    command_t, command_q, seqs, state_t, state_q = [], [], [], [], []
    newest_command = None
    with rosbag.Bag(str(path)) as bag:
        for topic, message, _ in bag.read_messages(topics=[robot.command_topic, robot.joint_states_topic]):
            if topic == robot.command_topic:
                assert list(message.joint_names) == list(robot.joint_names)
                newest_command = message.header.stamp.to_sec()
                command_t.append(newest_command)
                command_q.append(message.points[0].positions)
                seqs.append(message.header.seq)
            elif newest_command is not None and message.header.stamp.to_sec() <= newest_command + 0.5:
                order = [list(message.name).index(name) for name in robot.joint_names]
                state_t.append(message.header.stamp.to_sec())
                state_q.append(np.asarray(message.position)[order])
    return np.array(command_t), np.array(command_q), np.array(state_t), np.array(state_q), seqs


def test_campaign_writes_a_report_with_every_robot_and_use_case(campaign) -> None:
    out, stdout = campaign
    rows = report_rows(out / "report.md")
    for robot in ROBOTS:
        moving = load_robot(robot).joint_names
        for use_case in USE_CASES:
            for joint in moving:
                row = rows[(robot, use_case, joint)]
                assert row["trials"] == str(TRIALS)
                assert row["lost msgs"] == "0"
    assert "messages lost: 0" in stdout
    # README's campaign table has the columns sim.trials prints today (its rows are the robots the command names)
    for figures in figures_of("python -m sim.trials"):
        mismatch = shape_mismatch(figures, markdown_tables(stdout), same_rows=False)
        assert mismatch is None, mismatch
    for plot in ("bars_mape.png", "bars_wape.png", "joints_panda_no_ros.png", "joints_igt_auto_simulate_off.png"):
        assert (out / plot).stat().st_size > 10_000


def test_report_numbers_match_the_bags(campaign) -> None:
    out, _ = campaign
    rows = report_rows(out / "report.md")
    for robot in ROBOTS:
        spec = load_robot(robot)
        mape = {joint: [] for joint in spec.joint_names}
        max_error = {joint: [] for joint in spec.joint_names}
        for trial in range(1, TRIALS + 1):
            bag = out / "bags" / f"{robot}_auto_simulate_off_{trial}.bag"
            command_t, command_q, state_t, state_q, seqs = bag_series(bag, robot)
            assert seqs == list(range(seqs[0], seqs[0] + len(seqs))), "commands lost or reordered"
            assert len(command_t) >= 40 / 0.02, "the 40 s trial path at 50 Hz"
            # The scenario from its first sample (the commander's log says when): the approach to it is no part of it.
            start = scenario_start(out / "commander" / f"{robot}_auto_simulate_off_{trial}.csv")
            assert start > command_t[0]  # neither robot starts at home: the commander approaches the start first
            inside = (state_t >= start - 1e-9) & (state_t <= command_t[-1])
            for j, joint in enumerate(spec.joint_names):
                desired = np.interp(state_t[inside], command_t, command_q[:, j])
                achieved = state_q[inside, j]
                used = np.abs(desired) > 1e-3
                mape[joint].append(100 * np.mean(np.abs(achieved[used] - desired[used]) / np.abs(desired[used])))
                max_error[joint].append(np.max(np.abs(achieved - desired)))
        for joint in spec.joint_names:
            row = rows[(robot, "auto_simulate_off", joint)]
            assert mean_of(row["MAPE %"]) == pytest.approx(np.mean(mape[joint]), abs=6e-5)  # 4 decimals printed
            assert mean_of(row["max abs err"]) == pytest.approx(np.mean(max_error[joint]), rel=6e-3)
            # The lockstep use case tracks the trial path tightly (the target is 0.05 % MAPE).
            assert np.mean(mape[joint]) < 0.05


def test_no_ros_use_case_compares_the_engines_csv_log_with_its_input(campaign) -> None:
    out, _ = campaign
    desired = np.loadtxt(out / "csv" / "igt_no_ros_1_desired.csv", delimiter=",", skiprows=1)
    achieved = np.loadtxt(out / "csv" / "igt_no_ros_1_achieved.csv", delimiter=",", skiprows=1)
    assert desired.shape[1] == achieved.shape[1] == 1 + load_robot("igt").dof
    rows = report_rows(out / "report.md")
    for j, joint in enumerate(load_robot("igt").joint_names, start=1):
        reference = np.interp(achieved[:, 0], desired[:, 0], desired[:, j])
        max_error = np.max(np.abs(achieved[:, j] - reference))
        reported = re.split(r"\s*±\s*", rows[("igt", "no_ros", joint)]["max abs err"])[0]
        assert max_error <= 2 * float(reported)  # trial 1 vs the mean of two near-identical trials
        assert max_error < 1e-3


# On Noetic's Python: the campaign's nodes as a ROS Noetic user runs them (the other campaigns run on the project's)
@pytest.mark.lane("quiet", on=("noetic",))
def test_the_base_case_tracks_the_sweep_and_loses_nothing(tmp_path: Path, roscore) -> None:
    """The thesis's base case (endpoint + TCP engine, physics, auto-simulate at the default time scale), one trial
    of the Panda: every moving joint within the issue's 0.05 % MAPE, no message lost. launch_scripts/test.sh also runs
    it on ROS Noetic's Python 3.8: there every process of it runs on that Python but roscore and rosbag."""
    done = run_campaign(["panda"], ["base"], tmp_path, env=roscore.env, timeout=300)
    assert "messages lost: 0" in done.stdout
    rows = report_rows(tmp_path / "report.md")
    for joint in load_robot("panda").joint_names:
        row = rows[("panda", "base", joint)]
        assert row["lost msgs"] == "0" and mean_of(row["MAPE %"]) <= 0.05, (joint, row)
    assert (tmp_path / "bags" / "panda_base_1.bag").is_file()
