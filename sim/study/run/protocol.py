"""The trial protocol: what the runner and whoever answers it (a VR page, any Unity scene through the endpoint, a
simulated participant, the observer's keyboard) say to each other. The protocol itself is data, one table
(protocol.json beside this file) that the runner, the simulated participant and the VR page all read; this module
checks it and gives it to Python. Pure logic, but for reading that file once.

  /study/trial              std_msgs/String, latched, from the runner: the trial and its phase as JSON (TrialStatus)
  /study/go                 std_msgs/Empty, to the runner: start the approach (the observer, or the VR scene)
  /study/stop               std_msgs/Header, to the runner: the participant pressed stop. stamp = when, on ROS time
                            (the runner's /clock); a zero stamp means "when it arrives". frame_id = the stop source
                            (the table's stop_sources: vr_trigger, button, keyboard), logged with the press.
                            seq = the press's input delay (from the input's change to its stamp) in microseconds,
                            0 when not measured: std_msgs/Header has no other field for it, and its seq is otherwise
                            unused (rospy numbers only a message's header, not a Header sent as the message itself)
  /study/perceived_distance std_msgs/Float32, to the runner: test 1's answer in metres (the VR scene reports its two
                            controllers' distance; in reality the observer enters the measured one)
  /study/preference         std_msgs/String, to the runner: after a group of test 2, the preferred approach, as the
                            path's name or its place in the group (1, 2, 3)
  /study/answer             std_msgs/String, to the runner: a questionnaire item's answer as JSON (Answer:
                            administration, item, answer), naming the item so that a late answer to one item is never
                            taken for the next one's
  /study/pose/head          geometry_msgs/PoseStamped, to the runner, during every trial at the tracker's frame rate:
  /study/pose/left_hand     the headset's and the controllers' poses (the VR page), or a tracker's in reality; stamp =
  /study/pose/right_hand    when, on the runner's clock; frame_id = the scene's world frame ("world"). A body that is
                            not tracked in a frame sends nothing: a gap in tracking (sim.study.motion)
  /study/page_clock         std_msgs/String, to the runner, after each of a page's clock samples: its estimate of
                            ROS time minus its own clock as JSON (sim.study.run.clocks.PageClock: source, offset,
                            round_trip, applied, samples), by which the runner judges its stamps

Phases of a trial, in order: to_start (moving to the path's start), ready (accepts go), moving (accepts a stop),
at_rest (the motion has ended or stopped), distance (test 1: accepts the perceived distance), preference (after a
group of test 2: accepts the preference); then the next trial, and finally done. Between trials, where the plan
places a questionnaire, the phase questionnaire asks one item at a time (accepts its answer); its status carries
the item (text, scale, labels, k of n). Each phase accepts at most one input; what comes in another phase is not
kept. A phase's panel lines are templates: {name} is the status's field of that name, {choice} / {path} and
{answer} / {label} what the answerer has chosen so far.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

from sim.study.run.errors import RunError

__all__ = [
    "PROTOCOL_FILE",
    "INPUTS",
    "Phase",
    "Protocol",
    "PROTOCOL",
    "load_protocol",
    "STATUS_TOPIC",
    "GO_TOPIC",
    "STOP_TOPIC",
    "DISTANCE_TOPIC",
    "PREFERENCE_TOPIC",
    "ANSWER_TOPIC",
    "BODIES",
    "POSE_TOPICS",
    "POSE_TYPE",
    "POSE_FRAME",
    "TRACKING_GAP",
    "PAGE_CLOCK_TOPIC",
    "TOPIC_TYPES",
    "PHASES",
    "MAX_PERCEIVED_DISTANCE",
    "TrialStatus",
    "status_to_json",
    "status_from_json",
    "MAX_SEQ",
    "input_delay_seq",
    "input_delay_from_seq",
    "checked_distance",
    "chosen_path",
    "Answer",
    "answer_to_json",
    "answer_from_json",
    "checked_answer",
    "item_prompt",
    "ObserverInput",
    "observer_input",
]

PROTOCOL_FILE = Path(__file__).resolve().parent / "protocol.json"
INPUTS = ("go", "stop", "distance", "preference", "answer")  # the table's inputs, each read in its own way
# the message type each input must have: the runner subscribes with these, and the participants encode them
INPUT_TYPES = {
    "go": "std_msgs/Empty",
    "stop": "std_msgs/Header",
    "distance": "std_msgs/Float32",
    "preference": "std_msgs/String",
    "answer": "std_msgs/String",
}
BODIES = ("head", "left_hand", "right_hand")  # the tracked bodies, each a PoseStamped topic of its own
POSE_TYPE = "geometry_msgs/PoseStamped"


@dataclass(frozen=True)
class Phase:
    name: str
    accepts: str | None  # the one input that counts in this phase (one of INPUTS), or None
    meaning: str


@dataclass(frozen=True)
class Protocol:
    """The table, checked: topics as (name, type), phases in order, stop sources by name with the condition each
    belongs to, the limits; `data` is the table as read (what the VR page gets)."""

    status: tuple[str, str]
    inputs: dict[str, tuple[str, str]]
    phases: tuple[Phase, ...]
    stop_sources: dict[str, str | None]
    max_perceived_distance: float  # m: an answer beyond this is a typing or tracking error, not a judgement
    stamp_window: tuple[float, float]  # s around motion_start: a press stamped outside it is on another clock
    poses: dict[str, tuple[str, str]]  # by body (BODIES): its pose topic and type
    pose_frame: str  # the frame_id every pose must have: the scene's world frame
    tracking_gap: float  # s: a body's poses further apart than this leave a gap in its tracking
    data: dict[str, Any]

    def phase(self, name: str) -> Phase:
        for phase in self.phases:
            if phase.name == name:
                return phase
        raise RunError(f"unknown trial phase {name!r}; known: {', '.join(p.name for p in self.phases)}")

    def accepts(self, phase: str) -> str | None:
        """The input that counts in `phase`, if any."""
        return self.phase(phase).accepts

    def stop_source(self, condition: str) -> str:
        """The stop source of a participant's own press in `condition` (vr or reality)."""
        for name, belongs in self.stop_sources.items():
            if belongs == condition:
                return name
        raise RunError(f"no stop source for the condition {condition!r}")


def _topic(entry: Any, where: str) -> tuple[str, str]:
    if not (isinstance(entry, dict) and isinstance(entry.get("topic"), str) and isinstance(entry.get("type"), str)):
        raise RunError(f"{where}: needs a topic and a type, got {entry!r}")
    return entry["topic"], entry["type"]


def load_protocol(path: Path = PROTOCOL_FILE) -> Protocol:
    """The protocol table in `path`, checked; RunError names what is wrong."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise RunError(f"cannot read the trial protocol {path}: {error}") from None
    try:
        inputs = {name: _topic(data["inputs"][name], f"input {name}") for name in INPUTS}
        if sorted(data["inputs"]) != sorted(INPUTS):
            raise RunError(f"the inputs must be exactly {', '.join(INPUTS)}, got {', '.join(data['inputs'])}")
        for name, (_, kind) in inputs.items():
            if kind != INPUT_TYPES[name]:
                raise RunError(f"input {name} must be a {INPUT_TYPES[name]}, got {kind!r}")
        phases = tuple(Phase(entry["name"], entry["accepts"], entry["meaning"]) for entry in data["phases"])
        for phase, entry in zip(phases, data["phases"]):
            if phase.accepts is not None and phase.accepts not in INPUTS:
                raise RunError(f"phase {phase.name} accepts {phase.accepts!r}, which is no input")
            if not isinstance(entry.get("panel", {}).get("lines"), list):
                raise RunError(f"phase {phase.name} says nothing on the VR panel (panel.lines)")
        stop_sources = {name: entry["condition"] for name, entry in data["stop_sources"].items()}
        low, high = (float(value) for value in data["limits"]["stamp_window_s"])
        poses = {name: _topic(data["poses"]["bodies"][name], f"pose {name}") for name in BODIES}
        if sorted(data["poses"]["bodies"]) != sorted(BODIES):
            raise RunError(f"the poses must be exactly {', '.join(BODIES)}, got {', '.join(data['poses']['bodies'])}")
        for name, (_, kind) in poses.items():
            if kind != POSE_TYPE:
                raise RunError(f"pose {name} must be a {POSE_TYPE}, got {kind!r}")
        tracking_gap = float(data["limits"]["tracking_gap_s"])
        if not (math.isfinite(tracking_gap) and tracking_gap > 0.0):
            raise RunError(f"the tracking gap must be > 0 s, got {tracking_gap!r}")
        protocol = Protocol(
            status=_topic(data["status"], "status"),
            inputs=inputs,
            phases=phases,
            stop_sources=stop_sources,
            max_perceived_distance=float(data["limits"]["max_perceived_distance_m"]),
            stamp_window=(low, high),
            poses=poses,
            pose_frame=str(data["poses"]["frame_id"]),
            tracking_gap=tracking_gap,
            data=data,
        )
    except (KeyError, TypeError, ValueError) as error:
        raise RunError(f"the trial protocol {path} is malformed: {error!r}") from None
    names = [phase.name for phase in phases]
    if len(set(names)) != len(names) or names[-1] != "done":
        raise RunError(f"the phases must have unique names and end with done, got {', '.join(names)}")
    return protocol


PROTOCOL = load_protocol()
STATUS_TOPIC = PROTOCOL.status[0]
GO_TOPIC, STOP_TOPIC, DISTANCE_TOPIC, PREFERENCE_TOPIC, ANSWER_TOPIC = (PROTOCOL.inputs[name][0] for name in INPUTS)
POSE_TOPICS = {body: topic for body, (topic, _) in PROTOCOL.poses.items()}
POSE_FRAME = PROTOCOL.pose_frame
TRACKING_GAP = PROTOCOL.tracking_gap
PAGE_CLOCK_TOPIC = "/study/page_clock"  # std_msgs/String: a page's clock (sim.study.run.clocks)
TOPIC_TYPES = {topic: kind for topic, kind in (PROTOCOL.status, *PROTOCOL.inputs.values(), *PROTOCOL.poses.values())}
PHASES = tuple(phase.name for phase in PROTOCOL.phases)
MAX_PERCEIVED_DISTANCE = PROTOCOL.max_perceived_distance


@dataclass(frozen=True)
class TrialStatus:
    participant: int
    index: int  # 1-based; 0 once the session is done
    total: int
    phase: str
    condition: str = ""
    test: int = 0
    path: str = ""
    standoff: float = math.nan  # m (test 2: ON_TOP)
    peak_speed: float = math.nan  # m/s
    speed_set: str = ""
    group: int = 0
    # s of ROS time when the approach started (phase moving: when the runner asked for it; at_rest and later: the
    # arm's own start as its link reports it, the row's motion_start, later by the start lead on a real arm)
    motion_start: float = math.nan
    group_paths: tuple[str, ...] = ()  # phase preference: the group's paths in the order they were run
    # phase questionnaire: the item asked, with all an answerer needs (condition: the block it is asked around)
    administration: str = ""  # e.g. ssq_after_vr
    questionnaire: str = ""  # the instrument's name, e.g. ssq
    item: str = ""  # the item's id
    item_text: str = ""
    item_number: int = 0  # k of item_count, 1-based
    item_count: int = 0
    scale_low: int = 0  # the lowest answer
    scale_high: int = 0  # the highest answer
    scale_labels: tuple[str, ...] = ()  # one per answer from scale_low to scale_high; "" where the scale has none


def status_to_json(status: TrialStatus) -> str:
    data = asdict(status)
    data["group_paths"] = list(status.group_paths)
    data["scale_labels"] = list(status.scale_labels)
    # NaN is not JSON: absent values are null, which Unity's JsonUtility and every JSON parser take
    return json.dumps(
        {key: (None if isinstance(value, float) and math.isnan(value) else value) for key, value in data.items()}
    )


def _json_fields(text: str, kind: type, what: str) -> dict[str, Any]:
    """`text` as a JSON object with exactly the fields of the dataclass `kind`; RunError naming `what` if not."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise RunError(f"{what} is not JSON: {error}") from None
    names = [field.name for field in fields(kind)]
    if not isinstance(data, dict) or sorted(data) != sorted(names):
        raise RunError(f"{what} must have exactly {', '.join(names)}, got {text[:200]!r}")
    return data


def status_from_json(text: str) -> TrialStatus:
    data = _json_fields(text, TrialStatus, "a trial status")
    PROTOCOL.phase(data["phase"])  # RunError when it is none of the table's
    for key in ("standoff", "peak_speed", "motion_start"):
        data[key] = math.nan if data[key] is None else float(data[key])
    data["group_paths"] = tuple(data["group_paths"])
    data["scale_labels"] = tuple(data["scale_labels"])
    return TrialStatus(**data)


MAX_SEQ = 2**32 - 1  # a Header's seq is a uint32: some 71 minutes in microseconds
_SEQ_UNIT_S = 1e-6


def input_delay_seq(delay_s: float) -> int:
    """A stop's input delay (s) as its Header's seq: whole microseconds, at least 1 (0 is "not measured"); a delay
    that is not a number >= 0 was not measured."""
    if not (math.isfinite(delay_s) and delay_s >= 0.0):
        return 0
    return int(min(max(round(delay_s / _SEQ_UNIT_S), 1), MAX_SEQ))


def input_delay_from_seq(seq: int) -> float:
    """A stop's input delay (s) from its Header's seq; NaN when it was not measured (0)."""
    if not 0 <= seq <= MAX_SEQ:
        raise RunError(f"a Header's seq must be 0..{MAX_SEQ}, got {seq!r}")
    return math.nan if seq == 0 else seq * _SEQ_UNIT_S


def checked_distance(value: float) -> float:
    """A perceived distance as answered (m); RunError when it cannot be one."""
    if not (math.isfinite(value) and 0.0 <= value <= MAX_PERCEIVED_DISTANCE):
        raise RunError(f"a perceived distance must be 0..{MAX_PERCEIVED_DISTANCE:g} m, got {value!r}")
    return float(value)


def chosen_path(answer: str, group_paths: tuple[str, ...]) -> str:
    """The path a preference answer names: a path of the group, or its place in the group (1-based)."""
    text = answer.strip()
    if text in group_paths:
        return text
    if text.isdigit() and 1 <= int(text) <= len(group_paths):
        return group_paths[int(text) - 1]
    raise RunError(f"a preference must be one of {', '.join(group_paths)} or 1..{len(group_paths)}, got {answer!r}")


@dataclass(frozen=True)
class Answer:
    """A questionnaire item's answer, as it comes on the answer topic."""

    administration: str
    item: str
    answer: int


def answer_to_json(answer: Answer) -> str:
    return json.dumps(asdict(answer))


def answer_from_json(text: str) -> Answer:
    """An answer as sent; RunError when it is not one (the scale is checked against the item asked: checked_answer)."""
    data = _json_fields(text, Answer, "an answer")
    value = data["answer"]
    if not (isinstance(data["administration"], str) and isinstance(data["item"], str)):
        raise RunError(f"an answer's administration and item must be texts, got {text[:200]!r}")
    # a scale's points are whole numbers: 2.0 is a client's rounding, 2.5 is no point of any scale
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if not (isinstance(value, int) and not isinstance(value, bool)):
        raise RunError(f"an answer must be a whole number, got {data['answer']!r}")
    return Answer(data["administration"], data["item"], value)


def checked_answer(answer: Answer, status: TrialStatus) -> int:
    """The answer to the item `status` asks; RunError when it answers another item or is off the item's scale."""
    if status.phase != "questionnaire":
        raise RunError(f"no questionnaire item is asked in phase {status.phase}, got an answer to {answer.item}")
    if (answer.administration, answer.item) != (status.administration, status.item):
        raise RunError(
            f"an answer to {answer.administration} item {answer.item!r} while {status.administration} item "
            f"{status.item!r} is asked"
        )
    if not status.scale_low <= answer.answer <= status.scale_high:
        raise RunError(
            f"{status.administration} item {status.item}: the answer {answer.answer} is not one of "
            f"{status.scale_low}..{status.scale_high}"
        )
    return answer.answer


def item_prompt(status: TrialStatus) -> str:
    """What the observer reads at the terminal while an item is asked: the item and its scale's labelled
    answers."""
    points = [
        f"{answer} {label}" if label else str(answer)
        for answer, label in zip(range(status.scale_low, status.scale_high + 1), status.scale_labels)
    ]
    return (
        f"{status.administration}, item {status.item_number} of {status.item_count} ({status.item}): "
        f"{status.item_text} [{', '.join(points)}]?"
    )


@dataclass(frozen=True)
class ObserverInput:
    kind: str  # "go" | "stop" | "distance" | "preference" | "answer" | "unknown"
    distance: float = math.nan  # m
    text: str = ""  # the preference as typed, or why the line means nothing now
    answer: int = 0  # a questionnaire item's answer


def _metres(text: str) -> float:
    """ "0.12", "0.12 m" or "12 cm" in metres; ValueError otherwise."""
    for unit, scale in (("cm", 0.01), ("m", 1.0)):
        if text.endswith(unit):
            return float(text[: -len(unit)].strip()) * scale
    return float(text)


_WHOLE = re.compile(r"-?[0-9]+\Z")


def observer_input(line: str, phase: str) -> ObserverInput:
    """A line the observer typed at the runner's terminal (--keyboard), read in the trial's phase: Enter alone =
    go, "s" = stop; while a distance is asked, a distance ("0.12" in metres, "0.12 m" or "12 cm"); while a
    preference is asked, the path's name or its place in the group; while a questionnaire's item is asked, the
    answer as a whole number (checked against the item's scale by the runner)."""
    text = line.strip()
    if not text:
        return ObserverInput("go")
    if text.lower() in ("s", "stop"):
        return ObserverInput("stop")
    accepted = PROTOCOL.accepts(phase) if phase in PHASES else None
    if accepted == "distance":
        try:
            return ObserverInput("distance", _metres(text.lower()))
        except ValueError:
            return ObserverInput("unknown", text=f"{text!r} is not a distance (e.g. 0.12, 0.12 m or 12 cm)")
    if accepted == "preference":
        return ObserverInput("preference", text=text)
    if accepted == "answer":
        if _WHOLE.match(text):
            return ObserverInput("answer", answer=int(text))
        return ObserverInput("unknown", text=f"{text!r} is not an answer (a whole number on the item's scale)")
    return ObserverInput("unknown", text=f"{text!r} means nothing in phase {phase} (Enter = go, s = stop)")
