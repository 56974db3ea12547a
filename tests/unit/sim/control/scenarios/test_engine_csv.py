"""sim.control.scenarios.engine_csv: a motion as the engine's CSV, exactly."""

from __future__ import annotations

import csv

import numpy as np

from sim.control.scenarios import (
    ScenarioConfig,
    build_motion,
    write_engine_csv,
)


def test_engine_csv_export_round_trips_exactly(robot, tmp_path):
    motion = build_motion(robot, "sweep", ScenarioConfig(duration=1.0))
    path = tmp_path / "desired.csv"
    write_engine_csv(path, motion)
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["time", *robot.joint_names]
    data = np.array(rows[1:], dtype=float)
    np.testing.assert_array_equal(data[:, 0], motion.times)
    np.testing.assert_array_equal(data[:, 1:], motion.positions)
