"""sim.engine offline CSV mode (`--csv in.csv --log out.csv`, no ROS, no TCP) and the pose -> marker conversion."""

from __future__ import annotations

import csv
import subprocess
from pathlib import Path

import numpy as np
import pytest

from sim.engine import stand_in as engine
from sim.engine.physics import Mode
from sim.geometry import frames
from sim.robots import load_robot
from sim.wire.contract import PoseConvention
from tests.rosenv import PYTHON, REPO

PANDA = load_robot("panda")
IGT = load_robot("igt")
DT = 0.02


def write_csv(path: Path, header: list[str], rows: list[list[str]]) -> Path:
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(rows)
    return path


def read_log(path: Path) -> tuple[list[str], np.ndarray]:
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return rows[0], np.array([[float(cell) for cell in row] for row in rows[1:]])


def replay(tmp_path: Path, csv_in: Path, *extra: str) -> tuple[list[str], np.ndarray]:
    log = tmp_path / "achieved.csv"
    assert engine.main(["--csv", str(csv_in), "--log", str(log), *extra]) == 0
    return read_log(log)


def sine_rows(
    robot, names, duration_s: float, sample_dt: float, amplitude: float = 0.3
) -> tuple[np.ndarray, np.ndarray]:
    """Desired positions sampled at sample_dt, rounded to the 9 decimals the CSV carries."""
    times = np.round(np.arange(0.0, duration_s + 1e-9, sample_dt), 6)
    columns = [robot.joint_names.index(name) for name in names]
    positions = robot.home[columns] + amplitude * np.sin(2 * np.pi * times[:, None] / 2.0 + np.arange(len(names)))
    return times, np.round(positions, 9)


def as_rows(times: np.ndarray, positions: np.ndarray) -> list[list[str]]:
    return [[f"{t:.6f}", *(f"{x:.9f}" for x in row)] for t, row in zip(times, positions)]


# --- round trip and tracking ----------------------------------------------------------------------------------


@pytest.mark.parametrize("mode", ["no_physics", "infinite_stiffness"])
def test_kinematic_modes_reproduce_the_input_positions_at_the_step_times_exactly(tmp_path, mode):
    names = list(PANDA.joint_names)
    times, desired = sine_rows(PANDA, names, 1.0, DT)
    source = write_csv(tmp_path / "in.csv", ["time", *names], as_rows(times, desired))
    header, log = replay(tmp_path, source, "--mode", mode)
    assert header == ["time", *PANDA.joint_names]
    # one row per step end dt, 2·dt, ..., 1.0 s; the input's t = 0 row is the start pose, not a step
    np.testing.assert_allclose(log[:, 0], times[1:], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(log[:, 1:], desired[1:])


def test_no_physics_interpolates_between_samples_and_holds_joints_the_csv_does_not_name(tmp_path):
    names = ["panda_joint4", "panda_joint2"]  # a subset, out of order
    source = write_csv(
        tmp_path / "in.csv", ["time", *names], [["0", "-2.0", "-0.5"], ["0.1", "-1.0", "0.5"], ["0.2", "-1.0", "0.5"]]
    )
    _, log = replay(tmp_path, source, "--mode", "no_physics")
    assert log.shape == (10, 1 + PANDA.dof)
    t = log[:, 0]
    ramp = np.clip(t / 0.1, 0, 1)
    np.testing.assert_allclose(log[:, 1 + 3], -2.0 + ramp, rtol=0, atol=1e-9)  # panda_joint4
    np.testing.assert_allclose(log[:, 1 + 1], -0.5 + ramp, rtol=0, atol=1e-9)  # panda_joint2
    for j in (0, 2, 4, 5, 6):
        np.testing.assert_allclose(log[:, 1 + j], PANDA.home[j], rtol=0, atol=1e-9)


@pytest.mark.parametrize("robot", [PANDA, IGT], ids=lambda r: r.name)
def test_physics_tracks_a_smooth_csv_trajectory_closely(tmp_path, robot):
    names = list(robot.joint_names)
    times, desired = sine_rows(robot, names, 2.0, DT, amplitude=0.1)
    source = write_csv(tmp_path / "in.csv", ["time", *names], as_rows(times, desired))
    _, log = replay(tmp_path, source, "--robot", robot.name, "--mode", "physics")
    error = np.abs(log[:, 1:] - desired[1:])
    assert error.max() < 2e-3, f"max tracking error {error.max():.2e} (per joint {error.max(axis=0)})"
    # and it is the physics, not a copy of the input: a kinematic replay would be exact
    assert error.max() > 1e-9


def test_a_far_step_in_physics_mode_lags_behind_and_then_settles(tmp_path):
    source = write_csv(tmp_path / "in.csv", ["time", "panda_joint1"], [["0", "0"], ["0.02", "1.0"], ["3.0", "1.0"]])
    _, log = replay(tmp_path, source, "--mode", "physics")
    joint1 = log[:, 1]
    assert joint1[0] < 0.5  # force-limited drive: cannot jump 1 rad in one step
    assert abs(joint1[-1] - 1.0) < 1e-3
    np.testing.assert_allclose(log[-1, 2:], PANDA.home[1:], atol=5e-3)  # the others held near home


def test_csv_mode_as_a_process_needs_no_ros(tmp_path):
    source = write_csv(tmp_path / "in.csv", ["time", "igt_rail"], [["0", "0.0"], ["0.1", "0.05"]])
    log = tmp_path / "out" / "achieved.csv"
    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(REPO)}  # no ROS_MASTER_URI, no ROS setup at all
    result = subprocess.run(
        [PYTHON, "-m", "sim.engine", "--robot", "igt", "--mode", "no_physics", "--csv", str(source), "--log", str(log)],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    assert "replayed" in result.stdout and "5 steps" in result.stdout
    header, data = read_log(log)
    assert header == ["time", *IGT.joint_names]
    np.testing.assert_allclose(data[:, 1], [0.01, 0.02, 0.03, 0.04, 0.05], atol=1e-9)


# --- bad input ------------------------------------------------------------------------------------------------


BAD_CSVS = {
    "missing time column": (["t", "panda_joint1"], [["0", "0.1"]], ["first column must be 'time'", "'t'"]),
    "unknown joint": (["time", "panda_joint9"], [["0", "0.1"]], ["unknown joint", "panda_joint9"]),
    "no joint columns": (["time"], [["0"], ["1"]], ["unknown joint column"]),
    "joint twice": (["time", "panda_joint1", "panda_joint1"], [["0", "0", "0"]], ["twice", "panda_joint1"]),
    "equal times": (["time", "panda_joint1"], [["0", "0"], ["0.1", "0"], ["0.1", "0"]], ["strictly increasing", "0.1"]),
    "decreasing times": (
        ["time", "panda_joint1"],
        [["0", "0"], ["0.2", "0"], ["0.1", "0"]],
        ["strictly increasing", "0.1", "0.2"],
    ),
    "non-numeric cell": (
        ["time", "panda_joint1"],
        [["0", "0"], ["0.1", "abc"]],
        ["'abc'", "not a number", "line 3", "panda_joint1"],
    ),
    "empty cell": (["time", "panda_joint1"], [["0", "0"], ["0.1", ""]], ["not a number", "line 3"]),
    "short row": (
        ["time", "panda_joint1", "panda_joint2"],
        [["0", "0", "0"], ["0.1", "0"]],
        ["line 3", "2 cells", "header has 3"],
    ),
    "NaN position": (["time", "panda_joint1"], [["0", "0"], ["0.1", "nan"]], ["finite"]),
    "header only": (["time", "panda_joint1"], [], ["at least one data row"]),
}


@pytest.mark.parametrize("case", list(BAD_CSVS))
def test_a_bad_csv_exits_2_with_a_message_naming_the_problem(tmp_path, capsys, case):
    header, rows, fragments = BAD_CSVS[case]
    source = write_csv(tmp_path / "bad.csv", header, rows)
    log = tmp_path / "achieved.csv"
    assert engine.main(["--csv", str(source), "--log", str(log)]) == 2
    message = capsys.readouterr().err
    assert message.startswith("sim.engine: error:") and "bad.csv" in message
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    assert not log.exists()


def test_a_missing_csv_exits_2_naming_the_file(tmp_path, capsys):
    missing = tmp_path / "nowhere" / "in.csv"
    assert engine.main(["--csv", str(missing), "--log", str(tmp_path / "out.csv")]) == 2
    message = capsys.readouterr().err
    assert "cannot read" in message and str(missing) in message and "No such file" in message


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--robot", "ur5"], "unknown robot 'ur5'"),
        (["--dt", "0"], "--dt"),
        (["--time-scale", "-1"], "--time-scale"),
    ],
)
def test_bad_options_exit_2_naming_them(tmp_path, capsys, args, fragment):
    source = write_csv(tmp_path / "in.csv", ["time", "panda_joint1"], [["0", "0"], ["0.1", "0"]])
    assert engine.main(["--csv", str(source), "--log", str(tmp_path / "out.csv"), *args]) == 2
    assert fragment in capsys.readouterr().err


def test_a_bad_csv_exits_2_as_a_process_too(tmp_path):
    source = write_csv(tmp_path / "bad.csv", ["time", "elbow"], [["0", "0"]])
    result = subprocess.run(
        [PYTHON, "-m", "sim.engine", "--csv", str(source), "--log", str(tmp_path / "o.csv")],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert "unknown joint column(s) ['elbow']" in result.stderr


def test_replay_csv_direct_call_steps_at_the_option_dt_up_to_the_last_sample(tmp_path):
    source = write_csv(tmp_path / "in.csv", ["time", "igt_wrist"], [["0", "-1.0"], ["0.105", "-0.9"]])
    options = engine.EngineOptions(mode=Mode.NO_PHYSICS, dt=0.01)
    steps = engine.replay_csv(IGT, source, tmp_path / "out.csv", options)
    assert steps == 10  # 0.01 ... 0.10; 0.11 would be past the last sample
    _, log = read_log(tmp_path / "out.csv")
    np.testing.assert_allclose(log[:, 0], 0.01 * np.arange(1, 11), atol=1e-9)
    np.testing.assert_allclose(log[:, 3], -1.0 + 0.1 * log[:, 0] / 0.105, atol=1e-9)


# --- the pose topic's target marker -----------------------------------------------------------------------------


def test_pose_to_marker_quaternion_convention_converts_to_unity_frames():
    position = np.array([0.4, -0.2, 0.6])
    quaternion = frames.euler_xyz_to_quat(0.1, -0.3, 0.7)
    marker = engine.pose_to_marker(position, 3.0 * quaternion, PoseConvention.QUATERNION)  # normalised on the way
    np.testing.assert_allclose(marker.position_unity, frames.ros_to_unity_point(position), atol=1e-12)
    np.testing.assert_allclose(marker.orientation_unity, frames.ros_to_unity_quat(quaternion), atol=1e-12)
    # ROS FLU (x forward, y left, z up) -> Unity RUF (x right, y up, z forward)
    np.testing.assert_allclose(marker.position_unity, [0.2, 0.6, 0.4], atol=1e-12)


def test_pose_to_marker_euler_convention_reads_xyz_angles_from_the_quaternion_fields():
    position = np.array([0.3, 0.1, 0.5])
    angles = np.array([0.2, -0.1, 1.2])
    fields = np.array([*angles, 0.0])  # the thesis's convention: w unused (0 here, which is no quaternion at all)
    marker = engine.pose_to_marker(position, fields, PoseConvention.EULER)
    expected = frames.ros_to_unity_quat(frames.euler_xyz_to_quat(*angles))
    np.testing.assert_allclose(marker.orientation_unity, expected, atol=1e-12)
    np.testing.assert_allclose(marker.position_unity, [-0.1, 0.5, 0.3], atol=1e-12)
    # the same numbers read as a quaternion mean something else
    other = engine.pose_to_marker(position, np.array([*angles, 1.0]), PoseConvention.QUATERNION)
    assert not np.allclose(np.abs(other.orientation_unity), np.abs(expected), atol=1e-3)


def test_identity_orientation_stays_identity_in_unity():
    marker = engine.pose_to_marker(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), PoseConvention.QUATERNION)
    np.testing.assert_allclose(np.abs(marker.orientation_unity), [0.0, 0.0, 0.0, 1.0], atol=1e-12)


def test_path_velocity_is_the_slope_inside_segments_and_the_mean_at_samples():
    from sim.engine.stand_in import path_velocity

    times = np.array([0.0, 1.0, 2.0, 4.0])
    positions = np.array([[0.0, 5.0], [1.0, 5.0], [1.0, 3.0], [3.0, 3.0]])
    np.testing.assert_allclose(path_velocity(times, positions, 0.5), [1.0, 0.0])
    np.testing.assert_allclose(path_velocity(times, positions, 1.0), [0.5, -1.0])  # mean of both sides
    np.testing.assert_allclose(path_velocity(times, positions, 3.0), [1.0, 0.0])
    np.testing.assert_allclose(path_velocity(times, positions, 4.0), [0.5, 0.0])  # the path holds after the end
    np.testing.assert_allclose(path_velocity(times, positions, 9.0), [0.0, 0.0])


def test_render_writes_an_animation_of_the_replay_or_names_a_bad_file_name(tmp_path, capsys):
    from PIL import Image

    times, positions = sine_rows(IGT, IGT.joint_names, 2.0, 0.02)
    source = write_csv(
        tmp_path / "in.csv",
        ["time", *IGT.joint_names],
        [[f"{t:.6f}", *map(str, row)] for t, row in zip(times, positions)],
    )
    animation = tmp_path / "motion.gif"
    replay(tmp_path, source, "--robot", "igt", "--render", str(animation))
    with Image.open(animation) as gif:
        assert gif.n_frames > 5 and gif.size == (320, 240)
        first = np.asarray(gif.convert("RGB"))
        gif.seek(gif.n_frames // 2)
        assert not np.array_equal(first, np.asarray(gif.convert("RGB"))), "the robot moves between frames"
    assert engine.main(["--csv", str(source), "--log", str(tmp_path / "o.csv"), "--render", "x.bmp"]) == 2
    assert "must end in .png" in capsys.readouterr().err
