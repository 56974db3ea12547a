"""The session's bag: which topics `rosbag record` takes (the links' and every /study topic) and its start, once it
records; the runner's node starts it before the session and stops it after (sim.study.run.node)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

from sim.processes import ManagedProcess, ProcessError, start_recorder, stop_recorder
from sim.study.run.protocol import (
    ANSWER_TOPIC,
    DISTANCE_TOPIC,
    GO_TOPIC,
    PAGE_CLOCK_TOPIC,
    POSE_TOPICS,
    PREFERENCE_TOPIC,
    STATUS_TOPIC,
    STOP_TOPIC,
)
from sim.study.run.tracking import CALIBRATION_TOPIC, TF_STATIC_TOPIC, TRACKING_TOPIC

__all__ = ["RECORDER_DRAIN", "recorder_topics", "record_session"]

# s of wall time between the session's end and stopping rosbag record: it reads its links on threads of its own, and
# SIGINT drops what is still in its sockets; the last answer, which the runner took a few ms before, was lost so
# beside other work (a loopback link delivers in well under a millisecond on a quiet machine)
RECORDER_DRAIN = 0.25


def recorder_topics(link_topics: Iterable[str]) -> list[str]:
    """The links' topics (the stream's command, joint states and /clock; a controller's), then the study's."""
    return [
        *link_topics,
        STATUS_TOPIC,
        GO_TOPIC,
        STOP_TOPIC,
        DISTANCE_TOPIC,
        PREFERENCE_TOPIC,
        ANSWER_TOPIC,
        *POSE_TOPICS.values(),
        PAGE_CLOCK_TOPIC,
        TRACKING_TOPIC,
        CALIBRATION_TOPIC,
        TF_STATIC_TOPIC,
    ]


def record_session(link_topics: list[str], bag: Path, node: str, logs: Path, sim_time: bool) -> ManagedProcess:
    """`rosbag record` of the session's topics into `bag` (in this process's ROS environment), once it records; or,
    under /use_sim_time (`sim_time`), once it has subscribed to them all: it then opens the bag only when /clock has
    moved past 0, and /clock is the runner's to publish (wait_for_partner waits for the recorder's links)."""
    topics = recorder_topics(link_topics)
    recorder = start_recorder(bag, topics, node, dict(os.environ), logs)
    try:
        recorder.wait_for_output(f"Subscribing to {topics[-1]}" if sim_time else "Recording to", timeout=30)
    except (ProcessError, TimeoutError):
        stop_recorder(recorder, bag)
        raise
    return recorder
