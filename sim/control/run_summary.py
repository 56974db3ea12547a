"""What the commander prints after a run: the metrics table, the IK goal errors, fk_confirm's error over time."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.control.run_log import RunReport, RunResult
from sim.control.scenarios import Motion
from sim.robots import RobotSpec

__all__ = ["format_fk_confirm", "format_summary"]


def format_summary(
    robot: RobotSpec, motion: Motion, result: RunResult, report: RunReport, log_path: Path, realtime: bool
) -> str:
    lines = [
        f"commander: {robot.name} {motion.scenario} ({motion.description})",
        f"  {'realtime' if realtime else 'lockstep'}, dt {motion.dt:g} s: {len(result.times)} steps "
        f"({report.rows} scenario, {report.approach_rows} approach, {result.priming_steps} priming) "
        f"in {result.wall_seconds:.2f} s wall" + ("" if result.complete else " -- INCOMPLETE"),
        f"  log: {log_path}",
    ]
    if report.joint_metrics:
        lines.append(f"  {'joint':<14} {'MAPE %':>9} {'WAPE %':>9} {'NRMSE %':>9} {'max|e|':>10} {'lag s':>7}")
        for name, m in report.joint_metrics.items():
            lines.append(
                f"  {name:<14} {m.mape_percent:9.4f} {m.wape_percent:9.4f} {m.nrmse_percent:9.4f} "
                f"{m.max_abs_error:10.3e} {m.lag_s:7.3f}"
            )
    if (
        motion.ik is not None
        and report.ee_position_error is not None
        and report.ee_orientation_error is not None
        and report.ee_position_error.size
    ):
        ik = motion.ik
        lines.append(
            f"  IK ({ik.space} space, weights {ik.weights}): commanded goal error {ik.goal_position_error:.3e} m, "
            f"{ik.goal_orientation_error:.3e} rad"
            + (f"; max joint jump {ik.max_joint_jump:.4f}" if ik.space == "cartesian" else "")
        )
        lines.append(
            f"  FK(achieved) vs reference path: max {report.ee_position_error.max():.3e} m, "
            f"{report.ee_orientation_error.max():.3e} rad"
        )
    if report.final_goal_error is not None:
        lines.append(
            f"  FK(achieved) at the end vs goal: {report.final_goal_error[0]:.3e} m, "
            f"{report.final_goal_error[1]:.3e} rad"
        )
    for note in motion.warnings:
        lines.append(f"  warning: {note}")
    return "\n".join(lines)


def format_fk_confirm(report: RunReport, samples: int = 11) -> str:
    """The end-effector error over time (FK of the achieved joints vs the reference path), at a few instants."""
    errors_p, errors_r = report.ee_position_error, report.ee_orientation_error
    if errors_p is None or errors_r is None or errors_p.size == 0:
        return ""
    rows = np.unique(np.linspace(0, len(errors_p) - 1, samples).round().astype(int))
    lines = ["  fk_confirm: FK(achieved) vs reference path", f"  {'t s':>7} {'pos err m':>11} {'rot err rad':>12}"]
    for k in rows:
        lines.append(f"  {report.scenario_times[k]:7.2f} {errors_p[k]:11.3e} {errors_r[k]:12.3e}")
    return "\n".join(lines)
