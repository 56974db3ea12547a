"""A tracker of the participant's body in reality, as configured (pure: data in, data out; the node that relays its
poses is sim.study.run.tracker).

  TrackerConfig     a tracker's YAML: its name, the frame its poses are in, the conditions it tracks, each body's
                    source (a PoseStamped topic, as a motion-capture driver publishes one per rigid body, or a TF
                    frame, a direct child of the tracker's frame on /tf), the calibration's marked points (refused
                    here already when they lie near a line or a plane), bound and tip, and how long the bodies rest
                    for the jitter
  marked_points     the scene's points an experimenter touches to calibrate: the hand model's two ends on its top,
                    and the table top's four corners (world coordinates, from the scene)
  saved_calibration a saved fit (--calibration FILE) taken for this session only when it is of this config's tracker
                    and frame, made with its tip, and its points are this scene's where they are now; fitted again
                    from its touches and checked as a new fit is
  announcement      what a pose source says of itself on TRACKING_TOPIC (latched, JSON): its name, the conditions it
                    tracks, its jitter at rest and its calibration; the runner records it per condition. The tracker
                    relay (sim.study.run.tracker) announces itself, and so does the VR page (its settings carry its
                    announcement, made here, which it sends with its first poses, and again with its jitter when
                    its rest at the session's start is over)
  trial_source      one trial's pose source, recorded on its row: its name and its calibration's id (a short hash
                    of the fit in use; "" uncalibrated). An announced source without a calibration is named apart
                    in reality ("headset (uncalibrated)"): the headset's own tracking places its poses in the
                    virtual scene, not at the real table, so they are a source of their own there
  session_tracking  the session's record of it: per condition whose trials had poses, the source that announced
                    itself for it last (or the one named on the runner's command line, which overrides it), its
                    jitter and calibration
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.study.design.scene import Scene
from sim.study.design.spec import CONDITIONS
from sim.study.motion.calibration import MIN_POINTS, Calibration, check_spread, fit_calibration, saved_points
from sim.study.motion.errors import MotionError
from sim.study.run.errors import RunError
from sim.study.run.protocol import BODIES, POSE_FRAME

__all__ = [
    "TRACKING_TOPIC",
    "CALIBRATION_TOPIC",
    "TF_STATIC_TOPIC",
    "FOLDER",
    "REST_S",
    "BodySource",
    "CalibrationSettings",
    "TrackerConfig",
    "tracker_config",
    "marked_points",
    "saved_calibration",
    "announcement",
    "announcement_from_json",
    "UNNAMED",
    "PoseSource",
    "UNTRACKED",
    "calibration_id",
    "announced_name",
    "trial_source",
    "session_tracking",
]

TRACKING_TOPIC = "/study/tracking"  # std_msgs/String, latched: a pose source's announcement (JSON)
CALIBRATION_TOPIC = "/study/calibration"  # std_msgs/String, latched: the calibration's fit (JSON)
TF_STATIC_TOPIC = "/tf_static"  # the calibration as TF: world -> the tracker's frame
FOLDER = "tracking"  # in a session's output: the trackers' calibrations and jitter, and each session's record
REST_S = 3.0  # s of the bodies at rest at the session's start, for the jitter: the relay's default, and the VR page's
STAMPS = ("source", "arrival")  # how a relayed pose is stamped (TrackerConfig.stamp)
DEFAULT_POINTS = ("hand_fingertips", "hand_wrist", "table_corner_1", "table_corner_2", "table_corner_3")
SCENE_TOLERANCE = 0.001  # m: a saved fit's point further than this from the scene's is of another scene
UNNAMED = "unnamed"  # a tracked trial's source when neither an announcement nor the command line named one
CALIBRATION_ID_LENGTH = 8  # hex digits of the fit's hash: a few fits per study, told apart at a glance


@dataclass(frozen=True)
class BodySource:
    topic: str = ""  # a PoseStamped topic in the tracker's frame
    tf: str = ""  # or a TF child frame of the tracker's frame

    def __str__(self) -> str:
        return self.topic or f"TF {self.tf}"


@dataclass(frozen=True)
class CalibrationSettings:
    body: str = "right_hand"  # the tracked body that touches the points
    points: tuple[str, ...] = DEFAULT_POINTS
    max_residual: float = 0.01  # m: the largest residual accepted
    hold: float = 0.5  # s the body is held on each point; its poses over that time are averaged
    still: float = 0.005  # m: a touch whose poses stray further from their mean is taken again (the hand moved)
    tip: float = 0.0  # m: the tracked point's height above the surface it touches (a marker ball's radius)


@dataclass(frozen=True)
class TrackerConfig:
    source: str  # the tracker's name, as the report gives it
    frame: str  # the frame_id of its poses (its own origin), the child of the scene's world on /tf_static
    bodies: dict[str, BodySource]  # by BODIES' names: the bodies it tracks
    conditions: tuple[str, ...] = CONDITIONS
    calibration: CalibrationSettings = field(default_factory=CalibrationSettings)
    rest: float = REST_S  # s of the bodies at rest at the start, for the jitter
    # how a relayed pose is stamped: "source", the tracker's own stamp (a driver that stamps on ROS time), or
    # "arrival", the relay's ROS time when it came (a tracker on a clock of its own; adds the way to the relay)
    stamp: str = "source"


def _number(data: Mapping[str, Any], key: str, default: float, where: str) -> float:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0):
        raise RunError(f"{where}: {key} must be a positive number, got {value!r}")
    return float(value)


def _keys(data: object, allowed: tuple[str, ...], where: str) -> Mapping[str, Any]:
    if not isinstance(data, Mapping):
        raise RunError(f"{where} must be a mapping, got {data!r}")
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise RunError(f"{where}: unknown key {unknown[0]!r} (known: {', '.join(allowed)})")
    return data


def _name(data: Mapping[str, Any], key: str, where: str) -> str:
    value = data.get(key)
    if not isinstance(value, str) or not value.strip():
        raise RunError(f"{where}: {key} must be a name, got {value!r}")
    return value.strip()


def tracker_config(data: object, scene: Scene, where: str = "tracker config") -> TrackerConfig:
    """The tracker's configuration from its YAML data, its marked points checked against the scene's; RunError names
    the key and the value that cannot be used."""
    top = _keys(data, ("source", "frame", "conditions", "bodies", "calibration", "rest", "stamp"), where)
    source, frame = _name(top, "source", where), _name(top, "frame", where)
    if frame == POSE_FRAME:
        raise RunError(
            f"{where}: the tracker's frame is named {frame!r}, as the scene's: name the driver's frame otherwise "
            "(vrpn_client_ros: ~frame_id; mocap_optitrack: parent_frame_id), e.g. mocap"
        )
    conditions = tuple(top.get("conditions", CONDITIONS))
    if not conditions or any(c not in CONDITIONS for c in conditions) or len(set(conditions)) != len(conditions):
        raise RunError(f"{where}: conditions must be some of {', '.join(CONDITIONS)}, got {top.get('conditions')!r}")
    bodies_data = top.get("bodies")
    if not isinstance(bodies_data, Mapping) or not bodies_data:
        raise RunError(f"{where}: bodies must map some of {', '.join(BODIES)} to a topic or a TF frame")
    bodies = {}
    for body, given in bodies_data.items():
        if body not in BODIES:
            raise RunError(f"{where}: unknown body {body!r} (the bodies: {', '.join(BODIES)})")
        entry = _keys(given, ("topic", "tf"), f"{where}: bodies.{body}")
        if len(entry) != 1:
            raise RunError(f"{where}: bodies.{body} needs one of topic or tf, got {dict(entry)!r}")
        kind = next(iter(entry))
        bodies[body] = BodySource(**{kind: _name(entry, kind, f"{where}: bodies.{body}")})
    settings = _keys(
        top.get("calibration", {}), ("body", "points", "max_residual", "hold", "still", "tip"), f"{where}: calibration"
    )
    defaults = CalibrationSettings()
    body = settings.get("body", defaults.body)
    if body not in bodies:
        raise RunError(f"{where}: calibration.body must be a body it tracks ({', '.join(bodies)}), got {body!r}")
    points = tuple(settings.get("points", defaults.points))
    known = marked_points(scene)
    wrong = [p for p in points if p not in known]
    if wrong or len(set(points)) != len(points) or len(points) < MIN_POINTS:
        raise RunError(
            f"{where}: calibration.points must be {MIN_POINTS} or more of {', '.join(known)}, each once, not all in "
            f"one plane, got {list(points)!r}"
        )
    bound = _number(settings, "max_residual", defaults.max_residual, f"{where}: calibration")
    try:
        check_spread(np.array([known[p] for p in points]), bound, "calibration's points")
    except MotionError as error:
        raise RunError(f"{where}: {error}") from None
    tip = settings.get("tip", defaults.tip)
    if isinstance(tip, bool) or not isinstance(tip, (int, float)) or not (math.isfinite(tip) and 0 <= tip < 0.1):
        raise RunError(f"{where}: calibration: tip must be a length in m, 0 or more and under 0.1, got {tip!r}")
    calibration = CalibrationSettings(
        body,
        points,
        bound,
        _number(settings, "hold", defaults.hold, f"{where}: calibration"),
        _number(settings, "still", defaults.still, f"{where}: calibration"),
        float(tip),
    )
    stamp = top.get("stamp", "source")
    if stamp not in STAMPS:
        raise RunError(f"{where}: stamp must be one of {', '.join(STAMPS)}, got {stamp!r}")
    return TrackerConfig(source, frame, bodies, conditions, calibration, _number(top, "rest", REST_S, where), stamp)


def marked_points(scene: Scene) -> dict[str, np.ndarray]:
    """The scene's points to touch, in the world: the hand model's fingertips and wrist (the middle of each end of its
    top; its fingers point along its x), and the table top's corners, counted anticlockwise seen from above from the
    one at the table's lowest x and y."""
    hand, table = scene.hand, scene.table
    along = hand.rotation @ np.array([hand.size[0] / 2.0, 0.0, 0.0])
    points = {"hand_fingertips": hand.top + along, "hand_wrist": hand.top - along}
    half = table.size / 2.0
    for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (1, 1), (-1, 1)), start=1):
        corner = table.top + table.rotation @ np.array([sx * half[0], sy * half[1], 0.0])
        points[f"table_corner_{k}"] = corner
    return points


def _xyz(point: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in point) + ") m"


def saved_calibration(
    data: object, config: TrackerConfig, points: Mapping[str, np.ndarray], where: str = "the saved calibration"
) -> Calibration:
    """A saved fit (a tracker's tracking/*.json, or its calibration alone) for this session: refused in one line
    (RunError, or MotionError from the fit) naming what differs when it is of another tracker or frame than
    `config`'s, made with another tip, or its points are not this scene's `points` where they are now (a table
    moved since would otherwise move every pose with it, the old touches fitting the old places as well as ever).
    Fitted again from its touches, held to this config's bound."""
    fit = data.get("calibration", data) if isinstance(data, Mapping) else data
    if not isinstance(fit, Mapping):
        raise RunError(f"{where} holds no calibration")
    for key, here in (("source", config.source), ("frame", config.frame), ("world_frame", POSE_FRAME)):
        there = fit.get(key)
        if there != here:
            raise RunError(
                f"{where} is a fit of {key} {there!r}, not this session's {here!r} (the config's): calibrate again"
            )
    saved = saved_points(fit, where)
    if abs(saved.tip - config.calibration.tip) > 1e-6:
        raise RunError(
            f"{where} was made with a tip of {saved.tip * 1000:.1f} mm, the config says "
            f"{config.calibration.tip * 1000:.1f} mm: calibrate again"
        )
    for name, there in zip(saved.names, saved.world):
        if name not in points:
            raise RunError(f"{where} touched {name!r}, which this scene does not mark: calibrate again")
        apart = float(np.linalg.norm(there - points[name]))
        if apart > SCENE_TOLERANCE:
            raise RunError(
                f"{where} was fitted to another scene: its {name} is at {_xyz(there)}, this scene's at "
                f"{_xyz(points[name])}, {apart * 1000:.1f} mm apart: calibrate again"
            )
    return fit_calibration(saved.names, saved.world, saved.touched, config.calibration.max_residual, saved.tip)


def announcement(
    source: str,
    conditions: tuple[str, ...],
    jitter: Mapping[str, float],
    rest: float | None,
    calibration: Mapping[str, Any] | None,
    participant: int | None = None,
) -> str:
    """A pose source's announcement as JSON: its jitter by body (m; null where not measured), over `rest` s (None:
    not measured). The VR page gets it without jitter in its settings, and fills jitter_m and rest_s itself when
    its rest at the session's start is over (sim/study/views/vr/web/rest.js, the same measure as motion.calibration's
    jitter)."""
    return json.dumps(
        {
            "source": source,
            "conditions": list(conditions),
            "participant": participant,
            "rest_s": rest,
            "jitter_m": {body: (None if not math.isfinite(v) else v) for body, v in jitter.items()},
            "calibration": calibration,
        }
    )


def announcement_from_json(text: str) -> dict[str, Any]:
    """An announcement as data; RunError when it is not one."""
    try:
        data = json.loads(text)
    except ValueError as error:
        raise RunError(f"a tracker's announcement is not JSON: {error}") from None
    if not (isinstance(data, dict) and isinstance(data.get("source"), str) and data["source"]):
        raise RunError(f"a tracker's announcement names no source: {text[:200]!r}")
    conditions = data.get("conditions")
    if not (isinstance(conditions, list) and all(c in CONDITIONS for c in conditions)):
        raise RunError(f"a tracker's announcement has conditions {conditions!r}, not some of {CONDITIONS}")
    return data


@dataclass(frozen=True)
class PoseSource:
    """What tracked one trial, as its row records it."""

    name: str  # "" when the trial had no poses
    calibration_id: str = ""  # the fit's calibration_id; "" without a calibration


UNTRACKED = PoseSource("")


def calibration_id(fit: Mapping[str, Any] | None) -> str:
    """A short id of a calibration's fit (its JSON data, as announced): the first hex digits of the SHA-256 of its
    canonical JSON, so a fit has the same id in every trial and session that used it, and one from other touches
    another; "" without one."""
    if not fit:
        return ""
    canonical = json.dumps(fit, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()[:CALIBRATION_ID_LENGTH]


def announced_name(condition: str, said: Mapping[str, Any]) -> str:
    """The name an announced source goes by in `condition`'s trials: its own, but in reality "<name> (uncalibrated)"
    when it has no calibration (the VR page's headset worn with passthrough, `vr --pose-conditions vr,reality`):
    its own tracking places it in the virtual scene, which is not calibrated to the real table, so its poses there
    are neither a calibrated tracker's nor the same source as the headset in VR."""
    source = str(said["source"])
    return f"{source} (uncalibrated)" if condition == "reality" and not said.get("calibration") else source


def trial_source(condition: str, said: Mapping[str, Any] | None, named: str | None) -> PoseSource:
    """The source of a trial of `condition` that had poses: the one `named` on the command line, which overrides the
    announcement `said` for the condition unless that one has the same name (whose calibration it then keeps), else
    the announced one (announced_name), else UNNAMED."""
    if named is not None and (said is None or said["source"] != named):
        return PoseSource(named)
    if said is None:
        return PoseSource(UNNAMED)
    return PoseSource(announced_name(condition, said), calibration_id(said.get("calibration")))


def session_tracking(
    participant: int,
    tracked: set[str],
    announced: Mapping[str, Mapping[str, Any]],
    named: Mapping[str, str],
) -> dict[str, Any]:
    """The session's record of its pose sources: per condition in `tracked` (its trials had poses), the one `named`
    on the command line, which overrides any announcement (its jitter and calibration kept only when the source
    announced for the condition has that name), else the source `announced` for it (by condition, the latest
    announcement naming it, by announced_name), else "" (unnamed). Its trials' rows say which source tracked each
    (trial_source): an announcement that came mid-session is the record's, not every trial's."""
    conditions: dict[str, Any] = {}
    for condition in CONDITIONS:
        if condition not in tracked:
            continue
        said = announced.get(condition)
        if condition in named and (said is None or said["source"] != named[condition]):
            conditions[condition] = {"source": named[condition], "jitter_m": {}, "calibration": None}
        elif said is not None:
            conditions[condition] = {
                "source": announced_name(condition, said),
                "jitter_m": said.get("jitter_m") or {},
                "rest_s": said.get("rest_s"),
                "calibration": said.get("calibration"),
            }
        else:
            conditions[condition] = {"source": "", "jitter_m": {}, "calibration": None}
    return {"participant": participant, "conditions": conditions}
