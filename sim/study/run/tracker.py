"""The tracker relay: a rospy node that puts any tracker's poses on the study's pose topics, in the scene's world
(`python -m sim.study tracker --config tracker.yaml --participant N --out DIR`).

From its configuration (sim.study.run.tracking): each body's source, a motion-capture driver's PoseStamped topic
(vrpn_client_ros, mocap_optitrack: one per rigid body) or a TF frame (its transform from the tracker's frame on /tf).
At the start, in this order:
  1. calibration: the experimenter touches each marked point with the calibrating body and presses Enter here; that
     body's poses over the next `hold` s are averaged (a touch whose poses are not all finite, or stray more than
     `still`, is taken again); the rigid transform is fitted (sim.study.motion.calibration) and refused, one line
     and exit 2, when it cannot be trusted: a mirrored tracker frame, touches in another unit, a residual above its
     bound. `--calibration FILE` takes a saved one instead, if it is of this tracker, frame, tip and scene
     (sim.study.run.tracking.saved_calibration: fitted again from its points, and checked likewise);
  2. jitter: every body at rest for `rest` s; each one's RMS distance from its mean;
  3. it saves both in DIR/tracking/<source>_participant_NN.json and publishes them, latched: the announcement on
     /study/tracking, the fit on /study/calibration (both JSON std_msgs/String) and the transform on /tf_static
     (world -> the tracker's frame), so that the session's bag holds them.
Then, while the runner's status is a trial of one of its conditions, every pose is moved into the world and
published on its body's /study/pose/... topic with its own stamp (or, configured so, the relay's ROS time when it
came) and frame `world`. A pose in another frame than the
tracker's is dropped, and said once.
"""

from __future__ import annotations

import json
import re
import signal
import sys
import threading
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from sim.geometry.frames import matrix_to_quat, quat_to_matrix
from sim.study.errors import StudyError
from sim.study.motion.calibration import Calibration, RigidTransform, fit_calibration, jitter
from sim.study.run.errors import RunError
from sim.study.run.protocol import POSE_FRAME, POSE_TOPICS, STATUS_TOPIC, status_from_json
from sim.study.run.tracking import (
    CALIBRATION_TOPIC,
    FOLDER,
    TF_STATIC_TOPIC,
    TRACKING_TOPIC,
    TrackerConfig,
    announcement,
)

__all__ = ["EXIT_INTERRUPTED", "Samples", "held_problem", "run_tracker"]

EXIT_INTERRUPTED = 130


class Samples:
    """The raw poses of each body as they arrive, kept while someone is collecting them; thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._collecting: dict[str, list[np.ndarray]] | None = None

    def add(self, body: str, position: np.ndarray) -> None:
        with self._lock:
            if self._collecting is not None:
                self._collecting.setdefault(body, []).append(position)

    def collect(self, seconds: float, stop: threading.Event) -> dict[str, np.ndarray]:
        """Each body's positions (n, 3) that arrive over the next `seconds` of wall time."""
        with self._lock:
            self._collecting = {}
        stop.wait(seconds)
        with self._lock:
            taken, self._collecting = self._collecting, None
        return {body: np.array(points).reshape(-1, 3) for body, points in (taken or {}).items()}


def held_problem(held: np.ndarray, still: float) -> str:
    """Why a touch's poses (n, 3, at least one) cannot be taken ("" when they can): not all finite (the tracker lost
    the body, and a NaN compares as nothing), or straying further than `still` (m) from their mean."""
    if not np.all(np.isfinite(held)):
        return f"{int(np.sum(~np.all(np.isfinite(held), axis=1)))} of its {len(held)} poses were not finite (lost?)"
    spread = float(np.max(np.linalg.norm(held - held.mean(axis=0), axis=1)))
    if spread > still:
        return f"it moved {spread * 1000:.1f} mm"
    return ""


def _say(text: str) -> None:
    print(f"sim.study tracker: {text}", file=sys.stderr, flush=True)


def _touches(
    config: TrackerConfig,
    points: dict[str, np.ndarray],
    samples: Samples,
    lines: Iterable[str],
    stop: threading.Event,
) -> np.ndarray:
    """The calibrating body's place at each marked point, taken when the experimenter presses Enter (one line of
    `lines` per touch)."""
    settings = config.calibration
    body = settings.body
    taken = []
    typed = iter(lines)
    for name in settings.points:
        x, y, z = points[name]
        while True:
            _say(
                f"touch {name} (world {x:.3f}, {y:.3f}, {z:.3f} m) with the {body}'s tracker, hold it still and press "
                "Enter"
            )
            if next(typed, None) is None or stop.is_set():
                raise RunError(f"the calibration ended before {name} was touched (no more input)")
            held = samples.collect(settings.hold, stop).get(body, np.zeros((0, 3)))
            if len(held) == 0:
                _say(f"no pose of the {body} came within {settings.hold:g} s: is the tracker running? Again:")
                continue
            problem = held_problem(held, settings.still)
            if problem:
                _say(f"the {body} was not held still while {name} was taken ({problem}); touch it again:")
                continue
            spread = float(np.max(np.linalg.norm(held - held.mean(axis=0), axis=1)))
            taken.append(held.mean(axis=0))
            _say(f"{name} taken: {len(held)} poses, spread {spread * 1000:.1f} mm")
            break
    return np.array(taken)


def _rotation(q: Any) -> np.ndarray:
    """A message's quaternion as a matrix; a zero quaternion (a driver that sends positions only) as none."""
    try:
        return quat_to_matrix((q.x, q.y, q.z, q.w))
    except ValueError:
        return np.eye(3)


def _tf_message(transform: RigidTransform, frame: str) -> Any:
    """The calibration as a TFMessage: the tracker's frame in the scene's world."""
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    stamped = TransformStamped()
    stamped.header.frame_id, stamped.child_frame_id = POSE_FRAME, frame
    t = stamped.transform
    t.translation.x, t.translation.y, t.translation.z = (float(v) for v in transform.translation)
    q = matrix_to_quat(transform.rotation)
    t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w = (float(v) for v in q)
    return TFMessage(transforms=[stamped])


def run_tracker(
    config: TrackerConfig,
    points: dict[str, np.ndarray],
    participant: int,
    out: Path,
    saved: Calibration | None,
    lines: Iterable[str] = sys.stdin,
) -> int:
    """The node: calibration (or `saved`), jitter, announcement, then the relay until SIGINT or SIGTERM."""
    import rospy
    from geometry_msgs.msg import PoseStamped
    from std_msgs.msg import String
    from tf2_msgs.msg import TFMessage

    from sim.wire.rosnode import init_node

    stop = threading.Event()
    init_node("study_tracker_" + re.sub(r"[^A-Za-z0-9_]", "_", config.source))
    samples = Samples()
    relay: dict[str, Any] = {"transform": None, "open": False}  # set once calibrated; open during its trials
    publishers = {body: rospy.Publisher(POSE_TOPICS[body], PoseStamped, queue_size=100) for body in config.bodies}
    refused: set[str] = set()

    def on_pose(body: str, stamp: Any, frame_id: str, position: np.ndarray, rotation: np.ndarray) -> None:
        if frame_id.lstrip("/") != config.frame:
            if body not in refused:
                refused.add(body)
                _say(f"poses of the {body} dropped: their frame is {frame_id!r}, not the tracker's {config.frame!r}")
            return
        samples.add(body, position)
        transform: RigidTransform | None = relay["transform"]
        if transform is None or not relay["open"]:
            return
        message = PoseStamped()
        message.header.stamp = rospy.Time.now() if config.stamp == "arrival" else stamp
        message.header.frame_id = POSE_FRAME
        p, q = message.pose.position, message.pose.orientation
        p.x, p.y, p.z = (float(v) for v in transform.apply(position))
        q.x, q.y, q.z, q.w = (float(v) for v in matrix_to_quat(transform.apply_rotation(rotation)))
        publishers[body].publish(message)

    def on_topic(message: Any, body: str) -> None:
        p = message.pose.position
        rotation = _rotation(message.pose.orientation)
        on_pose(body, message.header.stamp, message.header.frame_id, np.array([p.x, p.y, p.z]), rotation)

    by_child = {source.tf: body for body, source in config.bodies.items() if source.tf}

    def on_tf(message: Any) -> None:
        for stamped in message.transforms:
            body = by_child.get(stamped.child_frame_id.lstrip("/"))
            if body is None:
                continue
            t, rotation = stamped.transform.translation, _rotation(stamped.transform.rotation)
            on_pose(body, stamped.header.stamp, stamped.header.frame_id, np.array([t.x, t.y, t.z]), rotation)

    def on_status(message: Any) -> None:
        try:
            status = status_from_json(message.data)
        except StudyError:
            return
        relay["open"] = status.test > 0 and status.condition in config.conditions

    subscribers = [
        rospy.Subscriber(source.topic, PoseStamped, on_topic, callback_args=body, tcp_nodelay=True)
        for body, source in config.bodies.items()
        if source.topic
    ]
    if by_child:
        subscribers.append(rospy.Subscriber("/tf", TFMessage, on_tf, tcp_nodelay=True))
    try:
        # Ctrl-C while a point is asked for or the bodies rest: interrupted at once (the read of a line is not)
        if saved is None:
            names = config.calibration.points
            touched = _touches(config, points, samples, lines, stop)
            calibration = fit_calibration(
                names,
                np.array([points[n] for n in names]),
                touched,
                config.calibration.max_residual,
                config.calibration.tip,
            )
        else:
            calibration = saved
        _say(
            f"calibrated from {len(calibration.names)} points: residual RMS {calibration.rms * 1000:.2f} mm, max "
            f"{calibration.max * 1000:.2f} mm at {calibration.worst} (bound {calibration.bound * 1000:.1f} mm); each "
            f"point left out of the fit and predicted by the others: RMS {calibration.left_out_rms * 1000:.2f} mm, "
            f"max {calibration.left_out_max * 1000:.2f} mm at {calibration.left_out_worst}"
        )
        _say(f"every tracked body still, please: measuring the jitter for {config.rest:g} s")
        rest = samples.collect(config.rest, stop)
        jitters = {body: jitter(rest.get(body, np.zeros((0, 3)))) for body in config.bodies}
        _say("jitter at rest: " + ", ".join(f"{body} {value * 1000:.2f} mm" for body, value in jitters.items()))
        fit = {
            "source": config.source,
            "frame": config.frame,
            "world_frame": POSE_FRAME,
            "body": config.calibration.body,
            **calibration.to_data(),
        }
        said = announcement(config.source, config.conditions, jitters, config.rest, fit, participant)
        record = out / FOLDER / f"{re.sub(r'[^A-Za-z0-9_.-]', '_', config.source)}_participant_{participant:02d}.json"
        record.parent.mkdir(parents=True, exist_ok=True)
        record.write_text(json.dumps(json.loads(said), indent=2) + "\n")
        latched = [
            (rospy.Publisher(TRACKING_TOPIC, String, queue_size=1, latch=True), String(data=said)),
            (rospy.Publisher(CALIBRATION_TOPIC, String, queue_size=1, latch=True), String(data=json.dumps(fit))),
            (
                rospy.Publisher(TF_STATIC_TOPIC, TFMessage, queue_size=1, latch=True),
                _tf_message(calibration.transform, config.frame),
            ),
        ]
        for publisher, message in latched:
            publisher.publish(message)
        relay["transform"] = calibration.transform
        for signum in (signal.SIGINT, signal.SIGTERM):  # from now on, the relay ends cleanly on either
            signal.signal(signum, lambda *_: stop.set())
        rospy.Subscriber(STATUS_TOPIC, String, on_status)
        print(f"tracker {config.source}: saved {record}", flush=True)
        print(
            f"tracker {config.source}: relaying {', '.join(f'{b} from {s}' for b, s in config.bodies.items())} "
            f"into the world in {' and '.join(config.conditions)} trials",
            flush=True,
        )
        while not stop.is_set():
            stop.wait(0.2)
    except KeyboardInterrupt:
        _say("interrupted before the relay started: nothing saved")
        return EXIT_INTERRUPTED
    finally:
        for subscriber in subscribers:
            subscriber.unregister()
        rospy.signal_shutdown("tracker done")
    return 0
