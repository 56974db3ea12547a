"""sim.campaign.analysis reads a trial's bag as rosbag record writes it: each topic in its own publication order,
whatever the interleaving of the two under load, with only real gaps in header.seq counted as lost."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer

from sim.campaign.analysis import TrialResult, controller_time_start, read_bag, worst_joint_rows
from sim.control.metrics import TrackingMetrics
from sim.robots import load_robot
from sim.wire import rosmsgs

IGT = load_robot("igt")
DT = 0.02
_T = rosmsgs.TYPESTORE.types


def command(seq: int, stamp_s: float, q: np.ndarray) -> bytes:
    point = _T["trajectory_msgs/msg/JointTrajectoryPoint"](
        positions=np.asarray(q, dtype=np.float64),
        velocities=np.zeros(len(q)),
        accelerations=np.zeros(0),
        effort=np.zeros(0),
        time_from_start=_T["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
    )
    header = _T["std_msgs/msg/Header"](seq=seq, stamp=rosmsgs.time_msg(stamp_s), frame_id="")
    message = _T["trajectory_msgs/msg/JointTrajectory"](
        header=header, joint_names=list(IGT.joint_names), points=[point]
    )
    return rosmsgs.serialize(message, rosmsgs.JOINT_TRAJECTORY)


def state(seq: int, stamp_s: float, q: np.ndarray) -> bytes:
    zeros = np.zeros(len(q))
    return rosmsgs.encode_joint_state(seq, stamp_s, IGT.joint_names, q, zeros, zeros)


def write_bag(path: Path, records: list[tuple[str, bytes]]) -> Path:
    """`records` in record order: ("command" | "state", raw bytes)."""
    with Writer(path) as writer:
        connections = {
            "command": writer.add_connection(
                IGT.command_topic, "trajectory_msgs/msg/JointTrajectory", typestore=rosmsgs.TYPESTORE
            ),
            "state": writer.add_connection(
                IGT.joint_states_topic, "sensor_msgs/msg/JointState", typestore=rosmsgs.TYPESTORE
            ),
        }
        for index, (kind, raw) in enumerate(records):
            writer.write(connections[kind], 1_000_000 * (index + 1), raw)
    return path


def trajectory(steps: int) -> list[np.ndarray]:
    return [IGT.home + 0.01 * k for k in range(steps)]


def test_the_controllers_time_starts_after_the_engines_last_jump_back():
    assert controller_time_start([]) == 0
    assert controller_time_start([0.0, 0.02, 0.04]) == 0
    assert controller_time_start([3.0, 3.02, 3.04, 0.0, 0.02]) == 3  # /clock 0 heard after 3 s of its own
    assert controller_time_start([0.5, 0.52, 0.02, 0.04, 0.06]) == 2


def test_states_recorded_far_ahead_of_their_commands_are_all_kept_and_none_is_lost(tmp_path):
    # Lockstep: state k answers command k. Under load rosbag record wrote the states 40 steps ahead.
    q = trajectory(100)
    commands = [("command", command(k, (k + 1) * DT, q[k])) for k in range(100)]
    states = [("state", state(k, (k + 1) * DT, q[k])) for k in range(100)]
    records = states[:40] + [item for pair in zip(commands, states[40:] + [None] * 40) for item in pair if item]
    series = read_bag(write_bag(tmp_path / "ahead.bag", records), IGT)
    assert series.lost_messages == 0 and len(series.achieved_t) == 100
    assert np.allclose(series.achieved_q, series.desired_q)


def test_the_engines_own_time_before_it_hears_the_clock_is_left_out_and_not_counted_lost(tmp_path):
    q = trajectory(50)
    own = [("state", state(k, 2.0 + k * DT, IGT.home)) for k in range(10)]  # auto-simulating, its own clock
    after = [("state", state(10 + k, (k + 1) * DT, q[k])) for k in range(50)]
    commands = [("command", command(k, (k + 1) * DT, q[k])) for k in range(50)]
    records = own + [item for pair in zip(commands, after) for item in pair]
    series = read_bag(write_bag(tmp_path / "own.bag", records), IGT)
    assert series.lost_messages == 0 and series.recorded_states == 60
    assert len(series.achieved_t) == 50 and series.achieved_t[0] == pytest.approx(DT)


def test_a_gap_in_the_publishers_seq_is_lost(tmp_path):
    q = trajectory(20)
    records = []
    for k in range(20):
        records.append(("command", command(k, (k + 1) * DT, q[k])))
        if k not in (7, 8):
            records.append(("state", state(k, (k + 1) * DT, q[k])))
    series = read_bag(write_bag(tmp_path / "gap.bag", records), IGT)
    assert (series.states_published, series.recorded_states, series.lost_messages) == (20, 18, 2)


def metrics(mape: float, lag_s: float) -> TrackingMetrics:
    return TrackingMetrics(mape, 0.0, 0.0, 0.0, lag_s, 100, 100)


def test_the_worst_joint_per_robot_and_use_case_is_the_one_of_the_highest_mean_mape() -> None:
    results = [
        TrialResult("panda", "base", 1, {"j1": metrics(0.010, 0.001), "j2": metrics(0.030, 0.004)}, 0),
        TrialResult("panda", "base", 2, {"j1": metrics(0.050, 0.003), "j2": metrics(0.010, 0.002)}, 0),
        TrialResult("igt", "no_ros", 1, {"x": metrics(float("nan"), float("nan"))}, 0),
        TrialResult("igt", "auto_simulate_off", 1, {"x": metrics(0.002, -0.00004)}, 0),
    ]
    assert worst_joint_rows(results) == [
        # j1's mean 0.030 over j2's 0.020, whichever trial had the highest single figure
        {"robot": "panda", "use case": "base", "joint": "j1", "MAPE %": "0.030", "lag ms": "2.0"},
        {"robot": "igt", "use case": "no_ros", "joint": "", "MAPE %": "n/a", "lag ms": "n/a"},
        {"robot": "igt", "use case": "auto_simulate_off", "joint": "x", "MAPE %": "0.002", "lag ms": "0.0"},
    ]
