"""The study end to end with real parts: the runner node (rospy, rosbag record), the endpoint, the engine stand-in
in lockstep, and clients of the endpoint without rospy (a scripted VR scene; simulated participants)."""

from __future__ import annotations

import csv
import math
import re
import subprocess
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from rosbags.rosbag1 import Reader

from bridge.client import TcpClient
from sim.launchers import Runner, finish, start
from sim.processes import plain_env
from sim.study.design.paths import ON_TOP
from sim.study.design.scene import load_scene, scene_robot
from sim.study.design.world import SceneWorld
from sim.study.participants.model import INPUT_DELAY_MAX_S
from sim.study.participants.simulated import POSE_QUEUE
from sim.study.run.protocol import (
    BODIES,
    DISTANCE_TOPIC,
    GO_TOPIC,
    POSE_FRAME,
    POSE_TOPICS,
    PREFERENCE_TOPIC,
    STATUS_TOPIC,
    STOP_TOPIC,
    TOPIC_TYPES,
    TRACKING_GAP,
    status_from_json,
)
from sim.study.run.stop import STOP_DECELERATION
from sim.wire.contract import STEP_S
from sim.wire.rosmsgs import (
    JOINT_STATE,
    TYPESTORE,
    deserialize,
    encode_message,
    encode_pose_stamped,
    time_msg,
    to_seconds,
)
from tests.doc_figures import figures_of, markdown_tables, shape_mismatch
from tests.integration.sim_helpers import start_engine
from tests.integration.study_helpers import SMALL_DESIGN, trial, write_plan
from tests.robot_files import PANDA_WITH_HAND
from tests.rosenv import PYTHON, REPO, ManagedProcess, kill_process

SCENE = load_scene()
ROBOT = scene_robot(SCENE)


def simulate_small_study(
    tmp_path: Path,
    participants: int,
    seed: int | None = None,
    extra: Sequence[str] = (),
    design: dict | None = None,
) -> Path:
    """`python -m sim.study simulate` of SMALL_DESIGN (or `design`) with simulated participants; the folder it
    wrote."""
    design_path = tmp_path / "design.yaml"
    design_path.write_text(yaml.safe_dump(SMALL_DESIGN if design is None else design))
    out = tmp_path / "study"
    command = [PYTHON, "-m", "sim.study", "simulate", "--participants", str(participants), "--design", str(design_path)]
    command += ["--out", str(out)] + ([] if seed is None else ["--seed", str(seed)]) + list(extra)
    process = ManagedProcess(command, plain_env(), tmp_path, "simulate")
    try:
        assert process.wait(300) == 0, process.output()[-3000:]
    finally:
        process.stop()
    return out


def message(topic: str, **fields: Any) -> bytes:
    return encode_message(TOPIC_TYPES[topic], **fields)


# The scripted scene's tracked body in trial 2, in the world: the head still, the right hand on the scene's hand,
# withdrawn from the press by WITHDRAWAL along -y at a constant speed; the left hand away on the table. The head's
# poses stop for HEAD_LOST joint states (a gap), and the first pose is sent on the approach's FIRST_POSE-th state.
HEAD = np.array([0.55, -0.65, 0.45])
LEFT_HAND = np.array([0.35, -0.45, 0.02])
WITHDRAWAL, WITHDRAWAL_SPEED = 0.03, 0.1  # m, m/s
HEAD_LOST = range(10, 21)
PRESS_STATE = 25
UPRIGHT = (0.0, 0.0, 0.0, 1.0)  # every body's orientation: the measures read positions only


class ScriptedVrScene:
    """What a Unity scene would do, scripted: go on ready; in trial 2 a trigger press (unstamped) on the 25th joint
    state of the approach, and the tracked body's poses at each joint state's stamp until the trial ends; wrong
    answers first, then right ones."""

    def __init__(self, port: int) -> None:
        self.client = TcpClient("127.0.0.1", port)
        self.done = threading.Event()
        self.phases: list[tuple[int, str]] = []
        self.moving_states = 0
        self.trial = 0
        self.posing = False  # trial 2, from its approach on
        self.press_stamp = math.nan  # of the joint state on which trial 2's press went
        for topic in (GO_TOPIC, STOP_TOPIC, DISTANCE_TOPIC, PREFERENCE_TOPIC):
            self.client.register_publisher(topic, TOPIC_TYPES[topic])
        # the simulated participant's queue for its poses: joint states that come in a burst (the lockstep starved
        # of CPU a moment) bring poses in a burst; with the default 10 the endpoint dropped 6 of a burst's oldest
        # while rosbag record, starved too, read them no quicker than PUBLISH_WAIT_S
        for topic in POSE_TOPICS.values():
            self.client.register_publisher(topic, TOPIC_TYPES[topic], queue_size=POSE_QUEUE)
        self.client.subscribe(STATUS_TOPIC, TOPIC_TYPES[STATUS_TOPIC], self.on_status)
        self.client.subscribe(ROBOT.joint_states_topic, JOINT_STATE, self.on_joint_state)

    def on_status(self, payload: bytes) -> None:
        status = status_from_json(deserialize(payload, TOPIC_TYPES[STATUS_TOPIC]).data)
        self.phases.append((status.index, status.phase))
        self.trial = status.index if status.phase == "moving" else 0
        self.posing = status.index == 2 and status.phase in ("moving", "at_rest")
        self.moving_states = 0
        if status.phase == "ready":
            self.client.publish(GO_TOPIC, message(GO_TOPIC))
        elif status.phase == "distance":
            self.client.publish(DISTANCE_TOPIC, message(DISTANCE_TOPIC, data=-1.0))  # refused
            self.client.publish(DISTANCE_TOPIC, message(DISTANCE_TOPIC, data=0.123))
        elif status.phase == "preference":
            assert status.group_paths == ("straight", "vertical")
            self.client.publish(PREFERENCE_TOPIC, message(PREFERENCE_TOPIC, data="9"))  # refused, asked again
            self.client.publish(PREFERENCE_TOPIC, message(PREFERENCE_TOPIC, data="2"))
        elif status.phase == "done":
            self.done.set()

    def on_joint_state(self, payload: bytes) -> None:
        if self.trial == 2:
            self.moving_states += 1
            if self.moving_states == PRESS_STATE:
                self.press_stamp = to_seconds(deserialize(payload, JOINT_STATE).header.stamp)
                self.client.publish(STOP_TOPIC, message(STOP_TOPIC, seq=0, stamp=time_msg(0.0), frame_id="vr_trigger"))
        if self.posing:
            stamp = to_seconds(deserialize(payload, JOINT_STATE).header.stamp)
            withdrawn = min(max(stamp - self.press_stamp, 0.0) * WITHDRAWAL_SPEED, WITHDRAWAL)
            hand = SCENE.hand.position + np.array([0.0, -1.0, 0.0]) * (0.0 if math.isnan(withdrawn) else withdrawn)
            if self.moving_states not in HEAD_LOST:
                self.client.publish(POSE_TOPICS["head"], encode_pose_stamped(stamp, POSE_FRAME, HEAD, UPRIGHT))
            self.client.publish(POSE_TOPICS["right_hand"], encode_pose_stamped(stamp, POSE_FRAME, hand, UPRIGHT))
            self.client.publish(POSE_TOPICS["left_hand"], encode_pose_stamped(stamp, POSE_FRAME, LEFT_HAND, UPRIGHT))


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as source:
        return list(csv.DictReader(source))


def bag_messages(bag: Path, topic: str) -> list[Any]:
    with Reader(bag) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        return [TYPESTORE.deserialize_ros1(raw, c.msgtype) for c, _, raw in reader.messages(connections=connections)]


def test_a_vr_scene_stops_the_robot_and_answers_through_the_endpoint(roscore, endpoint, tmp_path: Path) -> None:
    plan = write_plan(
        tmp_path / "plan.yaml",
        7,
        "vr",
        [
            trial(1, "vr", 1, "straight", 0.15, 0.15),
            trial(2, "vr", 2, "straight", ON_TOP, 0.3, "fast", 1),
            trial(3, "vr", 2, "vertical", ON_TOP, 0.3, "fast", 1),
        ],
    )
    engine = start_engine(roscore, tmp_path, "panda", endpoint.port, "--no-auto-simulate")
    scene = ScriptedVrScene(endpoint.port)
    scene.client.connect(timeout=30)
    runner = start(Runner(plan, tmp_path / "out"), roscore.env, tmp_path, "runner")
    try:
        finish(runner, 120)
        assert scene.done.wait(10)
    finally:
        runner.stop()
        scene.client.close()
        engine.stop()
    log = runner.output()
    assert "an answer was refused: a perceived distance must be 0..2 m, got -1.0" in log
    assert "a preference must be one of straight, vertical or 1..2, got '9'; asking again" in log
    # the summary gives the ROS time the lockstep clock advanced: the trials' seconds, not the clock's reading
    (ros_time,) = re.findall(r"participant 7: 3 trials .* s of wall time, ([0-9.]+) s of ROS time in lockstep", log)
    assert 1 < float(ros_time) < 60
    assert [phase for index, phase in scene.phases if index == 1] == [
        "to_start",
        "ready",
        "moving",
        "at_rest",
        "distance",
    ]
    rows = read_csv(tmp_path / "out" / "participant_07.csv")
    assert [row["index"] for row in rows] == ["1", "2", "3"]
    first, pressed, unpressed = rows
    assert float(first["perceived_distance"]) == pytest.approx(0.123, abs=1e-6)
    assert float(first["distance_at_rest"]) == pytest.approx(0.15, abs=0.002) and first["pressed"] == "false"
    # the press: on the runner's clock when it came (unstamped), braking along the path within the stated limit
    assert pressed["pressed"] == "true" and pressed["press_source"] == "vr_trigger"
    assert float(pressed["press_time"]) >= 0.48  # after the 25th state, applied when it came (never "late")
    assert float(pressed["press_late"]) < 1e-9
    braking = float(pressed["braking_distance"])
    assert 0 < braking <= 0.3**2 / (2 * STOP_DECELERATION) + 1e-6  # pressed while moving, braked within a
    at_press, at_rest = float(pressed["distance_at_press"]), float(pressed["distance_at_rest"])
    assert at_rest < at_press and at_press - at_rest == pytest.approx(braking, abs=0.01)
    assert unpressed["pressed"] == "false" and float(unpressed["distance_at_rest"]) == pytest.approx(ON_TOP, abs=0.002)
    assert pressed["preferred_path"] == unpressed["preferred_path"] == "vertical"
    # The tracked body of trial 2, measured over its approach: the right hand withdrew WITHDRAWAL at its speed, the
    # head was lost for the joint states it was not sent on (from the pose before to the one after), and was where
    # it was at the press, from the end effector there
    assert pressed["tracked_hand"] == "right_hand"
    assert float(pressed["withdrawal_distance"]) == pytest.approx(WITHDRAWAL, abs=1e-6)
    assert float(pressed["withdrawal_peak_speed"]) == pytest.approx(WITHDRAWAL_SPEED, rel=1e-3)
    assert float(pressed["hand_untracked"]) == 0.0
    head_lost = (len(HEAD_LOST) + 1) * STEP_S
    assert head_lost > TRACKING_GAP and float(pressed["head_untracked"]) == pytest.approx(head_lost, abs=1e-6)
    for row in (first, unpressed):  # no poses were sent in them
        assert row["tracked_hand"] == "" and row["withdrawal_distance"] == row["head_untracked"] == ""
    # everything is in the bag: the press, the answers, and the robot resting where the CSV says
    bag = tmp_path / "out" / "bags" / "participant_07.bag"
    presses = bag_messages(bag, STOP_TOPIC)
    assert [p.frame_id for p in presses] == ["vr_trigger"]
    assert [round(m.data, 3) for m in bag_messages(bag, DISTANCE_TOPIC)] == [-1.0, 0.123]
    assert [m.data for m in bag_messages(bag, PREFERENCE_TOPIC)] == ["9", "2"]
    heads = bag_messages(bag, POSE_TOPICS["head"])
    assert heads and all(m.header.frame_id == POSE_FRAME for m in heads)
    assert len(bag_messages(bag, POSE_TOPICS["right_hand"])) == len(heads) + len(HEAD_LOST)
    states = bag_messages(bag, ROBOT.joint_states_topic)
    last = states[-1]
    positions = np.array([last.position[list(last.name).index(name)] for name in ROBOT.joint_names])
    press = float(pressed["motion_start"]) + float(pressed["press_time"])
    at_press = min(states, key=lambda state: abs(to_seconds(state.header.stamp) - press))
    positions_at_press = np.array([at_press.position[list(at_press.name).index(n)] for n in ROBOT.joint_names])
    with SceneWorld(ROBOT, SCENE) as world:  # the robot's nearest surface, the scene's definition of the distance
        assert world.hand_distance(positions) == pytest.approx(float(unpressed["distance_at_rest"]), abs=1e-4)
        head_to_end_effector = float(np.linalg.norm(HEAD - world.end_effector(positions_at_press)))
    assert float(pressed["head_distance_at_press"]) == pytest.approx(head_to_end_effector, abs=1e-4)
    assert to_seconds(last.header.stamp) > 0


# On Noetic's Python: runner, participants, rosbag and report as a ROS Noetic user runs them. In lockstep the
# study's processes wait for each other, not for the clock: beside other work.
@pytest.mark.lane("beside", on=("noetic",))
def test_simulated_participants_run_the_study_and_the_analysis_recovers_their_biases(tmp_path: Path) -> None:
    """Four simulated participants through the whole study: roscore, endpoint, engine, the runner, participants over
    TCP, rosbag record, the report and its plots. launch_scripts/test.sh runs it on ROS Noetic's Python 3.8, where
    every process of it but roscore and rosbag runs on that Python. The robot is the Panda from its URDF path alone,
    in the scene's place: simulate hands it to every process (its end effector the hand's tool frame, as the scene's
    own robot has it). The participants' own VR − reality differences spread little (their SDs given), so that four
    of them recover the population's differences."""
    spreads = ["--distance-shift-sd", "0.01", "--comfort-shift-sd", "0.005", "--withdrawal-shift-sd", "0.002"]
    out = simulate_small_study(tmp_path, participants=4, seed=11, extra=["--robot", str(PANDA_WITH_HAND), *spreads])
    report = (out / "report.md").read_text()
    for plot in ("test1_distance_perception.png", "test2_comfort_distance.png", "agreement_bland_altman.png"):
        assert f"]({plot})" in report and (out / plot).stat().st_size > 10_000
    assert "## VR against reality: the verdicts" in report and "### Test 2: the mixed model" in report
    # README's tables of simulated studies have the columns and rows that simulate prints today
    for figures in figures_of("python -m sim.study simulate"):
        assert shape_mismatch(figures, markdown_tables(report)) is None, shape_mismatch(
            figures, markdown_tables(report)
        )
    from sim.study.analysis.latency import summarise_latency
    from sim.study.analysis.motion import summarise_motion
    from sim.study.analysis.report import load_study
    from sim.study.analysis.summary import summarise

    records = load_study(out)
    assert len(records) == 4 * 14 and {r.participant for r in records} == {1, 2, 3, 4}
    assert all(
        r.pressed and r.press_source == ("vr_trigger" if r.condition == "vr" else "button")
        for r in records
        if r.test == 2
    )
    # Each press is sent when its approach starts, stamped where it is to land: none comes late, however far the
    # participant's joint states lag behind the lockstep
    assert all(r.press_late == 0.0 for r in records if r.test == 2), [
        (r.participant, r.index, r.press_late, r.press_arrival_delay) for r in records if r.press_late
    ]
    # Each with the modelled input delay of its condition's page (within one frame) in the Header's seq, and the
    # arrival delay the runner measured: sent ahead, each arrived at or before its stamp (in lockstep, within a step)
    for r in records:
        if r.test == 2:
            assert 0 < r.press_input_delay <= INPUT_DELAY_MAX_S[r.condition] + 1e-6, r
            assert r.press_arrival_delay <= STEP_S + 1e-9, r
    assert "| vr_trigger | 16 |" in report and "| button | 16 |" in report and "The button path minus" in report
    assert all(math.isfinite(r.perceived_distance) for r in records if r.test == 1)
    summary = summarise(records)
    ratio = summary.distance_ratio_vr_vs_reality  # the 15 % underestimate put in
    assert ratio.ci_low <= -0.15 <= ratio.ci_high < 0, ratio
    # 2 cm closer in VR, as put in: the participants anticipate their presses, so the distances at the press differ
    # by what they mean to, not less
    press = summary.stop_distance_vr_vs_reality
    assert press.ci_low <= -0.02 <= press.ci_high < 0, press
    # Their motion: 1 cm less withdrawal in VR, as put in, from the poses they sent at every step of the approach
    motion = summarise_motion(records)
    (withdrawal,) = [c for c in motion.comparisons if c.measure.column == "withdrawal_distance" and c.measure.test == 2]
    shift = withdrawal.vr_vs_reality
    assert shift is not None and shift.ci_low <= -0.01 <= shift.ci_high < 0, shift
    assert all(r.tracked_hand == "right_hand" and r.hand_untracked == 0.0 == r.head_untracked for r in records)
    assert "## The participant's motion" in report
    # Each stop path's input delay, uniform up to its page's longest: its mean is half that
    latency = summarise_latency(records)
    for source, condition in (("vr_trigger", "vr"), ("button", "reality")):
        delays = [r.press_input_delay for r in records if r.press_source == source]
        assert float(np.mean(delays)) == pytest.approx(INPUT_DELAY_MAX_S[condition] / 2, rel=0.4), (source, delays)
        assert latency.path(source).input_delay.measured == len(delays) == 16
    for number in range(1, 5):
        bag = out / "bags" / f"participant_{number:02d}.bag"
        assert len(bag_messages(bag, STOP_TOPIC)) == 8 and len(bag_messages(bag, DISTANCE_TOPIC)) == 6
        # The tracked body in the bag at the simulated headset's frame rate, its engine's step, in every approach.
        # Not every pose: beside other work a lockstep's catching-up participant sends poses in bursts, and a
        # starved rosbag record drops what overflows its queue of 100 a topic (seen: 14 of 2006 of one body). That
        # the bag holds every pose sent is for the tests that run alone: the scripted scene's and the browser's.
        for body in BODIES:
            stamps = np.array([to_seconds(m.header.stamp) for m in bag_messages(bag, POSE_TOPICS[body])])
            steps = np.diff(stamps) / STEP_S
            assert np.median(steps) == pytest.approx(1.0) and np.allclose(steps, np.round(steps), atol=1e-4), body
            starts = sorted(r.motion_start for r in records if r.participant == number) + [math.inf]
            assert all(np.any((stamps >= a) & (stamps < b)) for a, b in zip(starts, starts[1:])), body
    derived = "robot panda: end effector 'panda_grasptarget': the tool frame of 'panda_hand'"
    for log in [*(out / "logs").glob("runner_*.log"), *(out / "logs").glob("participant_*.log")]:
        assert derived in log.read_text(), log


# The trials around the questionnaires: two of each test a block (8 a participant); what is asked between the blocks
# does not depend on how many trials they hold, and the biases are the 14-trial study's above
QUESTIONNAIRE_TRIALS = {
    "test1": {"paths": ["straight"], "standoffs": [0.08, 0.14], "peak_speed": 0.15, "sesoi": 0.05},
    "test2": {"paths": ["straight"], "speed_sets": {"slow": 0.2, "fast": 0.3}, "sesoi": 0.02},
}


# In lockstep, as the simulated study above: beside other work, on 3.8 so that the idle lanes end together (on
# 3.11's beside lane it was the last to end, 2 minutes after the others)
@pytest.mark.lane("beside", on=("noetic",))
def test_simulated_participants_answer_the_planned_questionnaires_and_the_report_scores_them(tmp_path: Path) -> None:
    """Two simulated participants (one starts with VR, one with reality) through a study whose design asks the SSQ
    before and after VR, the IPQ after VR and a lab item after each condition, as the bundled design does. No
    symptom before VR (--ssq-level 0), so every SSQ before VR scores 0 whichever block came first, and one after.
    Every item is answered, once, on the answer topic, into the bag; the scores are those of the answers; the
    report has their section."""
    from sim.study.design.plan import plan_from_data
    from sim.study.questionnaires.rows import read_answers, read_scores
    from sim.study.questionnaires.scoring import scores
    from sim.study.run.protocol import ANSWER_TOPIC, answer_from_json

    questionnaires = {
        "ssq": {"when": ["before_vr", "after_vr"]},
        "ipq": {"when": ["after_vr"]},
        "items": {
            "perceived_safety": {
                "text": "How safe did you feel near the robot?",
                "scale": [1, 7],
                "labels": ["not at all safe", "completely safe"],
                "when": ["after_each"],
            }
        },
    }
    design = {**QUESTIONNAIRE_TRIALS, "questionnaires": questionnaires}
    truths = ["--ssq-level", "0", "--vr-ssq-rise", "1.0"]
    out = simulate_small_study(tmp_path, participants=2, seed=5, extra=truths, design=design)
    plan = plan_from_data(yaml.safe_load((out / "plans" / "participant_01.yaml").read_text()))
    instruments = {name: plan.instrument(name) for name in ("ssq", "ipq", "perceived_safety")}
    assert instruments["perceived_safety"].items[0].text == "How safe did you feel near the robot?"
    administrations = {
        "ssq": ["ssq_before_vr", "ssq_after_vr"],
        "ipq": ["ipq_after_vr"],
        "perceived_safety": ["perceived_safety_after_vr", "perceived_safety_after_reality"],
    }
    for number in (1, 2):
        stem = f"participant_{number:02d}.csv"
        asked = {}
        for name, instrument in instruments.items():
            answers = read_answers(out / "questionnaires" / "answers" / f"{name}_{stem}")
            assert sorted({row.administration for row in answers}) == sorted(administrations[name])
            assert len(answers) == len(instrument.items) * len(administrations[name])
            assert all(row.answer is not None and row.participant == number for row in answers)
            given = {}
            for row in answers:
                given.setdefault(row.administration, {})[row.item] = row.answer
                asked[(row.administration, row.item)] = row.answer
            scored = read_scores(out / "questionnaires" / "scores" / f"{name}_{stem}")
            for administration, items in given.items():
                expected = scores(instrument, items)
                found = {r.subscale: r.score for r in scored if r.administration == administration}
                assert found == pytest.approx(expected), administration
            if name == "ssq":
                assert all(answer == 0 for (a, _), answer in asked.items() if a == "ssq_before_vr")
                assert sum(answer for (a, _), answer in asked.items() if a == "ssq_after_vr") > 0
        # the bag holds every answer as sent, one per item asked, and the CSV has them as the bag does
        bag = out / "bags" / f"participant_{number:02d}.bag"
        sent = [answer_from_json(m.data) for m in bag_messages(bag, ANSWER_TOPIC)]
        assert {(a.administration, a.item): a.answer for a in sent} == asked and len(sent) == len(asked)
        phases = [status_from_json(m.data) for m in bag_messages(bag, STATUS_TOPIC)]
        items = [(s.administration, s.item) for s in phases if s.phase == "questionnaire"]
        assert sorted(items) == sorted(asked) and len(items) == len(asked)
    report = (out / "report.md").read_text()
    assert "## Questionnaires" in report and "| ssq_after_vr | total | 2 |" in report
    assert "| ipq_after_vr | spatial_presence | 2 |" in report
    assert re.search(r"^\| 1 \| 0\.0 \| [0-9.]+ \| \+[0-9.]+ \|", report, re.M)
    assert "**VR data suspect** when the SSQ total after VR is above 20" in report


# In lockstep, as the simulated study above: beside other work
@pytest.mark.lane("beside", on=("project",))
def test_a_simulated_participant_that_fails_partway_ends_the_study_at_once_with_its_error(tmp_path: Path) -> None:
    """The first participant fails at its second test-1 trial (the fault injected for tests, --fault-trial: its
    distance measure gives inf, which its model refuses, as a lift that fell once made it): simulate ends there, a run
    that failed (exit 1), with the participant's own error in one line; the runner was stopped at that trial (its
    records end with it, its answer missing), not left to wait out its response timeout for the answer and go on."""
    from sim.study.design.plan import make_plan
    from sim.study.design.spec import load_design

    design_path = tmp_path / "design.yaml"
    design_path.write_text(yaml.safe_dump(SMALL_DESIGN))
    trials = make_plan(load_design(design_path), 1, 7).trials
    answered, fault = [t.index for t in trials if t.test == 1][:2]
    out = tmp_path / "study"
    command = [
        PYTHON,
        "-m",
        "sim.study",
        "simulate",
        "--participants",
        "2",
        "--seed",
        "7",
        "--design",
        str(design_path),
    ]
    process = ManagedProcess([*command, "--out", str(out), "--fault-trial", str(fault)], plain_env(), tmp_path, "sim")
    try:
        code = process.wait(240)
    finally:
        process.stop()
    output = process.output()
    assert code == 1, output[-3000:]
    last = output.strip().splitlines()[-1]
    assert last.startswith(
        f"sim.study simulate: error: participant_01 exited with 1: trial {fault} (distance): an actual distance must "
        "be >= 0 m, got inf (its log: "
    ), output[-3000:]
    rows = read_csv(out / "participant_01.csv")  # the runner, stopped, keeps the failed trial's answer missing
    assert [int(row["index"]) for row in rows] == list(range(1, fault + 1)), rows
    assert rows[-1]["perceived_distance"] in ("", "nan") and rows[answered - 1]["perceived_distance"] not in ("", "nan")
    assert not (out / "participant_02.csv").exists() and not (out / "report.md").exists()


pytestmark = [pytest.mark.lane("alone", on=("project",)), pytest.mark.timeout(400)]


def test_the_observer_drives_a_reality_trial_from_the_runners_keyboard(roscore, endpoint, tmp_path: Path) -> None:
    # In real time, as a real robot would run: the approach lasts its planned seconds, and the stop typed while it
    # moves lands in it.
    plan = write_plan(
        tmp_path / "plan.yaml",
        8,
        "reality",
        [
            trial(1, "reality", 1, "vertical", 0.1, 0.2),
            trial(2, "reality", 2, "straight", ON_TOP, 0.2, "medium", 1),
        ],
    )
    engine = start_engine(roscore, tmp_path, "panda", endpoint.port, "--no-auto-simulate")
    phases: list[tuple[int, str]] = []
    changed = threading.Condition()

    def on_status(payload: bytes) -> None:
        status = status_from_json(deserialize(payload, TOPIC_TYPES[STATUS_TOPIC]).data)
        with changed:
            phases.append((status.index, status.phase))
            changed.notify_all()

    watcher = TcpClient("127.0.0.1", endpoint.port)  # only watches the phases, as an observer's screen would
    watcher.subscribe(STATUS_TOPIC, TOPIC_TYPES[STATUS_TOPIC], on_status)
    watcher.connect(timeout=30)
    out = tmp_path / "out"
    runner = subprocess.Popen(
        [
            PYTHON,
            "-m",
            "sim.study",
            "run",
            "--plan",
            str(plan),
            "--out",
            str(out),
            "--keyboard",
            "--no-record",
            "--realtime",
        ],
        env=roscore.env,
        cwd=REPO,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )

    def when(phase: tuple[int, str], line: str) -> None:
        with changed:
            assert changed.wait_for(lambda: phase in phases, timeout=60), phases
        assert runner.stdin is not None
        runner.stdin.write(line)
        runner.stdin.flush()

    try:
        when((1, "ready"), "\n")
        when((1, "distance"), "banana\n")  # not a distance: said, and asked on
        when((1, "distance"), "9.5 cm\n")
        when((2, "ready"), "\n")
        when((2, "moving"), "s\n")
        when((2, "preference"), "1\n")
        output, _ = runner.communicate(timeout=60)
    finally:
        kill_process(runner)
        watcher.close()
        engine.stop()
    assert runner.returncode == 0, output
    assert "'banana' is not a distance" in output
    assert "trial 2/2 (reality, test 2, straight): s + Enter to stop" in output
    first, second = read_csv(out / "participant_08.csv")
    assert float(first["perceived_distance"]) == pytest.approx(0.095)
    assert second["pressed"] == "true" and second["press_source"] == "keyboard"
    assert float(second["distance_at_rest"]) > 0.05 and second["preferred_path"] == "straight"


def test_roslaunch_runs_a_session_from_the_catkin_package(roscore, endpoint, tmp_path: Path) -> None:
    # Nobody answers the preference here: after --response-timeout the session goes on, and says so.
    plan = write_plan(tmp_path / "plan.yaml", 9, "vr", [trial(1, "vr", 2, "vertical", ON_TOP, 0.3, "fast", 1)])
    engine = start_engine(roscore, tmp_path, "panda", endpoint.port, "--no-auto-simulate")
    out = tmp_path / "out"
    command = (
        f"source {REPO / 'catkin_ws' / 'devel' / 'setup.bash'} && exec roslaunch vr_sim study.launch "
        f"plan:={plan} out:={out} python:={PYTHON} "
        "extra_args:='--auto-go --response-timeout 1'"
    )
    launch = ManagedProcess(["bash", "-c", command], roscore.env, tmp_path, "roslaunch")
    try:
        assert launch.wait(120) == 0, launch.output()[-3000:]
    finally:
        launch.stop(timeout=20)
        engine.stop()
    assert "no preference within 1 s; left empty" in launch.output()
    (row,) = read_csv(out / "participant_09.csv")
    assert row["pressed"] == "false" and float(row["distance_at_rest"]) == pytest.approx(ON_TOP, abs=0.002)
    phases = [status_from_json(m.data).phase for m in bag_messages(out / "bags" / "participant_09.bag", STATUS_TOPIC)]
    assert phases[0] == "to_start" and phases[-2:] == ["preference", "done"]
