"""A simulated participant: a TCP client of the endpoint without rospy, as a Unity scene would be
(`python -m sim.study participant --port P --participant N --seed S`).

It follows the runner's `/study/trial` and the robot's joint states, and acts by its traits (sim.study.
participants.model), which stand for both the participant and the observer, on what each phase accepts (the
protocol's table, sim.study.run.protocol):
  go          test 2: draws where this trial's press is to land (its comfort distance) and finds how long after
              the start the planned approach gets there; then says go (`/study/go`), as the observer would;
  stop        test 2: presses stop (`/study/stop`) at once, stamped when the press is to land: it anticipates the
              robot, as people do, and the runner applies a press at its stamp. It reports a modelled input delay
              (the model's input_delay) in the Header's seq, as the pages do; its arrival delay is negative, as it
              sends the press ahead of its stamp.
  distance    test 1: reports its perceived distance of the robot at rest (`/study/perceived_distance`);
  preference  names its preferred path of the group (`/study/preference`);
  answer      answers the questionnaire item asked (`/study/answer`), by its traits: the SSQ's symptoms as they are
              before or after it has been in VR (any trial of the VR block), the IPQ's and the lab's own items around
              its own levels;
  done        (the last phase; for its participant number) ends.

A failure of its own (an error in acting on a status or a joint state, or a status it cannot read) ends it at once:
`failure` says what, at which trial, and `done` is set, so that the command exits with that line and `simulate`,
which watches every part of a session, ends the session there rather than the runner waiting out its response
timeout for an answer that never comes. (The endpoint client only logs an error in a callback.) `fault_trial`, for
tests only (`participant --fault-trial N`), measures the robot's distance at trial N as inf, as a distance measure
beyond its range once did, so that tests see such a failure end a session.

Its tracked body (the protocol's pose topics, one geometry_msgs/PoseStamped per body in the world frame), as
sim.study.participants.body's body_poses has it: from a trial's `moving` status until a status of another trial, a
questionnaire's or done, on each joint state stamped t it publishes every body's pose on the joint states' grid (dt)
from after the last one it published up to t itself: a joint state it missed leaves no gap, and the runner, which waits
at an approach's end for a pose of every tracked body stamped at its end, always has one. In test 2 the hand withdraws
from the press by this trial's withdrawal (the model's trial_withdrawal and trial_withdrawal_timing, drawn on go: at
once, or late and slow); in test 1 it stays.

Why at once, and planned before go: a lockstep runs some 15 times faster than real time on a busy machine, so
whatever the participant does after the approach starts races the robot. Pressing on the joint state one human
reaction time ahead (some 15 ms of wall time there) came late in three studies of seven; planning on `moving` (5 ms,
sometimes 140 ms on a starved CPU) still did now and then. While the runner waits for go nothing moves, and in
lockstep it holds the clock at a test-2 approach's start until the press is in.
"""

from __future__ import annotations

import math
import threading
from typing import Any, Callable

import numpy as np

from bridge.client import TcpClient
from sim.errors import SimError
from sim.robots import RobotSpec
from sim.study.design.feasibility import Approaches
from sim.study.design.scene import Scene
from sim.study.errors import StudyError
from sim.study.participants.body import body_layout, body_poses
from sim.study.participants.model import (
    WITHDRAWAL_DURATION,
    Traits,
    WithdrawalTiming,
    arrival_time,
    comfort_at_press,
    input_delay,
    perceived_distance,
    preferred_path,
    questionnaire_answer,
    trial_withdrawal,
    trial_withdrawal_timing,
)
from sim.study.questionnaires.instruments import STANDARD, standard_instrument
from sim.study.run.protocol import (
    ANSWER_TOPIC,
    DISTANCE_TOPIC,
    GO_TOPIC,
    PHASES,
    POSE_FRAME,
    POSE_TOPICS,
    POSE_TYPE,
    PREFERENCE_TOPIC,
    PROTOCOL,
    STATUS_TOPIC,
    STOP_TOPIC,
    TOPIC_TYPES,
    Answer,
    TrialStatus,
    answer_to_json,
    input_delay_seq,
    status_from_json,
)
from sim.wire.contract import STEP_S
from sim.wire.rosmsgs import (
    JOINT_STATE,
    decode_joint_state,
    deserialize,
    encode_message,
    encode_pose_stamped,
    time_msg,
)

__all__ = ["POSE_QUEUE", "SimulatedParticipant"]

# The endpoint's queue for each pose topic: a joint state missed is made up for by a burst of poses at once
POSE_QUEUE = 100


def _encode(topic: str, **fields: Any) -> bytes:
    return encode_message(TOPIC_TYPES[topic], **fields)


class SimulatedParticipant:
    def __init__(
        self,
        client: TcpClient,
        robot: RobotSpec,
        scene: Scene,
        traits: Traits,
        seed: int,
        dt: float = STEP_S,
        fault_trial: int | None = None,
    ) -> None:
        self.client, self.robot, self.scene, self.traits, self.dt = client, robot, scene, traits, dt
        self.fault_trial = fault_trial  # tests only: the trial whose distance is measured as inf (module doc)
        self.rng = np.random.default_rng([seed, traits.participant, 2])  # the judgements' noise
        # the questionnaires' answers: a stream apart, so that the judgements are those of a study without them
        self.answer_rng = np.random.default_rng([seed, traits.participant, 4])
        self.delay_rng = np.random.default_rng([seed, traits.participant, 5])  # the input delays: apart, likewise
        self.withdrawal_rng = np.random.default_rng([seed, traits.participant, 7])  # each trial's withdrawal: apart
        self.jitter_rng = np.random.default_rng([seed, traits.participant, 8])  # the tracking's jitter: apart
        self.timing_rng = np.random.default_rng([seed, traits.participant, 9])  # late or at once: apart, likewise
        self.layout = body_layout(scene)
        self.poses = 0  # samples of the tracked body published, each one pose per body
        self.been_in_vr = False  # whether any trial of the VR block has been run: the SSQ's symptoms rise after
        self.answers = 0
        self.done = threading.Event()
        self.presses = 0
        self.failure = ""  # what ended it before the session's end; "": nothing
        self.approaches = Approaches(robot, scene, dt)  # the runner's plans, and the robot's distance to the hand
        self._status: TrialStatus | None = None
        self._press_after: float | None = None  # test 2: s after the approach starts at which this trial's press lands
        self._latest: tuple[float, np.ndarray] | None = None
        self._tracked: TrialStatus | None = None  # the trial whose body is published: from its moving status on
        self._withdrawal = 0.0  # m: this trial's withdrawal after the press (test 2)
        self._timing = WithdrawalTiming(0.0, WITHDRAWAL_DURATION)  # when it starts after the press, how long it takes
        self._press_time = math.nan  # s of ROS time: this trial's press; NaN: none, the hand stays
        self._last_pose = math.nan  # s of ROS time: the last sample's stamp published in the tracked trial

    def attach(self) -> None:
        for topic in (GO_TOPIC, STOP_TOPIC, DISTANCE_TOPIC, PREFERENCE_TOPIC, ANSWER_TOPIC):
            self.client.register_publisher(topic, TOPIC_TYPES[topic])
        for topic in POSE_TOPICS.values():
            self.client.register_publisher(topic, POSE_TYPE, queue_size=POSE_QUEUE)
        self.client.subscribe(self.robot.joint_states_topic, JOINT_STATE, self._guarded(self._on_joint_state))
        self.client.subscribe(STATUS_TOPIC, TOPIC_TYPES[STATUS_TOPIC], self._guarded(self._on_status))

    def _guarded(self, handler: Callable[[bytes], None]) -> Callable[[bytes], None]:
        """`handler` as the client calls it: any error in it is this participant's failure (module doc)."""

        def guarded(payload: bytes) -> None:
            if self.failure:
                return  # failed already: it acts no more
            try:
                handler(payload)
            except Exception as error:  # whatever it is, it ends the participant, named
                self.fail(error if isinstance(error, SimError) else f"{type(error).__name__}: {error}")

        return guarded

    def fail(self, problem: object) -> None:
        """End at once with `problem`, named with the trial and phase it came in."""
        status = self._status
        where = "" if status is None else f"trial {status.index} ({status.phase}): "
        self.failure = self.failure or f"{where}{problem}"
        self.done.set()

    def hand_distance(self, positions: np.ndarray) -> float:
        if self._status is not None and self._status.index == self.fault_trial:
            return math.inf  # the fault injected for tests (module doc)
        return self.approaches.hand_distance(positions)

    def close(self) -> None:
        self.approaches.close()

    def _on_joint_state(self, payload: bytes) -> None:
        sample = decode_joint_state(payload, self.robot.joint_names)
        self._latest = (sample.stamp_s, sample.positions)
        if self._tracked is not None:
            self._publish_poses(sample.stamp_s)

    def _start_tracking(self, status: TrialStatus) -> None:
        if self._tracked is not None and self._tracked.index == status.index:
            return  # this trial's moving status again (latched, sent anew): its poses go on where they were
        self._tracked = status
        self._last_pose = status.motion_start - self.dt  # so that the first sample is the motion's start
        if self._latest is not None:  # joint states that came before this status
            self._publish_poses(self._latest[0])

    def _publish_poses(self, t: float) -> None:
        """Every body's pose on the grid of dt back from `t` (s of ROS time), from after the last stamp published up
        to `t` itself."""
        if self._tracked is None or t < self._tracked.motion_start - 1e-6 or not t > self._last_pose + 1e-9:
            return  # before the motion, or covered already
        count = max(round((t - self._last_pose) / self.dt), 1)  # its earliest lies >= dt/2 after the last one
        for k in range(count - 1, -1, -1):
            stamp = t - k * self.dt
            poses = body_poses(self.layout, stamp, self._withdrawal, self._press_time, self.jitter_rng, self._timing)
            for body, (position, orientation) in poses.items():
                self.client.publish(POSE_TOPICS[body], encode_pose_stamped(stamp, POSE_FRAME, position, orientation))
        self._last_pose = t
        self.poses += count

    def _plan_press(self, status: TrialStatus) -> float:
        """How long after the start (s) the planned approach reaches this trial's comfort distance."""
        planned = self.approaches.plan((status.path, status.standoff, status.peak_speed))
        comfort = comfort_at_press(self.traits, status.condition, self.rng)
        return arrival_time(planned.path.times, planned.distances, comfort)

    def _press(self, status: TrialStatus, after: float) -> None:
        source = PROTOCOL.stop_source(status.condition)
        stamp = time_msg(status.motion_start + after)
        self.presses += 1
        seq = input_delay_seq(input_delay(status.condition, self.delay_rng))
        self.client.publish(STOP_TOPIC, _encode(STOP_TOPIC, seq=seq, stamp=stamp, frame_id=source))

    def _on_status(self, payload: bytes) -> None:
        message: Any = deserialize(payload, TOPIC_TYPES[STATUS_TOPIC])
        status = status_from_json(message.data)  # a status it cannot read: its failure
        if status.participant != self.traits.participant:
            return  # another session's (a latched status from before)
        self._status = status
        if self._tracked is not None and (status.index != self._tracked.index or status.test == 0):
            self._tracked = None  # another trial's status, a questionnaire's or done: this trial's tracking ends
        if status.condition == "vr" and status.test > 0:  # a trial's status (a questionnaire's has test 0)
            self.been_in_vr = True
        accepted = PROTOCOL.accepts(status.phase)
        if accepted == "go":
            self._press_after = None
            self._withdrawal, self._press_time = 0.0, math.nan
            if status.test == 2:
                self._withdrawal = trial_withdrawal(self.traits, status.condition, self.withdrawal_rng)
                self._timing = trial_withdrawal_timing(self.traits, self.timing_rng)
                self._press_after = self._plan_press(status)
            self.client.publish(GO_TOPIC, _encode(GO_TOPIC))
        elif accepted == "stop":  # the approach has started
            if self._press_after is not None:
                self._press_time = status.motion_start + self._press_after
                self._press(status, self._press_after)
                self._press_after = None
            self._start_tracking(status)
        elif accepted == "distance":
            if self._latest is None:
                raise StudyError("asked for a distance before any joint state")
            actual = self.hand_distance(self._latest[1])
            answer = perceived_distance(self.traits, status.condition, actual, self.rng)
            self.client.publish(DISTANCE_TOPIC, _encode(DISTANCE_TOPIC, data=answer))
        elif accepted == "preference":
            choice = preferred_path(self.traits, status.group_paths)
            self.client.publish(PREFERENCE_TOPIC, _encode(PREFERENCE_TOPIC, data=choice))
        elif accepted == "answer":
            self._answer(status)
        elif status.phase == PHASES[-1]:  # the session is over
            self.done.set()

    def _answer(self, status: TrialStatus) -> None:
        # a standard instrument's reversed items are in its file; the lab's own items are never reversed
        reversed_ = (
            status.questionnaire in STANDARD and standard_instrument(status.questionnaire).item(status.item).reversed
        )
        value = questionnaire_answer(
            self.traits,
            status.questionnaire,
            status.scale_low,
            status.scale_high,
            reversed_,
            self.been_in_vr,
            self.answer_rng,
        )
        answer = Answer(status.administration, status.item, value)
        self.answers += 1
        self.client.publish(ANSWER_TOPIC, _encode(ANSWER_TOPIC, data=answer_to_json(answer)))

    @property
    def traits_note(self) -> str:
        ratio, comfort = self.traits.distance_ratio, self.traits.comfort_distance
        withdrawal = self.traits.withdrawal
        return (
            f"comfort {comfort['reality']:.3f} m (VR {comfort['vr']:.3f} m), "
            f"withdrawal {withdrawal['reality']:.3f} m (VR {withdrawal['vr']:.3f} m), "
            f"perceived / actual {ratio['reality']:.2f} (VR {ratio['vr']:.2f}), SSQ symptom rating "
            f"{self.traits.symptoms['before_vr']:.2f} (after VR {self.traits.symptoms['after_vr']:.2f})"
        )
