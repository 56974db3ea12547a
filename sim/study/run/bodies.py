"""The participant's tracked bodies in a session, as the runner takes them: the pose sources' announcements and the
poses on the protocol's pose topics, and each approach's motion measures.

The participant's tracked head and hands (the protocol's pose topics: the VR page's headset and controllers, or a
tracker in reality) are measured per approach (sim.study.motion): the hand's withdrawal, the head's distance to the
end effector at the press, the time tracking was lost; an approach during which no pose came is unmeasured. At an
approach's end the runner waits (at most RunnerOptions.pose_grace of wall time, holding the robot in real time) until
every body that has sent poses since the approach started has sent one stamped at its end: a lockstep outruns its
participant, and poses travel apart from the status. Then it holds the robot at rest, its clock running, until the
hand under the robot is at rest again (at most sim.study.motion's WITHDRAWAL_LIMIT after the robot rests), so that a
late withdrawal is measured whole. Which pose source tracked each condition (announced on /study/tracking by the
tracker relay, sim.study.run.tracker, and by the VR page, or named by RunnerOptions.pose_sources over them), with its
jitter and calibration, goes to tracking/participant_NN.json after every trial; each trial's row records the source
that tracked it and its calibration's id (sim.study.run.tracking.trial_source), so a source that changed mid-session
is attributed trial by trial. In a condition's trials only the poses of the ROS node that announced its source count
(a page's come through the endpoint's node); the others are dropped, and said once per node: two trackers never mix
in one measure. A condition without an announcement takes every pose. During an approach, the hand under the robot
as its tracker sees it goes to the link's supervision (hand_watch).
"""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path
from typing import Any, Callable, Mapping

from sim.study.design.feasibility import Approaches
from sim.study.design.plan import PlannedTrial
from sim.study.design.scene import Scene
from sim.study.errors import StudyError
from sim.study.motion.measures import (
    REST_DURATION,
    UNMEASURED,
    MotionMeasures,
    Window,
    hand_under_robot,
    motion_measures,
    withdrawal_end,
)
from sim.study.run.console import say
from sim.study.run.links.base import RobotLink
from sim.study.run.links.hand import HandWatch, tracks_hands
from sim.study.run.poses import ReceivedPoses
from sim.study.run.protocol import POSE_TOPICS, TRACKING_GAP
from sim.study.run.tracking import FOLDER as TRACKING
from sim.study.run.tracking import (
    TRACKING_TOPIC,
    UNTRACKED,
    PoseSource,
    announcement_from_json,
    session_tracking,
    trial_source,
)
from sim.study.run.trial import TrialRun

__all__ = ["TrackedBodies"]


class TrackedBodies:
    """The poses and pose sources of a session, by condition. `link` gives the current condition's link: its clock
    is the approach's, and it holds the robot while poses are waited for; `condition` is the current trial's, whose
    announced source's poses count, set by the runner."""

    def __init__(
        self,
        scene: Scene,
        approaches: Approaches,
        link: Callable[[], RobotLink],
        pose_grace: float,
        pose_sources: Mapping[str, str],
        dt: float,
        stop: threading.Event,
    ) -> None:
        import rospy
        from geometry_msgs.msg import PoseStamped
        from std_msgs.msg import String

        self.scene, self.approaches, self._link, self.stop = scene, approaches, link, stop
        self.pose_grace = pose_grace  # s of wall time, at an approach's end (RunnerOptions.pose_grace)
        # by condition, a pose source named by hand: over any announcement on /study/tracking (session_tracking)
        self.pose_sources = pose_sources
        self.dt = dt  # s: the link's step
        self.poses = ReceivedPoses()
        self._refusals_told: set[str] = set()  # bodies whose refused poses have been logged
        self.announced: dict[str, dict[str, Any]] = {}  # by condition: the latest pose source announced for it
        # by condition: the ROS node that announced it (the endpoint's, for a page): only its poses count in that
        # condition's trials, so that a second tracker (a VR page left open in reality) cannot mix its own in
        self.announcers: dict[str, str] = {}
        self._foreign_told: set[tuple[str, str]] = set()  # (condition, node) whose dropped poses have been logged
        self.condition = ""  # the current trial's
        self.tracked: set[str] = set()  # the conditions whose trials had poses
        self._subscribers = [rospy.Subscriber(TRACKING_TOPIC, String, self._on_tracker)]
        for body, topic in POSE_TOPICS.items():
            self._subscribers.append(
                rospy.Subscriber(topic, PoseStamped, self._on_pose, callback_args=body, tcp_nodelay=True)
            )

    def _on_tracker(self, message: Any) -> None:
        """A pose source's announcement: it serves its conditions from now on."""
        try:
            said = announcement_from_json(message.data)
        except StudyError as error:
            say(f"a tracker's announcement was refused: {error}")
            return
        node = _publisher(message)
        for condition in said["conditions"]:
            before = self.announcers.get(condition)
            if before is not None and before != node:
                say(
                    f"{condition}'s pose source is now {said['source']!r} (node {node}), was "
                    f"{self.announced[condition]['source']!r} (node {before}): only the latest's poses count"
                )
            self.announced[condition] = said
            self.announcers[condition] = node

    def write_tracking(self, out: Path, participant: int) -> None:
        """The session's pose sources per tracked condition, in `out`/tracking/participant_NN.json."""
        record = session_tracking(participant, self.tracked, self.announced, self.pose_sources)
        path = out / TRACKING / f"participant_{participant:02d}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(record, indent=2) + "\n")

    def _on_pose(self, message: Any, body: str) -> None:
        condition, node = self.condition, _publisher(message)
        source = self.announcers.get(condition)
        if source is not None and node != source:
            if (condition, node) not in self._foreign_told:
                self._foreign_told.add((condition, node))
                say(f"poses from node {node} dropped in {condition}'s trials: its announced pose source is {source}")
            return
        point = message.pose.position
        self.poses.add(body, message.header.stamp.to_sec(), message.header.frame_id, (point.x, point.y, point.z))

    def hand_watch(self, began: float) -> HandWatch:
        """The hand under the robot as its tracker (poses since the trial `began`) sees it, for the link's supervision
        of a motion (sim.study.run.links.hand): the distance floor, and the speed and separation monitor."""
        return HandWatch(
            self.scene.hand.position,
            lambda: self.poses.tracks(began),
            self.approaches.world.hand_distance,
            lambda: tracks_hands(self.poses.sending(began)),
        )

    def motion(
        self, trial: PlannedTrial, run: TrialRun, began: float, window: Window, log: Callable[[str], None]
    ) -> tuple[MotionMeasures, PoseSource]:
        """The approach's motion measures from the poses of the bodies sending since it started (none: unmeasured),
        once they are in up to its end; their poses since the trial `began` count (where a body was as it started).
        With them, the source that tracked it: the one announced (or named) for its condition as they are taken."""
        if not self.poses.sending(window.start):
            return UNMEASURED, UNTRACKED
        self.tracked.add(trial.condition)
        late = self._await_poses(window.start, window.end)
        if late:
            log(
                f"trial {trial.index}: no pose of {', '.join(late)} up to the approach's end within "
                f"{self.pose_grace:g} s; measured as a gap"
            )
        for body, why in self.poses.refused().items():
            if body not in self._refusals_told:
                self._refusals_told.add(body)
                log(f"poses of {body} refused: {why}")
        at_rest = self.approaches.end_effector(self._link().target)
        if not late:
            self._follow_withdrawal(began, window)
        pressed = math.isfinite(window.press)
        # the run's states are on the plan's seconds, as its press is (the window's are wall seconds: a rehearsal's
        # are slower)
        end_effector = self.approaches.end_effector(run.positions_at(run.measures().press_time)) if pressed else None
        measures = motion_measures(
            self.poses.tracks(began), window, self.scene.hand.position, end_effector, TRACKING_GAP, at_rest
        )
        self.poses.forget(before=window.end)
        if not measures.tracked_hand:
            log(f"trial {trial.index}: no tracked hand was at the scene's hand as the approach started")
        said, named = self.announced.get(trial.condition), self.pose_sources.get(trial.condition)
        return measures, trial_source(trial.condition, said, named)

    def _follow_withdrawal(self, began: float, window: Window) -> None:
        """Hold the robot at rest, its clock running, until the hand under the robot is at rest again after its
        withdrawal (sim.study.motion's withdrawal_end), at most to the window's limit: a participant who pulls back
        late is measured whole. Stops early when no hand is under the robot, or a body's poses fall behind."""
        hold = max(1, round(REST_DURATION / 2 / self.dt))  # steps between looks: a quarter second
        hand_point = self.scene.hand.position
        while self._link().clock < window.limit and not self.stop.is_set():
            tracks = self.poses.tracks(began)
            hand = hand_under_robot(tracks, window, hand_point, TRACKING_GAP)
            if not hand or withdrawal_end(tracks[hand], window, TRACKING_GAP) is not None:
                return
            self._link().idle(hold * self.dt)
            if self._await_poses(window.start, self._link().clock):
                return  # a body stopped sending: its gap is measured, and no longer waited for

    def _await_poses(self, since: float, end: float) -> list[str]:
        """Wait (at most pose_grace s of wall time; in real time holding the robot) until every body that has sent
        poses since `since` has one at `end`; the bodies still short of it."""
        if not self._link().realtime:
            return self.poses.wait_covered(since, end, self.pose_grace, self.stop)
        deadline = time.monotonic() + self.pose_grace
        while (late := self.poses.uncovered(since, end)) and time.monotonic() < deadline and not self.stop.is_set():
            self._link().idle()
        return late

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()


def _publisher(message: Any) -> str:
    """The ROS node that published a message rospy delivered (its connection header's caller id)."""
    return str(getattr(message, "_connection_header", {}).get("callerid", ""))
