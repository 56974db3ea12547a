"""The runner's side of the trial protocol's dialogue with the participant and the observer (sim.study.run.protocol):
the status it publishes on STATUS_TOPIC (latched), prompted at the observer's terminal with --keyboard, and the
inputs that come back (go, presses, distances, preferences, questionnaire answers, on their topics or typed at the
keyboard), kept by phase (sim.study.run.inputs) until the runner takes them; the waits for them, and for their
publishers to be linked. A press's arrival is taken on the current link's clock, first thing (its arrival delay).
While the runner waits for an input in real time, the current link holds the robot at its target; in lockstep its
clock stands still."""

from __future__ import annotations

import sys
import threading
import time
from typing import Any, Callable, Iterable

from sim.control.controller_node import ControllerError
from sim.study.run.console import say
from sim.study.run.inputs import Inputs
from sim.study.run.links.base import RobotLink
from sim.study.run.protocol import (
    ANSWER_TOPIC,
    DISTANCE_TOPIC,
    GO_TOPIC,
    POSE_TOPICS,
    PREFERENCE_TOPIC,
    PROTOCOL,
    STOP_TOPIC,
    Answer,
    TrialStatus,
    input_delay_from_seq,
    item_prompt,
    observer_input,
    status_to_json,
)

__all__ = ["Dialogue"]

# what the observer is told at the terminal (--keyboard), by the input the phase accepts
_PROMPTS = {
    "go": "Enter to start the approach",
    "stop": "s + Enter to stop",
    "distance": "the perceived distance (0.12, 0.12 m or 12 cm)?",
    "preference": "preferred approach: {paths}?",
}


class Dialogue:
    """The status out on `status_pub`, the participant's and the observer's inputs in, kept in `inputs`. `link` gives
    the current condition's link: its clock stamps a press's arrival, and it holds the robot while an input is waited
    for in real time."""

    def __init__(
        self,
        status_pub: Any,
        inputs: Inputs,
        link: Callable[[], RobotLink],
        keyboard: bool,
        response_timeout: float,
        stop: threading.Event,
    ) -> None:
        import rospy
        from std_msgs.msg import Empty, Float32, Header, String

        self.rospy = rospy
        self.status_pub, self.inputs, self._link, self.stop = status_pub, inputs, link, stop
        self.keyboard = keyboard  # the observer types at this terminal: go, stop, distances, preferences, answers
        self.response_timeout = response_timeout  # s: the longest wait for go or an answer
        self._string_type = String
        self.phase = ""  # of the last status published
        self.asked: TrialStatus | None = None  # the last status published: the item asked, in phase questionnaire
        self._subscribers = [
            self.rospy.Subscriber(GO_TOPIC, Empty, lambda _: self.inputs.go()),
            self.rospy.Subscriber(STOP_TOPIC, Header, self._on_press, tcp_nodelay=True),
            self.rospy.Subscriber(DISTANCE_TOPIC, Float32, lambda message: self.inputs.distance(message.data)),
            self.rospy.Subscriber(PREFERENCE_TOPIC, String, lambda message: self.inputs.preference(message.data)),
            self.rospy.Subscriber(ANSWER_TOPIC, String, lambda message: self.inputs.answer_json(message.data)),
        ]

    def _on_press(self, message: Any) -> None:
        arrival = self._link().now()  # first: the press's latency ends here
        self.inputs.press(
            message.stamp.to_sec(), message.frame_id or "unnamed", input_delay_from_seq(message.seq), arrival
        )

    def wait_for_inputs(self, timeout: float, recorder: str | None) -> None:
        """Wait (at most `timeout` s) until every node that publishes an input or pose topic writes it to this runner
        and to the recorder: rospy keeps nothing for a subscriber whose link is not up yet, and a simulated
        participant answers the first questionnaire's first item at once (its answer was lost, and the session hung
        until the response timeout). Nodes that come later (a VR page opened after the start) link as they come."""
        import rosgraph

        from sim.processes import writes_to

        me = self.rospy.get_name()
        readers = [me] + ([recorder if recorder.startswith("/") else "/" + recorder] if recorder else [])
        topics = {GO_TOPIC, STOP_TOPIC, DISTANCE_TOPIC, PREFERENCE_TOPIC, ANSWER_TOPIC, *POSE_TOPICS.values()}
        master = rosgraph.Master(me)
        deadline = time.monotonic() + timeout
        while not self.stop.is_set():
            publishers, _, _ = master.getSystemState()
            missing = [
                f"{topic}: {node} -> {reader}"
                for topic, nodes in publishers
                if topic in topics
                for node in nodes
                if node != me
                for reader in readers
                if not writes_to(master.lookupNode(node), topic, reader)
            ]
            if not missing:
                return
            if time.monotonic() > deadline:
                raise ControllerError(f"the participant's topics are not linked after {timeout:g} s: {missing}")
            self.stop.wait(0.05)
        raise ControllerError("interrupted while waiting for the participant's topics")

    def publish_status(self, status: TrialStatus) -> None:
        """Enter the status's phase (what it accepts from now on), then say so."""
        self.inputs.enter(status.phase)
        self.phase, self.asked = status.phase, status
        self.say(status)

    def say(self, status: TrialStatus) -> None:
        """Publish the status (and prompt the observer) without entering its phase again: said again, it keeps what
        has come in since it was entered."""
        self.status_pub.publish(self._string_type(data=status_to_json(status)))
        accepted = PROTOCOL.accepts(status.phase)
        if self.keyboard and accepted == "answer":
            print(item_prompt(status), file=sys.stderr, flush=True)
        elif self.keyboard and accepted is not None:
            print(
                f"trial {status.index}/{status.total} ({status.condition}, test {status.test}, {status.path}): "
                + _PROMPTS[accepted].format(
                    paths=", ".join(f"{k} {p}" for k, p in enumerate(status.group_paths, start=1))
                ),
                file=sys.stderr,
                flush=True,
            )

    def read_keyboard(self, lines: Iterable[str]) -> None:
        """The observer's lines (sim.study.run.protocol.observer_input), read in the phase they come in."""
        for line in lines:
            typed = observer_input(line, self.phase)
            if typed.kind == "go":
                self.inputs.go()
            elif typed.kind == "stop":
                self.inputs.press(0.0, "keyboard")
            elif typed.kind == "distance":
                self.inputs.distance(typed.distance)
            elif typed.kind == "preference":
                self.inputs.preference(typed.text)
            elif typed.kind == "answer" and self.asked is not None:
                # the observer answers the item asked now: the typed number names no item of its own
                self.inputs.answer(Answer(self.asked.administration, self.asked.item, typed.answer))
            else:
                say(typed.text)

    def wait_for_input(self, what: str) -> Any:
        """Go or an answer, waited for at most --response-timeout s. In real time the robot holds its target
        meanwhile (the controller keeps streaming); in lockstep the clock stands still."""
        if not self._link().realtime:
            return self.inputs.wait(what, self.response_timeout, self.stop)
        deadline = time.monotonic() + self.response_timeout
        while time.monotonic() < deadline and not self.stop.is_set():
            value = self.inputs.wait(what, 0.0, self.stop)
            if value is not None:
                return value
            self._link().idle()
        return None

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()
