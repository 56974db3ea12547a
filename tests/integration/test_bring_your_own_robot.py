"""A user's robot, the way a user brings it: a URDF path on the command line of every entry point, no Python edited.
Bad robots are one clear line and exit 2 everywhere; good ones run the CSV mode in every physics mode and a short
campaign."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from sim.campaign import analysis
from sim.engine.physics import Mode
from sim.engine.stand_in import EngineOptions, replay_csv
from sim.robots import load_robot
from tests.integration.sim_helpers import mean_of, report_rows, run_campaign
from tests.robot_files import LIFT_ARM, PANDA_WITH_HAND, THIRD_PARTY_URDFS, write_gripper_arm
from tests.rosenv import PYTHON, REPO

# A campaign over ROS records its bags alone (test.sh); what runs no robot through ROS (bad robots refused before
# anything starts, the CSV mode, the no_ros campaign) runs in the beside lane instead.
# The alone lane, with the realtime lane beside it: a campaign's lockstep goes at 250 steps a second, so that rosbag
# record may fall 0.4 s behind (its queue: 100 messages per topic). Unpaced, it lost 52 beside the realtime lane.
pytestmark = pytest.mark.lane("alone", on=("project",))

ENTRY_POINTS = {
    "sim.robots": [],
    "sim.engine": ["--csv", "desired.csv"],
    "sim.commander": ["--scenario", "sweep", "--export-csv", "out.csv", "--export-only"],
    "sim.physics_node": [],
    "sim.description_node": [],
}


def bad_robots(tmp_path: Path) -> dict[str, tuple[str, str]]:
    """name -> (--robot value, what the error must say)"""
    no_moving = tmp_path / "no_moving.urdf"
    no_moving.write_text(
        '<robot name="statue"><link name="base"/><link name="head"/><joint name="neck" '
        'type="fixed"><parent link="base"/><child link="head"/></joint></robot>'
    )
    floating = tmp_path / "floating.urdf"
    floating.write_text(
        '<robot name="drone"><link name="world"/><link name="body"/><joint name="free" '
        'type="floating"><parent link="world"/><child link="body"/></joint></robot>'
    )
    ambiguous = tmp_path / "twins.urdf"  # two equal arms on one torso: no end effector can be derived
    limit = '<limit lower="-1" upper="1" velocity="1" effort="10"/>'
    ambiguous.write_text(
        '<robot name="twins"><link name="torso"/>'
        + "".join(
            f'<link name="{side}_hand"/><joint name="{side}_shoulder" type="revolute"><parent link="torso"/>'
            f'<child link="{side}_hand"/><axis xyz="0 0 1"/>{limit}</joint>'
            for side in ("left", "right")
        )
        + "</robot>"
    )
    return {
        "missing": (str(tmp_path / "absent.urdf"), "URDF not found"),
        "no_moving_joints": (str(no_moving), "has no moving joint"),
        "ambiguous_ee": (
            str(ambiguous),
            "is ambiguous, 2 leaves end a chain of 1 moving joints: left_hand, right_hand",
        ),
        "floating_joint": (str(floating), "joint 'free' is floating"),
    }


@pytest.mark.lane("beside", on=("project",))
@pytest.mark.parametrize("module", sorted(ENTRY_POINTS))
def test_a_bad_urdf_is_one_clear_line_and_exit_2_from_every_entry_point(tmp_path, module):
    # Every kind of bad robot through sim.robots; the others share its loader (robot_from_args): one kind each.
    kinds = bad_robots(tmp_path)
    for name, (robot, message) in (
        kinds.items() if module == "sim.robots" else [("ambiguous_ee", kinds["ambiguous_ee"])]
    ):
        done = subprocess.run(
            [PYTHON, "-m", module, "--robot", robot, *ENTRY_POINTS[module]],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert done.returncode == 2, (name, done.stdout, done.stderr)
        errors = [line for line in done.stderr.splitlines() if "error" in line]
        assert len(errors) == 1 and message in errors[0], (name, done.stderr)


@pytest.mark.lane("beside", on=("project",))
def test_the_campaign_refuses_a_bad_robot_before_running_anything(tmp_path):
    robot, message = bad_robots(tmp_path)["ambiguous_ee"]
    done = subprocess.run(
        [PYTHON, "-m", "sim.trials", "--robots", "igt", robot, "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2 and message in done.stderr
    assert not (tmp_path / "out").exists()
    twice = subprocess.run(
        [PYTHON, "-m", "sim.trials", "--robots", str(LIFT_ARM), str(LIFT_ARM)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert twice.returncode == 2 and "two robots are named lift_arm" in twice.stderr


@pytest.mark.lane("beside", on=("project",))
@pytest.mark.parametrize("name", sorted(THIRD_PARTY_URDFS))
def test_the_trial_exports_and_replays_in_every_physics_mode(tmp_path, name):
    """Commander export and the engine's CSV mode (every mode) on a robot that is not ours; the trial tracks within
    0.05 % MAPE on every moving joint in physics mode. (Every scenario builds on these robots: the unit tests.)"""
    robot = load_robot(str(THIRD_PARTY_URDFS[name]))
    desired = tmp_path / "trial.csv"
    done = subprocess.run(
        [
            PYTHON,
            "-m",
            "sim.commander",
            *robot.cli_args,
            "--scenario",
            "sweep",
            "--export-csv",
            str(desired),
            "--export-only",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    for mode in Mode:
        achieved = tmp_path / f"achieved_{mode.value}.csv"
        if mode is Mode.PHYSICS:  # the command line once; the other modes in this process (the same replay_csv)
            done = subprocess.run(
                [
                    PYTHON,
                    "-m",
                    "sim.engine",
                    *robot.cli_args,
                    "--mode",
                    mode.value,
                    "--csv",
                    str(desired),
                    "--log",
                    str(achieved),
                ],
                capture_output=True,
                text=True,
                timeout=120,
            )
            assert done.returncode == 0, (mode, done.stderr)
        else:
            replay_csv(robot, desired, achieved, EngineOptions(mode=mode))
        metrics = analysis.trial_metrics(analysis.read_csv_pair(desired, achieved, robot), 0.02)
        assert set(metrics) == set(robot.joint_names)  # every joint of the trial moves
        worst = max(m.mape_percent for m in metrics.values())
        assert worst <= (0.05 if mode is Mode.PHYSICS else 1e-6), (mode, worst)


def test_a_short_campaign_runs_on_robots_that_are_not_ours_and_on_arms_with_a_gripper(tmp_path: Path, roscore) -> None:
    """Third parties' arms, the Panda with its hand and an arm the test writes (fingers under a flange with a tool
    frame), each named by its URDF path and nothing else, in one campaign: for the arms with a gripper the end effector
    is the hand's tool frame, said in one line; every moving joint tracks within the issue's 0.05 % MAPE (lockstep is
    deterministic; the CSV mode is the test above) with no message lost."""
    urdfs = {**THIRD_PARTY_URDFS, "panda": PANDA_WITH_HAND, "gripper_arm": write_gripper_arm(tmp_path)}
    done = run_campaign(
        [str(path) for path in urdfs.values()], ["auto_simulate_off"], tmp_path / "out", env=roscore.env
    )
    assert "messages lost: 0" in done.stdout
    for name, tool in (("panda", "panda_grasptarget"), ("gripper_arm", "tool0")):
        said = [line for line in done.stderr.splitlines() if f"robot {name}: end effector '{tool}'" in line]
        assert len(said) == 1, done.stderr[-3000:]
    rows = report_rows(tmp_path / "out" / "report.md")
    for name, path in urdfs.items():
        for joint in load_robot(str(path)).joint_names:
            row = rows[(name, "auto_simulate_off", joint)]
            assert row["lost msgs"] == "0" and mean_of(row["MAPE %"]) <= 0.05, (name, joint, row)
    assert (tmp_path / "out" / "bags" / "lift_arm_auto_simulate_off_1.bag").is_file()


@pytest.mark.lane("beside", on=("project",))
def test_the_campaign_takes_the_overrides_every_command_takes(tmp_path: Path) -> None:
    """`sim.trials` accepts --ee-link (and --base-link, --name, --home) as the other commands do, for one robot; with
    several it says where their overrides go, in one line, exit 2."""
    arm = str(write_gripper_arm(tmp_path))
    done = run_campaign([arm], ["no_ros"], tmp_path / "out", extra=["--ee-link", "flange", "--name", "arm"])
    rows = report_rows(tmp_path / "out" / "report.md")
    assert {joint for robot, _, joint in rows if robot == "arm"} == {f"joint{k}" for k in range(1, 7)}
    assert "end effector 'tool0'" not in done.stderr  # the given end effector, nothing derived to say
    refused = subprocess.run(
        [PYTHON, "-m", "sim.trials", "--robots", arm, "igt", "--ee-link", "flange", "--out", str(tmp_path / "x")],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    errors = [line for line in refused.stderr.splitlines() if "error" in line]
    assert refused.returncode == 2 and len(errors) == 1, refused.stderr
    assert "--ee-link applies to one robot, and 2 are given; put each robot's overrides in a YAML" in errors[0]
    assert not (tmp_path / "x").exists()
