"""Trial analysis: read recorded bags (rosbags, no ROS needed) or CSV logs, align desired and achieved joint
positions by time, compute tracking metrics per joint, aggregate over trials, write a markdown report and plots.

Desired = the commands' first points (stamp = the time the target is for); achieved = joint_states (stamp = the
end of the physics step). Both are in the controller's time base, so achieved samples are compared with the
desired trajectory interpolated at their stamps. Lost messages are counted from gaps in header.seq, which rospy
numbers per publisher and the endpoint passes through unchanged.
"""

from __future__ import annotations

import csv
import logging
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from sim.control.metrics import TrackingMetrics, mean_and_std, per_joint_metrics, resample
from sim.errors import SimError
from sim.robots import RobotSpec
from sim.wire import rosmsgs
from sim.wire.joint_csv import read_joint_csv

__all__ = [
    "controller_time_start",
    "MOVING_JOINT_RANGE",
    "AnalysisError",
    "TrialSeries",
    "TrialResult",
    "read_bag",
    "read_csv_pair",
    "scenario_start",
    "without_approach",
    "align",
    "trial_metrics",
    "summary_rows",
    "worst_joint_rows",
    "markdown_table",
    "write_report",
    "write_plots",
    "plot_ee_paths",
]

log = logging.getLogger(__name__)

MOVING_JOINT_RANGE = 1e-3  # a joint whose desired range is below this (rad or m) does not move in the trial


class AnalysisError(SimError, ValueError):
    """A bag or log that cannot be analysed (missing topics, no overlap), named in the message."""


@dataclass
class TrialSeries:
    """Desired and achieved joint positions of one trial, in the robot's joint order."""

    robot: str
    joint_names: tuple[str, ...]
    desired_t: np.ndarray
    desired_q: np.ndarray  # (n, dof)
    achieved_t: np.ndarray
    achieved_q: np.ndarray  # (m, dof)
    commanded: int = 0  # messages the controller published (from seq numbers)
    recorded_commands: int = 0
    states_published: int = 0
    recorded_states: int = 0

    @property
    def lost_messages(self) -> int:
        return (self.commanded - self.recorded_commands) + (self.states_published - self.recorded_states)


@dataclass
class TrialResult:
    robot: str
    use_case: str
    trial: int
    metrics: dict[str, TrackingMetrics]  # by joint name, moving joints only
    lost_messages: int
    series: TrialSeries | None = field(default=None, repr=False)


# --- reading ---------------------------------------------------------------------------------------------------


def _seq_span(seqs: list[int]) -> int:
    """How many messages a publisher sent between the first and last recorded seq (inclusive)."""
    return 0 if not seqs else max(seqs) - min(seqs) + 1


def controller_time_start(stamps: Sequence[float]) -> int:
    """The index of the first joint state on the controller's time base, given the states' stamps in the order the
    engine published them. An auto-simulating engine stamps with its own clock until it hears /clock, and its stamps
    then jump back to the controller's: whatever comes before the last jump back is the engine's own time. Pure."""
    start = 0
    for index in range(1, len(stamps)):
        if stamps[index] < stamps[index - 1]:
            start = index
    return start


def read_bag(path: Path, robot: RobotSpec) -> TrialSeries:
    """The trial in a bag. Messages of the two topics reach rosbag record over separate connections, so one
    topic may be recorded well ahead of the other under load: each topic is read in its own publication order
    (header.seq), never against the other's record order. Only gaps in header.seq count as lost."""
    from rosbags.rosbag1 import Reader

    command_t, command_q, command_seq = [], [], []
    states: list[rosmsgs.JointStateSample] = []
    hold = robot.home.copy()
    with Reader(path) as reader:
        wanted = [c for c in reader.connections if c.topic in (robot.command_topic, robot.joint_states_topic)]
        if not any(c.topic == robot.joint_states_topic for c in wanted):
            raise AnalysisError(f"{path}: no {robot.joint_states_topic} messages recorded")
        for connection, _, raw in reader.messages(connections=wanted):
            if connection.topic == robot.command_topic:
                command = rosmsgs.decode_joint_trajectory(raw, robot.joint_names)
                named = np.isfinite(command.positions)
                hold = np.where(named, command.positions, hold)
                command_t.append(command.stamp_s)
                command_q.append(hold.copy())
                command_seq.append(_header_seq(raw))
            else:
                try:
                    states.append(rosmsgs.decode_joint_state(raw, robot.joint_names))
                except rosmsgs.MessageError as error:
                    raise AnalysisError(f"{path}: {robot.joint_states_topic}: {error}") from None
    if len(command_t) < 2:
        raise AnalysisError(f"{path}: fewer than 2 commands on {robot.command_topic}")
    states.sort(key=lambda state: state.seq)
    on_time = states[controller_time_start([state.stamp_s for state in states]) :]
    return TrialSeries(
        robot=robot.name,
        joint_names=robot.joint_names,
        desired_t=np.array(command_t),
        desired_q=np.array(command_q),
        achieved_t=np.array([state.stamp_s for state in on_time]),
        achieved_q=np.array([state.positions for state in on_time]).reshape(len(on_time), robot.dof),
        commanded=_seq_span(command_seq),
        recorded_commands=len(command_seq),
        states_published=_seq_span([state.seq for state in states]),
        recorded_states=len(states),
    )


def scenario_start(commander_log: Path) -> float:
    """The stamp of the scenario's first sample, from the commander's log: rows before it (phase "approach") only
    bring the robot from wherever it was to the scenario's start, and are no part of the scenario."""
    with commander_log.open(newline="") as handle:
        for row in csv.DictReader(handle):
            if row.get("phase") != "approach":
                return float(row["time"])
    raise AnalysisError(f"{commander_log}: no scenario row")


def without_approach(series: TrialSeries, start_s: float) -> TrialSeries:
    """`series` from the scenario's first sample on (see `scenario_start`); message counts are kept."""
    desired, achieved = series.desired_t >= start_s - 1e-9, series.achieved_t >= start_s - 1e-9
    return replace(
        series,
        desired_t=series.desired_t[desired],
        desired_q=series.desired_q[desired],
        achieved_t=series.achieved_t[achieved],
        achieved_q=series.achieved_q[achieved],
    )


def _header_seq(raw: bytes) -> int:
    # std_msgs/Header is the first field of JointTrajectory; its seq is the first uint32.
    return int.from_bytes(raw[:4], "little")


def read_csv_pair(desired_csv: Path, achieved_csv: Path, robot: RobotSpec) -> TrialSeries:
    """The no-ROS use cases: the engine's input CSV (desired) and its log (achieved)."""
    d_t, d_names, d_q = read_joint_csv(desired_csv, robot)
    a_t, a_names, a_q = read_joint_csv(achieved_csv, robot)
    desired = np.tile(robot.home, (d_t.size, 1))
    desired[:, [robot.joint_names.index(n) for n in d_names]] = d_q
    achieved = np.tile(robot.home, (a_t.size, 1))
    achieved[:, [robot.joint_names.index(n) for n in a_names]] = a_q
    return TrialSeries(
        robot.name,
        robot.joint_names,
        d_t,
        desired,
        a_t,
        achieved,
        commanded=d_t.size,
        recorded_commands=d_t.size,
        states_published=a_t.size,
        recorded_states=a_t.size,
    )


# --- metrics ---------------------------------------------------------------------------------------------------


def align(series: TrialSeries) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, desired, achieved) at the achieved stamps that lie within the desired trajectory's time span."""
    order = np.argsort(series.desired_t, kind="stable")
    d_t, d_q = series.desired_t[order], series.desired_q[order]
    keep_unique = np.concatenate(([True], np.diff(d_t) > 1e-9))
    d_t, d_q = d_t[keep_unique], d_q[keep_unique]
    inside = (series.achieved_t >= d_t[0] - 1e-9) & (series.achieved_t <= d_t[-1] + 1e-9)
    times = series.achieved_t[inside]
    if times.size < 2:
        raise AnalysisError(
            f"{series.robot}: joint states [{series.achieved_t.min(initial=np.nan):g} s…] do not overlap the "
            f"commands [{d_t[0]:g}, {d_t[-1]:g}] s"
        )
    return times, resample(d_t, d_q, times), series.achieved_q[inside]


def trial_metrics(series: TrialSeries, dt: float) -> dict[str, TrackingMetrics]:
    """Metrics per moving joint (desired range above MOVING_JOINT_RANGE)."""
    _, desired, achieved = align(series)
    return per_joint_metrics(series.joint_names, desired, achieved, dt, MOVING_JOINT_RANGE)


# --- report ----------------------------------------------------------------------------------------------------

_METRIC_COLUMNS = (
    ("MAPE %", "mape_percent", "{:.4f}"),
    ("WAPE %", "wape_percent", "{:.4f}"),
    ("NRMSE %", "nrmse_percent", "{:.4f}"),
    ("max abs err", "max_abs_error", "{:.2e}"),
    ("lag ms", "lag_s", "{:.2f}"),
)


def _fmt(mean: float, std: float, spec: str, scale: float = 1.0) -> str:
    if not np.isfinite(mean):
        return "n/a"
    return f"{spec.format(mean * scale)} ± {spec.format(std * scale)}"


def summary_rows(results: Sequence[TrialResult]) -> list[dict[str, str]]:
    """One row per (robot, use case, joint): mean ± std over trials of every metric, plus lost messages."""
    grouped: dict[tuple[str, str, str], list[TrackingMetrics]] = defaultdict(list)
    lost: dict[tuple[str, str], int] = defaultdict(int)
    trials: dict[tuple[str, str], int] = defaultdict(int)
    for result in results:
        lost[(result.robot, result.use_case)] += result.lost_messages
        trials[(result.robot, result.use_case)] += 1
        for joint, metrics in result.metrics.items():
            grouped[(result.robot, result.use_case, joint)].append(metrics)
    rows = []
    for (robot, use_case, joint), joint_trials in grouped.items():
        row = {"robot": robot, "use case": use_case, "joint": joint, "trials": str(trials[(robot, use_case)])}
        for title, attribute, spec in _METRIC_COLUMNS:
            mean, std = mean_and_std([getattr(m, attribute) for m in joint_trials])
            row[title] = _fmt(mean, std, spec, 1000.0 if attribute == "lag_s" else 1.0)
        row["lost msgs"] = str(lost[(robot, use_case)])
        rows.append(row)
    return rows


def worst_joint_rows(results: Sequence[TrialResult]) -> list[dict[str, str]]:
    """Per (robot, use case), its moving joint of the highest mean MAPE over trials, with that MAPE and the joint's
    mean lag: the campaign's figures in one line per robot and use case (README's table)."""
    grouped: dict[tuple[str, str], dict[str, list[TrackingMetrics]]] = defaultdict(lambda: defaultdict(list))
    for result in results:
        for joint, metrics in result.metrics.items():
            grouped[(result.robot, result.use_case)][joint].append(metrics)
    rows = []
    for (robot, use_case), joints in grouped.items():
        means = {
            joint: (mean_and_std([m.mape_percent for m in trials])[0], mean_and_std([m.lag_s for m in trials])[0])
            for joint, trials in joints.items()
        }
        finite = {joint: figures for joint, figures in means.items() if np.isfinite(figures[0])}
        if not finite:
            rows.append({"robot": robot, "use case": use_case, "joint": "", "MAPE %": "n/a", "lag ms": "n/a"})
            continue
        joint = max(finite, key=lambda name: finite[name][0])
        mape, lag = finite[joint]
        lag_cell = f"{round(lag * 1000, 1) + 0.0:.1f}" if np.isfinite(lag) else "n/a"  # + 0.0: no "-0.0"
        rows.append({"robot": robot, "use case": use_case, "joint": joint, "MAPE %": f"{mape:.3f}", "lag ms": lag_cell})
    return rows


def markdown_table(rows: Sequence[dict[str, str]]) -> str:
    if not rows:
        return "(no results)\n"
    headers = list(rows[0])
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(row[h] for h in headers) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def write_report(results: Sequence[TrialResult], out_dir: Path, title: str = "Tracking accuracy") -> Path:
    """report.md with the summary table and links to the plots (written beside it)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    plots = write_plots(results, out_dir)
    lines = [
        f"# {title}",
        "",
        "Mean ± std over trials, per moving joint. MAPE leaves out samples with "
        "|desired| ≤ 1e-3 (rad or m); lag is the cross-correlation delay of achieved behind desired.",
        "",
        markdown_table(summary_rows(results)),
        "",
    ]
    for plot in plots:
        lines.append(f"![{plot.stem}]({plot.name})")
    report = out_dir / "report.md"
    report.write_text("\n".join(lines) + "\n")
    return report


def write_plots(results: Sequence[TrialResult], out_dir: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    # Desired vs achieved per joint: the first trial of each (robot, use case).
    seen = set()
    for result in results:
        key = (result.robot, result.use_case)
        if key in seen or result.series is None:
            continue
        seen.add(key)
        times, desired, achieved = align(result.series)
        dof = desired.shape[1]
        figure, axes = plt.subplots(dof, 1, figsize=(8, 1.6 * dof + 1), sharex=True, squeeze=False)
        for j in range(dof):
            axis = axes[j, 0]
            axis.plot(times, desired[:, j], label="desired", linewidth=2.0)
            axis.plot(times, achieved[:, j], "--", label="achieved", linewidth=1.2)
            axis.set_ylabel(result.series.joint_names[j], fontsize=7)
        axes[0, 0].legend(loc="upper right", fontsize=7)
        axes[-1, 0].set_xlabel("time [s]")
        figure.suptitle(f"{result.robot} — {result.use_case}: desired vs achieved")
        figure.tight_layout()
        path = out_dir / f"joints_{result.robot}_{result.use_case}.png"
        figure.savefig(path, dpi=90)
        plt.close(figure)
        written.append(path)
    # Bar charts per use case with error bars per robot (mean over moving joints, mean ± std over trials).
    for title, attribute in (("MAPE %", "mape_percent"), ("WAPE %", "wape_percent")):
        chart = _bar_chart(results, attribute, title, out_dir, plt)
        if chart is not None:
            written.append(chart)
    return written


def _bar_chart(results: Sequence[TrialResult], attribute: str, title: str, out_dir: Path, plt: Any) -> Path | None:
    per_trial: dict[tuple[str, str], list[float]] = defaultdict(list)
    for result in results:
        values = [getattr(m, attribute) for m in result.metrics.values()]
        values = [v for v in values if np.isfinite(v)]
        if values:
            per_trial[(result.robot, result.use_case)].append(float(np.mean(values)))
    if not per_trial:
        return None
    robots = sorted({robot for robot, _ in per_trial})
    use_cases = list(dict.fromkeys(use_case for _, use_case in per_trial))
    width = 0.8 / len(robots)
    figure, axis = plt.subplots(figsize=(max(6, 1.3 * len(use_cases)), 4))
    for i, robot in enumerate(robots):
        stats = [mean_and_std(per_trial.get((robot, uc), [])) for uc in use_cases]
        positions = np.arange(len(use_cases)) + (i - (len(robots) - 1) / 2) * width
        axis.bar(positions, [m for m, _ in stats], width, yerr=[s for _, s in stats], capsize=3, label=robot)
    axis.set_xticks(np.arange(len(use_cases)), use_cases, rotation=25, ha="right", fontsize=8)
    axis.set_ylabel(f"{title} (mean over moving joints)")
    axis.set_yscale("symlog", linthresh=1e-3)
    axis.legend()
    axis.set_title(f"{title} per use case, mean ± std over trials")
    figure.tight_layout()
    path = out_dir / f"bars_{attribute.split('_')[0]}.png"
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return path


def plot_ee_paths(
    robot: RobotSpec, desired_q: np.ndarray, achieved_q: np.ndarray, goal: np.ndarray | None, path: Path
) -> Path:
    """The end-effector path (FK of desired and of achieved joint positions) and the goal, in 3-D."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sim.geometry.kinematics import chain_for

    chain = chain_for(robot)
    desired_xyz = np.array([chain.fk(q)[:3, 3] for q in desired_q])
    achieved_xyz = np.array([chain.fk(q)[:3, 3] for q in achieved_q])
    figure = plt.figure(figsize=(6, 5))
    axis = figure.add_subplot(projection="3d")
    axis.plot(*desired_xyz.T, label="desired (FK of commands)", linewidth=2.0)
    axis.plot(*achieved_xyz.T, "--", label="achieved (FK of joint states)")
    if goal is not None:
        axis.scatter(*np.asarray(goal)[:3], color="red", s=40, label="goal")
    axis.set_xlabel("x [m]")
    axis.set_ylabel("y [m]")
    axis.set_zlabel("z [m]")
    axis.legend(fontsize=7)
    axis.set_title(f"{robot.name}: end-effector path")
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return path
