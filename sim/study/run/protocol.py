"""The study's ROS interface: what the runner and a VR client (any Unity scene, through the endpoint) or the
observer's tools say to each other. Pure logic: names, types, and the trial status as JSON.

  /study/trial              std_msgs/String, latched, from the runner: the trial and its phase as JSON (TrialStatus)
  /study/go                 std_msgs/Empty, to the runner: start the approach (the observer, or the VR scene)
  /study/stop               std_msgs/Header, to the runner: the participant pressed stop. stamp = when, on ROS time
                            (the runner's /clock); a zero stamp means "when it arrives". frame_id = where it came
                            from (e.g. "vr_trigger", "button", "keyboard"), logged with the press
  /study/perceived_distance std_msgs/Float32, to the runner: test 1's answer in metres (the VR scene reports its two
                            controllers' distance; in reality the observer enters the measured one)
  /study/preference         std_msgs/String, to the runner: after a group of test 2, the preferred approach, as the
                            path's name or its place in the group (1, 2, 3)

Phases of a trial, in order: to_start (moving to the path's start), ready (waiting for go), moving (presses count),
at_rest (the motion has ended or stopped), distance (test 1: waiting for the perceived distance), preference (after
a group of test 2: waiting for the preference); then the next trial, and finally done.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields

from sim.study.run.errors import RunError

__all__ = [
    "STATUS_TOPIC",
    "GO_TOPIC",
    "STOP_TOPIC",
    "DISTANCE_TOPIC",
    "PREFERENCE_TOPIC",
    "TOPIC_TYPES",
    "PHASES",
    "MAX_PERCEIVED_DISTANCE",
    "TrialStatus",
    "status_to_json",
    "status_from_json",
    "checked_distance",
    "chosen_path",
    "ObserverInput",
    "observer_input",
]

STATUS_TOPIC = "/study/trial"
GO_TOPIC = "/study/go"
STOP_TOPIC = "/study/stop"
DISTANCE_TOPIC = "/study/perceived_distance"
PREFERENCE_TOPIC = "/study/preference"
TOPIC_TYPES = {
    STATUS_TOPIC: "std_msgs/String",
    GO_TOPIC: "std_msgs/Empty",
    STOP_TOPIC: "std_msgs/Header",
    DISTANCE_TOPIC: "std_msgs/Float32",
    PREFERENCE_TOPIC: "std_msgs/String",
}
PHASES = ("to_start", "ready", "moving", "at_rest", "distance", "preference", "done")
MAX_PERCEIVED_DISTANCE = 2.0  # m: an answer beyond this is a typing or tracking error, not a judgement


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
    motion_start: float = math.nan  # s of ROS time when the approach started (phase moving and later)
    group_paths: tuple[str, ...] = ()  # phase preference: the group's paths in the order they were run


def status_to_json(status: TrialStatus) -> str:
    data = asdict(status)
    data["group_paths"] = list(status.group_paths)
    # NaN is not JSON: absent values are null, which Unity's JsonUtility and every JSON parser take
    return json.dumps(
        {key: (None if isinstance(value, float) and math.isnan(value) else value) for key, value in data.items()}
    )


def status_from_json(text: str) -> TrialStatus:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise RunError(f"a trial status is not JSON: {error}") from None
    names = [field.name for field in fields(TrialStatus)]
    if not isinstance(data, dict) or sorted(data) != sorted(names):
        raise RunError(f"a trial status must have exactly {', '.join(names)}, got {text[:200]!r}")
    if data["phase"] not in PHASES:
        raise RunError(f"unknown trial phase {data['phase']!r}; known: {', '.join(PHASES)}")
    for key in ("standoff", "peak_speed", "motion_start"):
        data[key] = math.nan if data[key] is None else float(data[key])
    data["group_paths"] = tuple(data["group_paths"])
    return TrialStatus(**data)


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
class ObserverInput:
    kind: str  # "go" | "stop" | "distance" | "preference" | "unknown"
    distance: float = math.nan  # m
    text: str = ""  # the preference as typed, or why the line means nothing now


def _metres(text: str) -> float:
    """ "0.12", "0.12 m" or "12 cm" in metres; ValueError otherwise."""
    for unit, scale in (("cm", 0.01), ("m", 1.0)):
        if text.endswith(unit):
            return float(text[: -len(unit)].strip()) * scale
    return float(text)


def observer_input(line: str, phase: str) -> ObserverInput:
    """A line the observer typed at the runner's terminal (--keyboard), read in the trial's phase: Enter alone =
    go, "s" = stop; while a distance is asked, a distance ("0.12" in metres, "0.12 m" or "12 cm"); while a
    preference is asked, the path's name or its place in the group."""
    text = line.strip()
    if not text:
        return ObserverInput("go")
    if text.lower() in ("s", "stop"):
        return ObserverInput("stop")
    if phase == "distance":
        try:
            return ObserverInput("distance", _metres(text.lower()))
        except ValueError:
            return ObserverInput("unknown", text=f"{text!r} is not a distance (e.g. 0.12, 0.12 m or 12 cm)")
    if phase == "preference":
        return ObserverInput("preference", text=text)
    return ObserverInput("unknown", text=f"{text!r} means nothing in phase {phase} (Enter = go, s = stop)")
