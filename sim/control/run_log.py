"""A commander run's log: desired vs achieved per step as CSV, with the end-effector pose by FK for IK scenarios, and
the tracking metrics of the scenario rows (approach rows left out)."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.control.metrics import TrackingMetrics, per_joint_metrics, resample
from sim.control.scenarios import Motion, Schedule, fk_path, pose_errors
from sim.geometry.frames import matrix_to_quat
from sim.geometry.kinematics import chain_for
from sim.robots import RobotSpec

__all__ = ["RunReport", "RunResult", "write_log"]


@dataclass
class RunResult:
    times: np.ndarray  # (S,) step end times
    schedule_index: np.ndarray  # (S,) index into the schedule
    desired: np.ndarray  # (S, n)
    achieved: np.ndarray  # (S, n), NaN where no state was known yet (realtime)
    achieved_stamps: np.ndarray  # (S,)
    wall_seconds: float
    priming_steps: int
    complete: bool
    error: str | None = None  # why the run stopped early


@dataclass
class RunReport:
    joint_metrics: dict[str, TrackingMetrics]
    scenario_times: np.ndarray  # scenario time of each scenario row with a joint state
    ee_position_error: np.ndarray | None  # per scenario row: FK(achieved) vs the reference path
    ee_orientation_error: np.ndarray | None
    final_goal_error: tuple[float, float] | None  # FK(last achieved) vs the goal: m, rad
    rows: int  # scenario rows with a joint state
    approach_rows: int


def write_log(path: Path, robot: RobotSpec, motion: Motion, schedule: Schedule, result: RunResult) -> RunReport:
    """The per-step CSV log; returns the metrics of the scenario rows (approach rows left out)."""
    motion_index = schedule.motion_index[result.schedule_index]
    t_motion_start = (result.priming_steps + schedule.approach_steps) * motion.dt
    scenario = motion_index >= 0
    valid = scenario & np.isfinite(result.achieved_stamps)

    ee_columns: list[str] = []
    ee_data = np.empty((len(result.times), 0))
    pos_err = rot_err = None
    final_goal_error = None
    if motion.reference_path is not None and motion.ik is not None:
        chain = chain_for(robot)
        # The reference at each achieved state's stamp (lockstep: the step end; realtime: whatever the engine reached).
        at = np.where(np.isfinite(result.achieved_stamps), result.achieved_stamps, result.times)
        ref_index = np.clip(np.round(at / motion.dt).astype(int) - result.priming_steps, 0, len(schedule.positions) - 1)
        ref_motion = schedule.motion_index[ref_index]
        reference = np.where(
            (ref_motion >= 0)[:, None, None],
            motion.reference_path[np.maximum(ref_motion, 0)],
            fk_path(chain, schedule.positions[ref_index]),
        )
        achieved_fk = np.array(
            [chain.fk(q) if np.all(np.isfinite(q)) else np.full((4, 4), np.nan) for q in result.achieved]
        )
        pos_err, rot_err = pose_errors(achieved_fk, reference, motion.ik.weights)
        ref_q = np.array([matrix_to_quat(r[:3, :3]) for r in reference])
        ach_q = np.array(
            [matrix_to_quat(a[:3, :3]) if np.all(np.isfinite(a)) else np.full(4, np.nan) for a in achieved_fk]
        )
        axes = ("x", "y", "z", "qx", "qy", "qz", "qw")
        ee_columns = [f"ref_{a}" for a in axes] + [f"ee_{a}" for a in axes] + ["ee_pos_err", "ee_rot_err"]
        ee_data = np.column_stack([reference[:, :3, 3], ref_q, achieved_fk[:, :3, 3], ach_q, pos_err, rot_err])
        if np.any(valid) and motion.goal is not None:
            last = int(np.flatnonzero(valid)[-1])
            goal_p, goal_r = pose_errors(achieved_fk[last][None], motion.goal[None], motion.ik.weights)
            final_goal_error = (float(goal_p[0]), float(goal_r[0]))

    path.parent.mkdir(parents=True, exist_ok=True)
    names = robot.joint_names
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(
            [
                "time",
                "scenario_time",
                "phase",
                *(f"desired_{n}" for n in names),
                *(f"achieved_{n}" for n in names),
                "achieved_stamp",
                *ee_columns,
            ]
        )
        for k, t in enumerate(result.times):
            writer.writerow(
                [
                    f"{t:.6f}",
                    f"{t - t_motion_start:.6f}",
                    "scenario" if scenario[k] else "approach",
                    *(f"{v:.9f}" for v in result.desired[k]),
                    *(f"{v:.9f}" for v in result.achieved[k]),
                    f"{result.achieved_stamps[k]:.6f}",
                    *(f"{v:.9f}" for v in ee_data[k]),
                ]
            )

    metrics: dict[str, TrackingMetrics] = {}
    if np.count_nonzero(valid) >= 2:
        # Desired at the achieved states' stamps (equal to the step ends in lockstep), held at the schedule's ends.
        full_times = (np.arange(len(schedule.positions)) + result.priming_steps) * motion.dt
        at = np.clip(result.achieved_stamps[valid], full_times[0], full_times[-1])
        desired = resample(full_times, schedule.positions, at)
        metrics = per_joint_metrics(names, desired, result.achieved[valid], motion.dt)
    return RunReport(
        joint_metrics=metrics,
        scenario_times=result.times[valid] - t_motion_start,
        ee_position_error=None if pos_err is None else pos_err[valid],
        ee_orientation_error=None if rot_err is None else rot_err[valid],
        final_goal_error=final_goal_error,
        rows=int(np.count_nonzero(valid)),
        approach_rows=int(np.count_nonzero(~scenario)),
    )
