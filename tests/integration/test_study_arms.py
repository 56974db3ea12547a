"""The study with arms the project does not bundle, from their URDF alone (issue: a lab's own robot): every
combination of the bundled design checks, in the bundled scene or the one proposed for the arm; the proposal is
written and read back; an arm that cannot do the study is told why in one line; a simulated study with each arm runs
end to end and recovers the biases it was given.

What the checks and `scene` work out (self-contact verdicts, scene proposals) is kept in the run's cache (test.sh's
$VR_SIM_CACHE, new for every run; a test's own without it): a check computes its arm's, the first in the run to ask,
and that arm's simulated study reads them."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from sim.launchers import finish
from sim.processes import PYTHON, REPO, ManagedProcess, plain_env
from sim.robots.examples import (
    LAB_ARM_EE_LINKS,
    SCARA_LIKE,
    STUDY_ARMS,
    ArmDesign,
    with_effort,
    write_arm,
    write_lab_arm,
)
from tests.integration.study_helpers import SMALL_DESIGN
from tests.robot_files import THIRD_PARTY_URDFS
from tests.study_arms import study_arm

pytestmark = [pytest.mark.lane("beside", on=("project",)), pytest.mark.timeout(300)]


def study(args: list[str], cache: Path, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    env = dict(plain_env(), VR_SIM_CACHE=str(cache))
    return subprocess.run(
        [PYTHON, "-m", "sim.study", *args], cwd=REPO, env=env, capture_output=True, text=True, timeout=timeout
    )


def run_cache(tmp_path: Path) -> Path:
    """The test run's cache where test.sh gives one, else this test's own."""
    return Path(os.environ.get("VR_SIM_CACHE") or tmp_path / "cache")


def arm(tmp_path: Path, name: str) -> Path:
    return study_arm(tmp_path / "arms", name)


def robot_args(tmp_path: Path, name: str) -> list[str]:
    """--robot (and --ee-link where the URDF has more than one end, as a UR's has)."""
    ee_link = LAB_ARM_EE_LINKS.get(name)
    return ["--robot", str(arm(tmp_path, name)), *(["--ee-link", ee_link] if ee_link else [])]


# (the LBR iiwa's proposal is made and checked in the next test; the five-joint desktop arm in its own below)
@pytest.mark.parametrize("name", [*(design.name for design in STUDY_ARMS), "xarm6", "ur5_like", "scara_like"])
def test_every_combination_checks_on_the_arm_from_its_urdf_alone(tmp_path: Path, name: str) -> None:
    done = study(["check", *robot_args(tmp_path, name)], run_cache(tmp_path))
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "19 combinations planned" in done.stdout and "not feasible" not in done.stdout
    kept = {line.split("|")[7].strip() for line in done.stdout.splitlines() if line.startswith("| ") and "m/s" in line}
    # what IK kept, per combination: the whole pose on six joints or more; the SCARA (four joints, its quill pointing
    # down by construction) the position and the tool axis
    assert kept == {"scara_like": {"position and tool axis"}}.get(name, {"position and orientation"}), kept


def test_the_desktop_arm_checks_every_combination_with_its_tool_down_on_test_1s_paths(tmp_path: Path) -> None:
    # five joints (its roll free): its end effector 40 mm beyond its gripper's geometry ends inside the hand for the
    # gripper to end 20 mm from it; a path whose tool-down pose is beyond its wrist's reach keeps the position alone
    done = study(["check", *robot_args(tmp_path, "widowx_like")], run_cache(tmp_path))
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "19 combinations planned" in done.stdout and "not feasible" not in done.stdout
    rows = [line.split("|") for line in done.stdout.splitlines() if line.startswith("| ") and "m/s" in line]
    kept = {(row[1].strip(), row[7].strip()) for row in rows}
    assert {what for path, what in kept if path in ("straight", "vertical")} == {"position and tool axis"}, kept
    assert {what for _, what in kept} <= {"position and tool axis", "position only"}, kept
    assert "widowx_like: the paths' shapes" in done.stdout  # sized to its reach, and said so


def test_the_proposed_scene_is_written_with_its_reasons_and_checks_as_given(tmp_path: Path) -> None:
    urdf = str(THIRD_PARTY_URDFS["lbr_iiwa"])
    out = tmp_path / "iiwa_scene.yaml"
    done = study(["scene", "--robot", urdf, "--out", str(out)], run_cache(tmp_path))  # kept for the study below
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("tried the bundled scene")  # the thesis's scene first (its paths sized), and why not
    assert "fits" in done.stdout.splitlines()[-2] and f"-> {out}" in done.stdout
    text = out.read_text()
    assert text.startswith("# The study's scene for lbr_iiwa, proposed by python -m sim.study scene")
    data = yaml.safe_load(text)
    assert data["robot"] == urdf and data["distance"] == "surface" and data["base"]["xyz"] == [0.0, 0.0]
    # checked as given: in a cache with no scene or plan of this run's, so planned afresh; the arm's self-contact
    # verdict (which pairs of its links can meet, no part of the scene) as this run has it, not sampled again
    other = tmp_path / "other_cache"
    shutil.copytree(run_cache(tmp_path) / "self_contact", other / "self_contact")
    again = study(["check", "--scene", str(out), "--robot", urdf], other)
    assert again.returncode == 0, again.stdout[-2000:]


def test_an_arm_that_cannot_reach_over_a_table_is_told_why_in_one_line(tmp_path: Path) -> None:
    tiny = write_arm(tmp_path / "arms", ArmDesign("tiny_arm", 6, 0.25))
    done = study(["check", "--robot", str(tiny)], tmp_path / "cache")
    assert done.returncode == 2 and done.stdout == ""
    lines = [line for line in done.stderr.splitlines() if not line.startswith("pybullet build time")]
    assert len(lines) == 1 and lines[0].startswith("sim.study check: error: no scene fits tiny_arm (reach "), lines
    assert "give a scene of your own with --scene" in lines[0]


def test_an_arm_whose_lift_cannot_carry_it_is_refused_in_one_line_before_anything_runs(tmp_path: Path) -> None:
    # the SCARA's lift at 100 N, under the 103 N that hangs on it: its simulated study once hung, the lift falling
    weak = write_lab_arm(tmp_path / "arms", "scara_like", with_effort(SCARA_LIKE, "lift", 100.0))
    out = tmp_path / "study"
    for command in (["check"], ["simulate", "--participants", "2", "--out", str(out)]):
        done = study([*command, "--robot", str(weak)], tmp_path / "cache", timeout=120)
        lines = [line for line in done.stderr.splitlines() if not line.startswith("pybullet build time")]
        # (stdout has only pybullet's own warnings: tool0 has no <inertial>)
        assert done.returncode == 2 and "combinations" not in done.stdout and len(lines) == 1, (command, lines)
        assert lines[0].startswith(
            f"sim.study {command[0]}: error: scara_like: lift cannot hold the arm at home: it needs 103.0 N, its "
            "effort limit is 100 N; to change: a joint that holds the arm"
        ), lines
    assert not out.exists()  # refused before anything was written or started


# In lockstep, the study's processes wait for each other, not for the clock: beside other work, as the checks.
# The UR5's scene is proposed with the paths' shapes made smaller, named by its tool0. The SCARA (a prismatic lift,
# its quill pointing down) and the five-joint desktop arm (its tool's roll free) too.
@pytest.mark.parametrize("name", [*(design.name for design in STUDY_ARMS), "ur5_like", "scara_like", "widowx_like"])
def test_a_simulated_study_with_the_arm_recovers_its_biases(tmp_path: Path, name: str) -> None:
    simulated_study_recovers_its_biases(tmp_path, name)


# The LBR iiwa's (its scene proposed with the paths' shapes made smaller) on Noetic's Python, in the lane beside the
# project's unit and beside lanes: a minute taken off the suite's critical path, and the fit of a third party's arm
# run on 3.8, the oldest Python (its scene from the run's cache when the project's `scene` test above came first)
@pytest.mark.lane("beside", on=("noetic",))
def test_a_simulated_study_with_the_lbr_iiwa_recovers_its_biases(tmp_path: Path) -> None:
    simulated_study_recovers_its_biases(tmp_path, "lbr_iiwa")


def simulated_study_recovers_its_biases(tmp_path: Path, name: str) -> None:
    design = tmp_path / "design.yaml"
    design.write_text(yaml.safe_dump(SMALL_DESIGN))
    out = tmp_path / "study"
    spreads = ["--distance-shift-sd", "0.01", "--comfort-shift-sd", "0.005"]
    # without bags: the report reads the CSVs, and the study's bags are the Panda's tests' (test_study.py)
    command = ["simulate", "--participants", "2", "--seed", "3", "--design", str(design), "--out", str(out)]
    command += ["--no-record"]
    # simulate starts a roscore, an endpoint and nodes: in a process group of its own, stopped whatever happens
    env = dict(plain_env(), VR_SIM_CACHE=str(run_cache(tmp_path)))
    process = ManagedProcess(
        [PYTHON, "-m", "sim.study", *command, *robot_args(tmp_path, name), *spreads], env, tmp_path, "simulate"
    )
    try:
        finish(process, 280)
    finally:
        process.stop()
    from sim.study.analysis.report import load_study
    from sim.study.analysis.summary import summarise

    records = load_study(out)
    assert not (out / "bags").exists()  # --no-record
    assert len(records) == 2 * 14 and all(r.pressed and r.press_late == 0.0 for r in records if r.test == 2)
    summary = summarise(records)
    # Two participants, three judgements each per condition: the estimates are near what was put in, within the
    # judgements' noise (a perceived / actual ratio's is some 0.05) and the two participants' own differences (their
    # comfort shifts' SD is 5 mm, their mean's 3.5 mm: 10 mm is three of those)
    ratio, press = summary.distance_ratio_vr_vs_reality, summary.stop_distance_vr_vs_reality
    assert ratio.mean_difference == pytest.approx(-0.15, abs=0.06), ratio  # the 15 % underestimate put in
    assert press.mean_difference == pytest.approx(-0.02, abs=0.01), press  # 2 cm closer in VR, as put in
    scene = yaml.safe_load((out / "scene.yaml").read_text())
    assert scene["robot"] == str(arm(tmp_path, name))  # every process was handed the scene chosen for the arm
