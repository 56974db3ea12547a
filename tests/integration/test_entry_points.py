"""Every command of sim/ answers bad input the same way: one line naming the problem, exit code 2 (sim.entry)."""

from __future__ import annotations

import os
import subprocess

import pytest

from tests.rosenv import PYTHON, REPO

pytestmark = pytest.mark.lane("beside", on=("project",))

COMMANDS = [
    ("sim.commander", ["--scenario", "sweep"]),
    ("sim.engine", []),
    ("sim.physics_node", []),
    ("sim.description_node", []),
    ("sim.trials", []),
    ("sim.demo", []),
    ("sim.robots", []),
]


def problem_lines(stderr: str) -> list[str]:
    """stderr without pybullet's banner, which its C extension prints at import, before any of our code runs."""
    return [line for line in stderr.strip().splitlines() if not line.startswith("pybullet build time:")]


@pytest.mark.parametrize("module, extra", COMMANDS, ids=[module for module, _ in COMMANDS])
def test_an_unknown_robot_is_one_line_and_exit_2(module: str, extra: list[str], tmp_path) -> None:
    robot_option = ["--robots", "no_such_robot"] if module == "sim.trials" else ["--robot", "no_such_robot"]
    done = subprocess.run(
        [PYTHON, "-m", module, *robot_option, *extra],
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(REPO), "ROS_MASTER_URI": "http://127.0.0.1:9/"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, (done.stdout, done.stderr)
    lines = problem_lines(done.stderr)
    assert len(lines) == 1 and lines[0].startswith(f"{module}: error: ") and "no_such_robot" in lines[0], done.stderr


def test_a_bad_study_design_is_one_line_and_exit_2(tmp_path) -> None:
    design = tmp_path / "design.yaml"
    design.write_text("participants: many\n")
    done = subprocess.run(
        [PYTHON, "-m", "sim.study", "plan", "--participant", "1", "--seed", "0", "--design", str(design)],
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, (done.stdout, done.stderr)
    lines = problem_lines(done.stderr)
    assert len(lines) == 1 and lines[0].startswith("sim.study plan: error: "), done.stderr
