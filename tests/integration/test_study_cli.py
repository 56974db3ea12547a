"""python -m sim.study as a user types it: plans, checks, and bad input as one line and exit 2, before anything
starts."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
import yaml

from sim.processes import PYTHON, REPO, plain_env
from sim.study.design.plan import make_plan, plan_from_data, plan_to_data
from sim.study.design.spec import DEFAULT_DESIGN, load_design
from tests.robot_files import PANDA_WITH_HAND

pytestmark = pytest.mark.lane("beside", on=("project",))


def study(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(
        [PYTHON, "-m", "sim.study", *args], cwd=REPO, env=plain_env(), capture_output=True, text=True, timeout=timeout
    )


def one_error_line(result: subprocess.CompletedProcess, *fragments: str) -> None:
    assert result.returncode == 2, (result.returncode, result.stdout, result.stderr)
    lines = [line for line in result.stderr.splitlines() if "pybullet build time" not in line]
    assert len(lines) == 1 and lines[0].startswith("sim.study "), result.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def test_a_plan_is_written_reproducibly_and_printable(tmp_path: Path) -> None:
    first, again = tmp_path / "a.yaml", tmp_path / "b.yaml"
    assert study("plan", "--participant", "3", "--seed", "9", "--out", str(first)).returncode == 0
    assert study("plan", "--participant", "3", "--seed", "9", "--out", str(again)).returncode == 0
    assert first.read_text() == again.read_text()
    plan = plan_from_data(yaml.safe_load(first.read_text()))
    assert len(plan.trials) == 38 and plan.conditions == ("vr", "reality")
    printed = study("plan", "--participant", "4", "--seed", "9", "--print")
    assert printed.returncode == 0 and "Conditions in this order: reality then vr." in printed.stdout


@pytest.mark.parametrize("robot", [[], ["--robot", str(PANDA_WITH_HAND)]], ids=["the scene's", "from its URDF"])
def test_check_plans_every_combination_of_the_design(robot: list[str]) -> None:
    result = study("check", *robot)
    assert result.returncode == 0, result.stderr
    assert "19 combinations planned" in result.stdout and "not feasible" not in result.stdout


def write(path: Path, data: object) -> Path:
    path.write_text(yaml.safe_dump(data))
    return path


def bundled_plan(path: Path, participant: int, seed: int) -> Path:
    """The bundled design's plan, written here as `plan` writes it (that command is run, and its file compared, above):
    a bad-input case needs a plan, not another process start."""
    plan = make_plan(load_design(DEFAULT_DESIGN), participant, seed)
    path.write_text(yaml.safe_dump(plan_to_data(plan), sort_keys=False))
    return path


@pytest.mark.parametrize(
    "case",
    [
        "unknown path",
        "infeasible stand-off",
        "malformed plan",
        "no records",
        "bad participant",
        "bad option",
        "earlier records",
        "bad robot",
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, case: str) -> None:
    design = {
        "test1": {"paths": ["straight"], "standoffs": [0.1], "peak_speed": 0.15, "sesoi": 0.05},
        "test2": {"paths": ["straight"], "speed_sets": {"slow": 0.1}, "sesoi": 0.02},
    }
    if case == "unknown path":
        design["test2"]["paths"] = ["zigzag"]
        result = study(
            "simulate",
            "--participants",
            "2",
            "--out",
            str(tmp_path / "out"),
            "--design",
            str(write(tmp_path / "d.yaml", design)),
        )
        one_error_line(result, "zigzag")
    elif case == "infeasible stand-off":
        scene = yaml.safe_load((REPO / "sim" / "study" / "design" / "scene.yaml").read_text())
        scene["hand"]["xyz"] = [1.05, 0.0, 0.0175]  # beyond the Panda's reach
        result = study(
            "simulate",
            "--participants",
            "2",
            "--out",
            str(tmp_path / "out"),
            "--design",
            str(write(tmp_path / "d.yaml", design)),
            "--scene",
            str(write(tmp_path / "s.yaml", scene)),
        )
        one_error_line(result, "not feasible", "straight to 0.1 m", "to change: the hand within the arm's reach")
        assert not (tmp_path / "out").exists()  # nothing was started
    elif case == "malformed plan":
        plan = bundled_plan(tmp_path / "plan.yaml", 1, 1)
        data = yaml.safe_load(plan.read_text())
        data["trials"][4]["standoff"] = "near"
        one_error_line(
            study("run", "--plan", str(write(plan, data)), "--out", str(tmp_path / "out")),
            "trial 5",
            "stand-off 'near'",
        )
    elif case == "no records":
        one_error_line(study("analyse", str(tmp_path)), "no participant_*.csv")
    elif case == "bad participant":
        one_error_line(study("plan", "--participant", "0", "--seed", "1"), "participant number")
    elif case == "earlier records":  # a real study's, perhaps: never overwritten
        (tmp_path / "participant_01.csv").write_text("kept\n")
        one_error_line(study("simulate", "--participants", "2", "--out", str(tmp_path)), "already holds participant")
        assert (tmp_path / "participant_01.csv").read_text() == "kept\n"
    elif case == "bad robot":
        plan = bundled_plan(tmp_path / "plan.yaml", 1, 1)
        one_error_line(
            study("run", "--plan", str(plan), "--out", str(tmp_path / "out"), "--robot", "/no/arm.urdf"),
            "the given robot: URDF not found",
        )
        one_error_line(study("check", "--ee-link", "nope"), "the scene's robot", "no link 'nope'")
    else:
        one_error_line(study("simulate", "--participants", "1", "--out", str(tmp_path / "out")), "--participants")
