"""sim.study.participants.simulated, its tracked body, without an endpoint: fed the runner's statuses and joint
states as the endpoint would hand them over, it publishes every body's pose from a trial's motion on, on the joint
states' grid up to each joint state's own stamp, with no gap where a joint state was missed; the hand withdraws
after a test-2 press and stays in test 1. An error in acting on what it is handed ends it at once, named."""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Callable

import numpy as np
import pytest

from sim.study.design.paths import ON_TOP
from sim.study.design.scene import load_scene, scene_robot
from sim.study.participants.body import TRACKING_JITTER
from sim.study.participants.model import (
    WITHDRAWAL_DURATION,
    Population,
    draw_traits,
)
from sim.study.participants.simulated import SimulatedParticipant
from sim.study.questionnaires.instruments import standard_instrument
from sim.study.run.protocol import (
    BODIES,
    DISTANCE_TOPIC,
    GO_TOPIC,
    POSE_FRAME,
    POSE_TOPICS,
    POSE_TYPE,
    STATUS_TOPIC,
    STOP_TOPIC,
    TrialStatus,
    status_to_json,
)
from sim.wire.contract import STEP_S
from sim.wire.rosmsgs import deserialize, encode_joint_state, encode_message, time_msg, to_seconds

SCENE = load_scene()
ROBOT = scene_robot(SCENE)
DT = STEP_S
JITTER = 6 * TRACKING_JITTER  # m: farther than this from the model's pose is no jitter


class FakeClient:
    """What the participant uses of a TcpClient: registrations kept, publications recorded."""

    def __init__(self) -> None:
        self.publishers: dict[str, tuple[str, int]] = {}
        self.callbacks: dict[str, Callable[[bytes], None]] = {}
        self.sent: list[tuple[str, bytes]] = []

    def register_publisher(self, topic: str, message_name: str, queue_size: int = 10, latch: bool = False) -> None:
        self.publishers[topic] = (message_name, queue_size)

    def subscribe(self, topic: str, message_name: str, callback: Callable[[bytes], None], queue_size=None) -> None:
        self.callbacks[topic] = callback

    def publish(self, topic: str, payload: bytes) -> None:
        self.sent.append((topic, payload))


@pytest.fixture
def participant():
    client = FakeClient()
    made = SimulatedParticipant(client, ROBOT, SCENE, draw_traits(Population(), 1, 3), seed=3)  # type: ignore[arg-type]
    made.attach()
    yield made
    made.close()


def say(participant: SimulatedParticipant, status: TrialStatus) -> None:
    participant._on_status(encode_message("std_msgs/String", data=status_to_json(status)))


def joint_state(participant: SimulatedParticipant, stamp: float) -> None:
    zeros = np.zeros(ROBOT.dof)
    participant._on_joint_state(encode_joint_state(0, stamp, ROBOT.joint_names, zeros, zeros, zeros))


def poses_sent(participant: SimulatedParticipant) -> dict[str, list[Any]]:
    client: Any = participant.client
    by_body: dict[str, list[Any]] = {body: [] for body in BODIES}
    topics = {topic: body for body, topic in POSE_TOPICS.items()}
    for topic, payload in client.sent:
        if topic in topics:
            by_body[topics[topic]].append(deserialize(payload, POSE_TYPE))
    return by_body


def stamps(messages: list[Any]) -> list[float]:
    return [to_seconds(m.header.stamp) for m in messages]


def position(message: Any) -> np.ndarray:
    p = message.pose.position
    return np.array([p.x, p.y, p.z])


def test_a_test_1_trial_publishes_every_body_on_the_grid_up_to_each_joint_state_and_the_hand_stays(
    participant,
) -> None:
    client: Any = participant.client
    assert {client.publishers[topic] for topic in POSE_TOPICS.values()} == {(POSE_TYPE, 100)}
    trial = TrialStatus(1, 1, 2, "ready", "vr", 1, "straight", 0.15, 0.15)
    say(participant, trial)
    assert client.sent[-1][0] == GO_TOPIC
    joint_state(participant, 1.98)  # before the motion: no pose
    say(participant, replace(trial, phase="moving", motion_start=2.0))
    for stamp in (2.0, 2.02, 2.06, 2.08):  # 2.04 is missed
        joint_state(participant, stamp)
    say(participant, replace(trial, phase="at_rest", motion_start=2.0))
    joint_state(participant, 2.1)  # the same trial: still tracked
    joint_state(participant, 2.1)  # again: covered already
    say(participant, TrialStatus(1, 2, 2, "to_start", "vr", 1, "straight", 0.15, 0.15))
    joint_state(participant, 2.12)  # the next trial, before its motion: no pose
    sent = poses_sent(participant)
    for body in BODIES:
        assert stamps(sent[body]) == pytest.approx([2.0, 2.02, 2.04, 2.06, 2.08, 2.1], abs=1e-9)
        assert all(m.header.frame_id == POSE_FRAME for m in sent[body])
    # exactly at each joint state's stamp, as the runner's wait at the motion's end needs
    assert [m.header.stamp.nanosec for m in sent["head"][-3:]] == [time_msg(t).nanosec for t in (2.06, 2.08, 2.1)]
    hands = np.array([position(m) for m in sent["right_hand"]])
    assert np.abs(hands - SCENE.hand.top).max() < JITTER
    assert participant.poses == 6 and not participant.failure


def test_a_test_2_trial_withdraws_the_hand_from_the_press_until_a_questionnaire(participant) -> None:
    client: Any = participant.client
    trial = TrialStatus(1, 3, 4, "ready", "reality", 2, "straight", ON_TOP, 0.3, "fast", 1)
    say(participant, trial)
    press_after, withdrawal = participant._press_after, participant._withdrawal
    assert press_after is not None and press_after > 0 and withdrawal > 0
    joint_state(participant, 10.0)  # the motion's first joint state came before its status
    say(participant, replace(trial, phase="moving", motion_start=10.0))
    assert [topic for topic, _ in client.sent].count(STOP_TOPIC) == 1
    timing = participant._timing  # at once, or late and slow
    assert timing.duration >= WITHDRAWAL_DURATION
    steps = int(np.ceil((press_after + timing.delay + timing.duration + 0.3) / DT))
    end = 10.0 + steps * DT
    for k in range(1, steps + 1):
        joint_state(participant, 10.0 + k * DT)
    item = standard_instrument("ssq").items[0]
    asked = TrialStatus(1, 3, 4, "questionnaire", "reality", 0, administration="ssq_after_reality")
    say(participant, replace(asked, questionnaire="ssq", item=item.id, scale_low=item.low, scale_high=item.high))
    assert participant.answers == 1
    joint_state(participant, end + DT)  # not tracked any more
    sent = poses_sent(participant)
    times = np.array(stamps(sent["right_hand"]))
    assert times[0] == pytest.approx(10.0) and times[-1] == pytest.approx(end)
    assert np.diff(times) == pytest.approx(np.full(len(times) - 1, DT))
    moved = np.array([position(m) for m in sent["right_hand"]]) - SCENE.hand.top
    before = times < 10.0 + press_after + timing.delay
    assert np.abs(moved[before]).max() < JITTER
    farthest = np.linalg.norm(moved, axis=1).max()
    assert farthest == pytest.approx(withdrawal, abs=JITTER)  # the trial's withdrawal, as the runner will measure it
    toward_seat = (SCENE.seat - SCENE.hand.top)[:2] / np.linalg.norm((SCENE.seat - SCENE.hand.top)[:2])
    assert moved[-1, :2] == pytest.approx(withdrawal * toward_seat, abs=JITTER)
    assert all(len(sent[body]) == len(times) for body in BODIES)


def test_an_error_in_acting_on_a_status_ends_the_participant_at_once_with_the_trial_named() -> None:
    """Through the callback the client calls (as the endpoint's reader thread does): the fault injected for tests
    (--fault-trial 2) measures trial 2's distance as inf, and the model refuses it; the participant answers nothing,
    says why and which trial, is done, and acts on nothing more."""
    client = FakeClient()
    made = SimulatedParticipant(client, ROBOT, SCENE, draw_traits(Population(), 1, 3), 3, fault_trial=2)  # type: ignore[arg-type]
    made.attach()
    try:
        on_status = client.callbacks[STATUS_TOPIC]
        zeros = np.zeros(ROBOT.dof)
        client.callbacks[ROBOT.joint_states_topic](
            encode_joint_state(0, 1.0, ROBOT.joint_names, ROBOT.home, zeros, zeros)
        )
        first = TrialStatus(1, 1, 4, "distance", "vr", 1, "straight", 0.15, 0.15, motion_start=0.5)
        on_status(encode_message("std_msgs/String", data=status_to_json(first)))
        assert [topic for topic, _ in client.sent] == [DISTANCE_TOPIC] and not made.done.is_set()
        on_status(encode_message("std_msgs/String", data=status_to_json(replace(first, index=2))))
        assert made.done.is_set()
        assert made.failure == "trial 2 (distance): an actual distance must be >= 0 m, got inf"
        on_status(encode_message("std_msgs/String", data=status_to_json(replace(first, index=3))))
        assert [topic for topic, _ in client.sent] == [DISTANCE_TOPIC]  # nothing after its failure
    finally:
        made.close()
