"""The tidy per-participant CSV: one row per trial, what was planned, measured and answered. Reading checks every
column, so the analysis never works on a half-written or edited-by-hand file without saying so.

Distances are the end effector's (its FK from the achieved joint states) to the hand's surface, in metres. The
press's latency columns, then the participant's motion (sim.study.motion), then the robot link's, then its goals'
leads, then the separation monitoring, then the trial's pose source, then the clocks, then the move's least separation
came last: a file written before any of them is still read, with them at their defaults (NaN, no tracked hand, the
stream, no source named).
"""

from __future__ import annotations

import csv
import math
from dataclasses import astuple, dataclass, fields
from pathlib import Path

from sim.study.run.errors import RunError

__all__ = ["TrialRecord", "write_records", "read_records"]


@dataclass(frozen=True)
class TrialRecord:
    participant: int
    index: int
    condition: str
    condition_position: int  # 1 if the participant did this condition first, else 2
    test: int
    path: str
    standoff: float  # m, planned end (test 2: on top of the hand)
    peak_speed: float  # m/s
    speed_set: str
    group: int
    motion_start: float  # s on the link's clock (ROS time, or wall time): when the arm began to move
    pressed: bool
    press_time: float  # s from the motion's start; NaN without a press
    press_source: str  # the press's frame_id; "" without a press
    press_late: float  # s by which a press arrived after its stamp had passed (applied at arrival); 0 if in time
    distance_at_press: float  # m, FK of the achieved state at the press
    distance_at_rest: float  # m, FK of the last achieved state
    distance_extrapolated: float  # m, the plan's distance at the press time (the thesis's estimate from time)
    braking_distance: float  # m along the path
    perceived_distance: float  # m, test 1's answer; NaN otherwise
    preferred_path: str  # test 2: the group's preferred path, on each of its rows; "" otherwise
    # The press's latency in two parts (NaN where it was not measured: the keyboard's, a client that does not say):
    press_input_delay: float = math.nan  # s from the first reading that saw the press to its stamp (the client's)
    press_arrival_delay: float = math.nan  # s from its stamp to its arrival at the runner (ROS time); NaN unstamped
    # The participant's motion during the approach (sim.study.motion; NaN and "" where nothing was tracked):
    tracked_hand: str = ""  # the body taken for the hand under the robot (left_hand or right_hand); "" untracked
    withdrawal_distance: float = math.nan  # m, how far the hand got away from the robot (sim.study.motion); NaN: gap
    withdrawal_peak_speed: float = math.nan  # m/s, the hand's highest speed away from the robot, likewise
    head_distance_at_press: float = math.nan  # m, the head to the end effector at the press; NaN without a press
    hand_untracked: float = math.nan  # s of the approach without the hand's pose (gaps longer than the protocol's)
    head_untracked: float = math.nan  # s of the approach without the head's pose
    # The robot link (sim.study.run.links) and, on a trajectory controller, what its goals did (NaN/"" on the stream):
    link: str = "stream"  # stream, or the trajectory controller's preset and namespace
    goal_result: str = ""  # the last goal's final status (SUCCEEDED, PREEMPTED, ABORTED...); "" on the stream
    error_code: int = -1  # its result's control_msgs error code (0 SUCCESSFUL); -1: none (the stream, no result)
    tracking_error: float = math.nan  # rad: the largest joint error of the achieved against the commanded path
    replacement_latency: float = math.nan  # s from the press to the braking replacement's sending
    braking_latency: float = math.nan  # s from the press to the first joint state whose speed had fallen
    braking_distance_achieved: float = math.nan  # m along the path from the achieved state at the press to the rest
    safety_stop: str = ""  # why the runner stopped the arm on its own; "" when it did not
    # How far ahead the controller's goals were stamped, measured on the link (sim.study.run.links.lead; NaN on the
    # stream, and stop_lead without a stop):
    start_lead: float = math.nan  # s from the approach's sending to its stamp
    stop_lead: float = math.nan  # s from the braking replacement's preparation to its stamp
    # Speed and separation monitoring on a trajectory controller (sim.study.safety.separation; NaN and "" on the
    # stream): the hand "tracked", or "untracked" (no tracker: the scene's hand, taken at rest, was not monitored)
    hand_monitored: str = ""
    least_separation_predicted: float = math.nan  # m: the least separation a stop decided then would have kept
    least_separation: float = math.nan  # m: the least achieved separation to the hand's live place while moving
    # What tracked the trial's head and hands (sim.study.run.tracking.trial_source): the source's name ("" when no pose
    # came, or the file was written before these columns) and its calibration's id ("" without one)
    pose_source: str = ""
    calibration_id: str = ""
    # The clocks (sim.study.run.links.clock, sim.study.run.clocks; NaN where there is none): the robot's clock behind
    # the runner's as the approach began (applied to its start and press) and how far that moved during it, on a
    # trajectory controller; the clock of the page whose presses stop this condition: its offset to ROS time (its
    # estimate as the trial ended) and the most its stamps could be off from go to the trial's end (half its best
    # round trip plus its lag)
    robot_clock_offset: float = math.nan  # s
    robot_clock_drift: float = math.nan  # s
    page_clock_offset: float = math.nan  # s: ROS time minus the page's clock
    page_clock_uncertainty: float = math.nan  # s
    # The least achieved separation to the hand's live place during the move to the path's start (m; NaN on the
    # stream, and without a move): the move is monitored as the approach is
    move_least_separation: float = math.nan


_FIELDS = fields(TrialRecord)
_NAMES = [field.name for field in _FIELDS]
# The headers a file may have: the columns up to each group added later (the press's latency, the motion, the link,
# its leads, the separation monitoring, the pose source, the clocks, the move's separation). A file written before a
# group is read with that group's columns at their defaults.
_LATER_GROUPS = (
    "press_input_delay",
    "tracked_hand",
    "link",
    "start_lead",
    "hand_monitored",
    "pose_source",
    "robot_clock_offset",
    "move_least_separation",
)
_HEADERS = [_NAMES[: _NAMES.index(first)] for first in _LATER_GROUPS] + [_NAMES]


def write_records(path: Path, records: list[TrialRecord]) -> None:
    """Write the rows at once (to a temporary file, then renamed): a reader never sees half a session."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    with open(partial, "w", newline="") as out:
        writer = csv.writer(out)
        writer.writerow(_NAMES)
        for record in records:
            writer.writerow([_text(value) for value in astuple(record)])
    partial.replace(path)


def _text(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(float(value))  # a numpy float's repr names its type
    return str(value)


def _value(text: str, kind: object, column: str, where: str) -> object:
    try:
        if kind in (int, "int"):
            return int(text)
        if kind in (float, "float"):
            return math.nan if text == "" else float(text)
        if kind in (bool, "bool"):
            if text not in ("true", "false"):
                raise ValueError(text)
            return text == "true"
        return text
    except ValueError:
        raise RunError(f"{where}: column {column} has {text!r}, not a {kind}") from None


def read_records(path: Path) -> list[TrialRecord]:
    try:
        with open(path, newline="") as source:
            rows = list(csv.reader(source))
    except OSError as error:
        raise RunError(f"cannot read {path}: {error.strerror}") from None
    if not rows or rows[0] not in _HEADERS:
        raise RunError(f"{path} is not a study record file: its header must be {','.join(_NAMES)}")
    columns = _FIELDS[: len(rows[0])]
    records = []
    for number, row in enumerate(rows[1:], start=2):
        where = f"{path}:{number}"
        if len(row) != len(columns):
            raise RunError(f"{where}: {len(row)} columns where {len(columns)} belong")
        values = [_value(text, field.type, field.name, where) for text, field in zip(row, columns)]
        records.append(TrialRecord(*values))  # type: ignore[arg-type]
    return records
