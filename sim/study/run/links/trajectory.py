"""The trajectory-controller link: a real arm's ros_control joint_trajectory_controller (or the physics node's
stand-in of it), on wall time. rospy and actionlib.

- No /clock: the link's clock is the wall clock, the time a driver stamps with. A move to a path's start has stamp
  zero ("start at the controller's next update"). An approach and a replacement are stamped ahead by leads
  measured on this connection (sim.study.run.links.lead: a goal's delivery for an approach; query_state's round
  trip, the stop's planning and the delivery for a stop; each its high quantile, summed with a margin, within a
  floor and a ceiling; a stop's is said on stderr, and both are in the trial's record): the controller starts a
  goal at its stamp, so the link knows when the commanded path began (with stamp zero, the goal's delivery delay
  would count as tracking error), and a start in the past drops its first points.
- An approach is one follow_joint_trajectory goal of the planned samples (positions, velocities, accelerations).
- A press is a replacement: sim.study.safety.braking's stop along the path at the runner's deceleration, from the
  controller's desired state at the replacement's start (query_state), continuous in position, velocity and
  acceleration; a stop the controller refuses (it came after its last point was due) is planned and sent anew, and
  a stop before the approach has begun is a hold (an empty trajectory). Never a bare cancel: with franka's
  stop_trajectory_duration of 0 a cancel holds the measured position at once, a step that makes libfranka abort
  with a reflex.
- The arm's joint states are read at whatever rate its driver publishes them. During a motion the link stops the
  arm (the same replacement) on its own when the feed goes stale, the tracking error passes the tolerance, the
  achieved distance to the hand falls under the floor, or the controller ends the goal otherwise than by success.
  These are the toolkit's checks, never instead of the robot's own stop.
- If the runner dies, nothing more is sent: the goal runs on to its end, at the stand-off at rest (ros_control's
  action server does not cancel a goal when its client goes away).

Goals are followed through actionlib's ActionClient, each by its own handle (SimpleActionClient drops a result that
comes before its send_goal has returned).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.control.controller_node import ControllerError
from sim.control.scenarios import approach
from sim.robots import RobotSpec
from sim.study.run.console import say
from sim.study.run.links.base import AppliedPress, ApproachOutcome, Press, TakePress
from sim.study.run.links.goals import GOAL_STATUS, CommandedPath, GoalPoints, goal_points, speed_fell
from sim.study.run.links.lead import START, Leads
from sim.study.run.links.specs import TrajectoryLinkSpec
from sim.study.run.trial import TrialRun
from sim.study.safety.braking import STOP_JERK, Braking, PathGeometry, brake
from sim.wire.contract import MessageError, positions_by_name

__all__ = ["QUERY_PROBES", "JointFeed", "TrajectoryLink", "await_goal_end"]

QUERY_PROBES = 10  # query_state round trips measured at connect, before any stop needs one
POLL = 0.01  # s: the longest wait for a joint state between looks at the presses and the goal
RESULT_GRACE = 5.0  # s after a motion's planned end that the controller may take to end its goal
SUCCEEDED = 3
REJECTED = 5
STAMP_WINDOW = 5.0  # s: a press stamped further from the wall clock is on another clock (the stream's /clock)


@dataclass(frozen=True)
class FedState:
    stamp: float  # s, the driver's
    arrival: float  # s, the wall clock when it came
    positions: np.ndarray
    velocities: np.ndarray


class JointFeed:
    """The arm's joint states as they come (any rate), in the robot's joint order; thread-safe."""

    def __init__(self, robot: RobotSpec) -> None:
        self.robot = robot
        self.error: str | None = None
        self._states: list[FedState] = []
        self._changed = threading.Condition()

    def callback(self, message: Any) -> None:
        try:
            positions = positions_by_name(message.name, message.position, self.robot.joint_names)
            velocities = (
                positions_by_name(message.name, message.velocity, self.robot.joint_names)
                if len(message.velocity)
                else np.full(self.robot.dof, math.nan)
            )
        except MessageError as error:
            with self._changed:
                self.error = str(error)
                self._changed.notify_all()
            return
        state = FedState(message.header.stamp.to_sec(), time.time(), positions, velocities)
        with self._changed:
            self._states.append(state)
            del self._states[:-10000]  # a 500 Hz driver's 20 s, more than a motion takes between looks
            self._changed.notify_all()

    def count(self) -> int:
        with self._changed:
            return len(self._states)

    def latest(self) -> FedState | None:
        with self._changed:
            return self._states[-1] if self._states else None

    def since(self, arrival: float) -> list[FedState]:
        """The states that came after wall time `arrival`."""
        with self._changed:
            return [state for state in self._states if state.arrival > arrival]

    def wait(self, after: float, timeout: float, stop: threading.Event) -> FedState | None:
        """The latest state once one has come after wall time `after` (None after `timeout` s or when stopped)."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while not stop.is_set():
                if self.error is not None:
                    raise ControllerError(f"{self.robot.name}'s joint states: {self.error}")
                if self._states and self._states[-1].arrival > after:
                    return self._states[-1]
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._changed.wait(min(remaining, 0.1))
        return None


def await_goal_end(
    feed: JointFeed, done: Callable[[], bool], sent: float, deadline: float, stale_after: float, stop: threading.Event
) -> None:
    """Until `done()` holds for a goal sent at wall time `sent`: looked at on each new joint state and at least every
    POLL s, never in a spin (a runner spinning on a core starves the arm's driver, or its stand-in, beside it).
    ControllerError when the feed goes stale, when stopped, or when the goal is not done by wall time `deadline`."""
    looked = sent
    while not done():
        state = feed.wait(looked, POLL, stop)  # a state newer than the last one looked at, or POLL s without one
        if stop.is_set():
            raise ControllerError("interrupted")
        if state is not None:
            looked = state.arrival
        latest = feed.latest()
        now = time.time()
        if latest is None or now - latest.arrival > stale_after:
            age = "none yet" if latest is None else f"none for {now - latest.arrival:.3f} s"
            raise ControllerError(f"joint states stale for over {stale_after:g} s on the way to a start ({age})")
        if now > deadline:
            raise ControllerError(f"the controller did not end the move to the start within {RESULT_GRACE:g} s")


class TrajectoryLink:
    """One trajectory controller: its action, its query_state service and the arm's joint states."""

    realtime = True

    def __init__(self, robot: RobotSpec, spec: TrajectoryLinkSpec, dt: float, stop: threading.Event) -> None:
        import actionlib
        import rospy
        from sensor_msgs.msg import JointState

        from sim.wire.control_types import control_types, joint_trajectory

        self.rospy, self.robot, self.spec, self.dt, self.stop = rospy, robot, spec, dt, stop
        self.name = spec.label
        self.types = control_types()
        self._joint_trajectory = joint_trajectory
        ns = spec.namespace
        self.client = actionlib.ActionClient(f"{ns}/follow_joint_trajectory", self.types.action)
        # persistent: a stop's query must not wait for the master's lookup and a new connection
        self.query = rospy.ServiceProxy(f"{ns}/query_state", self.types.query_state, persistent=True)
        self.feed = JointFeed(robot)
        self.subscriber = rospy.Subscriber(
            spec.joint_states_topic, JointState, self.feed.callback, tcp_nodelay=True, queue_size=1000
        )
        self._target = robot.home.copy()
        self._handles: list[Any] = []  # actionlib tracks a goal while its handle lives
        self.lead = Leads()  # the delays measured on this connection, and the leads they give
        self._lead_lock = threading.Lock()  # goals' deliveries are measured on actionlib's threads
        self._connected = False

    # --- RobotLink -------------------------------------------------------------------------------------------
    @property
    def clock(self) -> float:
        return time.time()

    def now(self) -> float:
        return time.time()

    @property
    def target(self) -> np.ndarray:
        return self._target

    def recorded_topics(self) -> list[str]:
        ns = self.spec.namespace
        action = f"{ns}/follow_joint_trajectory"
        return [
            self.spec.joint_states_topic,
            f"{ns}/state",
            f"{ns}/command",
            *(f"{action}/{part}" for part in ("goal", "cancel", "status", "feedback", "result")),
        ]

    def connect(self, timeout: float, recorder: str | None) -> str:
        """The controller's action server and query_state service, and a first joint state."""
        ns = self.spec.namespace
        if not self.client.wait_for_server(self.rospy.Duration(timeout)):
            raise ControllerError(f"no action server {ns}/follow_joint_trajectory within {timeout:g} s")
        try:
            self.query.wait_for_service(timeout)
        except self.rospy.ROSException:
            raise ControllerError(f"no service {ns}/query_state within {timeout:g} s") from None
        for _ in range(QUERY_PROBES):
            self._query(time.time())
        if self.feed.wait(-math.inf, timeout, self.stop) is None:
            raise ControllerError(f"no joint state on {self.spec.joint_states_topic} within {timeout:g} s")
        self._connected = True
        return ns

    def start(self, timeout: float) -> np.ndarray:
        state = self.feed.wait(-math.inf, timeout, self.stop)
        if state is None:
            raise ControllerError(f"no joint state on {self.spec.joint_states_topic} within {timeout:g} s")
        self._target = state.positions.copy()
        return state.positions

    def idle(self, seconds: float = 0.0) -> None:
        """The controller holds the last point on its own: only wait."""
        self.stop.wait(max(seconds, POLL * 2))

    def move_to(self, positions: np.ndarray) -> np.ndarray:
        """A quintic from where the arm is, as one goal; waited for to its end (ControllerError when the feed goes
        stale or the controller does not succeed: the move to a path's start keeps away from the hand, and its goal
        ends at rest)."""
        here = self._latest().positions
        samples, speeds = approach(self.robot, here, np.asarray(positions, dtype=float), self.dt)
        points = goal_points(samples, speeds, self.dt)
        handle, sent = self._send(points, 0.0)
        self._target = np.asarray(positions, dtype=float).copy()
        await_goal_end(
            self.feed, lambda: self._done(handle), sent, sent + points.duration + RESULT_GRACE, self.spec.stale_after,
            self.stop,
        )  # fmt: skip
        status, code, text = self._outcome(handle)
        if status != SUCCEEDED:
            raise ControllerError(f"the move to the path's start ended {GOAL_STATUS.get(status)} ({code}): {text}")
        return self._latest().positions

    def approach(self, run: TrialRun, take_press: TakePress, settle: float) -> ApproachOutcome:
        planned = run.planned
        geometry = PathGeometry(planned.path, planned.positions)
        points = goal_points(planned.positions, planned.velocities, run.dt, self.spec.speed_scale)
        commanded = CommandedPath()
        first = self._latest()
        run.record_state(0.0, first.positions)
        self._time_planning(geometry, run)
        with self._lead_lock:
            start_lead = self.lead.choose(START).lead
        start = time.time() + start_lead
        handle, _ = self._send(points, start)
        commanded.add(start, np.concatenate([[0.0], points.times]), np.vstack([planned.positions[0], points.positions]))
        self._target = planned.positions[-1].copy()
        ends = start + points.duration
        applied: AppliedPress | None = None
        press_at = math.nan
        braking: Braking | None = None
        replacement_sent = math.nan
        stop_lead = math.nan
        reason = ""
        tracking = 0.0
        looked = start
        while True:
            self.feed.wait(looked, POLL, self.stop)
            now = time.time()
            if self.stop.is_set():
                raise ControllerError("interrupted")
            for fed in self.feed.since(looked):
                looked = fed.arrival  # each state once
                if fed.stamp >= start:
                    run.record_state(fed.stamp - start, fed.positions)
                    tracking = max(tracking, commanded.error(fed.stamp, fed.positions))
            stopping = not math.isnan(press_at) or reason != ""
            if not stopping:
                press = take_press(now)
                why = self._unsafe(now, tracking, run, handle)
                if press is not None or why:
                    press_at = now
                    if press is not None:
                        applied, when = _applied(press, now)
                        press_at = min(max(when, start), now)
                    reason = why if press is None else ""
                    run.press(min(max(press_at - start, 0.0) * self.spec.speed_scale, planned.path.duration))
                    stop, braking, sent_at, stop_ends, stop_lead = self._stop_approach(
                        geometry, run, commanded, start, first
                    )
                    if stop is not None:
                        handle, replacement_sent, ends = stop, sent_at - press_at, max(ends, stop_ends)
            elif handle is not self._handles[0] and self._refused(handle):
                # The controller refused the stop (it came after its last point was due, on a starved machine), so
                # the approach goes on: stop it anew, from where it is now commanded to be.
                commanded.discard_last()
                stop, braking, sent_at, stop_ends, stop_lead = self._stop_approach(
                    geometry, run, commanded, start, first
                )
                handle = self._handles[0] if stop is None else stop
                if stop is not None:
                    replacement_sent, ends = sent_at - press_at, max(ends, stop_ends)
            if now >= ends + settle and (self._done(handle) or now >= ends + RESULT_GRACE):
                break
        status, code, text = self._outcome(handle) if self._done(handle) else (-1, None, "no result")
        if not reason and status != SUCCEEDED and handle is self._handles[0]:
            reason = f"the controller ended the goal {GOAL_STATUS.get(status, 'without a result')}: {text}"
        seen = self.feed.since(start)
        stamps = np.array([s.stamp for s in seen])
        speeds = np.array([float(np.linalg.norm(s.velocities)) for s in seen])
        achieved = math.nan
        if not math.isnan(press_at) and seen:
            at_press = min(seen, key=lambda s: abs(s.stamp - press_at)).positions
            zeros = np.zeros(self.robot.dof)
            rest = geometry.project(seen[-1].positions, zeros, zeros)
            achieved = rest.arc - geometry.project(at_press, zeros, zeros).arc
        self._target = seen[-1].positions.copy() if seen else self._target
        self._handles.clear()
        return ApproachOutcome(
            press=applied,
            goal_result=GOAL_STATUS.get(status, "NO RESULT"),
            error_code=code,
            tracking_error=tracking,
            replacement_sent=replacement_sent,
            braking_began=speed_fell(stamps, speeds, press_at) if seen and not math.isnan(press_at) else math.nan,
            braking_planned=braking.distance if braking is not None else math.nan,
            braking_achieved=achieved,
            safety_stop=reason,
            start_lead=start_lead,
            stop_lead=stop_lead,
        )

    def close(self) -> None:
        if self._connected:  # the lead the session ended with, for the lab's record
            with self._lead_lock:
                say(f"{self.name}: a stop would now be stamped {self.lead.choose().describe()}")
        self.subscriber.unregister()
        self.query.close()
        self._handles.clear()
        client = self.client
        for endpoint in (client.pub_goal, client.pub_cancel, client.status_sub, client.result_sub, client.feedback_sub):
            endpoint.unregister()

    # --- the parts -------------------------------------------------------------------------------------------
    def _latest(self) -> Any:
        state = self.feed.wait(time.time() - self.spec.stale_after, self.spec.stale_after, self.stop)
        if state is None:
            raise ControllerError(f"no joint state on {self.spec.joint_states_topic} for {self.spec.stale_after:g} s")
        return state

    def _unsafe(self, now: float, tracking: float, run: TrialRun, handle: Any) -> str:
        """Why the arm must be stopped now ("" when it need not)."""
        latest = self.feed.latest()
        if latest is None or now - latest.arrival > self.spec.stale_after:
            age = math.inf if latest is None else now - latest.arrival
            return f"joint states stale: none for {age:.3f} s (limit {self.spec.stale_after:g} s)"
        if tracking > self.spec.tracking_tolerance:
            return f"tracking error {tracking:.4f} rad over the tolerance {self.spec.tracking_tolerance:g} rad"
        distance = run.live_hand_distance(latest.positions)
        if distance < self.spec.floor:
            return f"achieved distance to the hand {distance:.4f} m under the floor {self.spec.floor:g} m"
        if self._done(handle):
            status, code, text = self._outcome(handle)
            if status != SUCCEEDED:
                return f"the controller ended the goal {GOAL_STATUS.get(status, status)} ({code}): {text}"
        return ""

    def _query(self, at: float) -> Any:
        """query_state's answer for wall time `at`, its round trip measured for the stops' lead."""
        asked = time.time()
        try:
            desired = self.query(self.rospy.Time.from_sec(at))
        except (self.rospy.ServiceException, self.rospy.ROSException) as error:
            raise ControllerError(f"{self.spec.namespace}/query_state failed: {error}") from None
        with self._lead_lock:
            self.lead.add("query", time.time() - asked)
        return desired

    def _time_planning(self, geometry: PathGeometry, run: TrialRun) -> None:
        """Plan a stop from the approach's fastest state (the longest stop) and keep how long it took: this machine's
        planning time now, before a press needs it."""
        planned = run.planned
        k = int(np.argmax(planned.path.speeds))
        accelerations = np.gradient(planned.velocities, run.dt, axis=0)[k]
        began = time.time()
        brake(
            geometry, planned.positions[k], planned.velocities[k], accelerations, self.dt, run.deceleration, STOP_JERK
        )
        with self._lead_lock:
            self.lead.add("planning", time.time() - began)

    def _brake(
        self, geometry: PathGeometry, run: TrialRun, commanded: CommandedPath
    ) -> tuple[Braking | None, float, float, float]:
        """The replacement: braking from the controller's desired state a measured lead from now. (The braking,
        when it was sent, its stamp, its lead); (None, now, its stamp, NaN) when the plan comes to rest sooner (it
        goes on)."""
        began = time.time()
        with self._lead_lock:
            choice = self.lead.choose()
        at = began + choice.lead
        desired = self._query(at)
        planning = time.time()
        q = positions_by_name(desired.name, desired.position, self.robot.joint_names)
        qd = positions_by_name(desired.name, desired.velocity, self.robot.joint_names)
        qdd = positions_by_name(desired.name, desired.acceleration, self.robot.joint_names)
        stop = brake(geometry, q, qd, qdd, self.dt, run.deceleration, STOP_JERK)
        if stop is None or len(stop.times) < 2:  # the plan rests sooner, or it rests already
            return None, time.time(), at, math.nan
        points = GoalPoints(stop.times[1:], stop.positions[1:], stop.velocities[1:], stop.accelerations[1:])
        _, sent = self._send(points, at)
        with self._lead_lock:
            self.lead.add("planning", sent - planning)
        say(
            f"{self.name}: a stop stamped {choice.describe()}; sent {(sent - began) * 1e3:.1f} ms after its "
            f"preparation began ({'before' if sent < at else 'AFTER'} its stamp)"
        )
        commanded.add(at, stop.times, stop.positions)
        self._target = stop.positions[-1].copy()
        return stop, sent, at, choice.lead

    def _stop_approach(
        self, geometry: PathGeometry, run: TrialRun, commanded: CommandedPath, start: float, first: FedState
    ) -> tuple[Any, Braking | None, float, float, float]:
        """The approach's replacement: braking, or a hold where the arm waits when the approach (starting at
        `start`) has not begun. (Its handle, the braking, when it was sent, when it ends, the braking's lead: NaN
        when nothing brakes); handle None when the plan comes to rest sooner on its own."""
        braking, sent_at, at, lead = self._brake(geometry, run, commanded)
        if braking is not None:
            return self._handles[-1], braking, sent_at, at + braking.duration, lead
        if sent_at < start:
            handle, sent_at = self._hold(commanded, first.positions)
            return handle, None, sent_at, sent_at, math.nan
        return None, None, sent_at, -math.inf, math.nan

    @staticmethod
    def _refused(handle: Any) -> bool:
        return TrajectoryLink._done(handle) and int(handle.get_goal_status()) == REJECTED

    def _hold(self, commanded: CommandedPath, positions: np.ndarray) -> tuple[Any, float]:
        """A goal with no points, which a controller takes as "hold where you are": the replacement of an approach
        stopped before its start, where braking has nothing to slow down. Its handle and when it was sent."""
        nothing = np.zeros((0, self.robot.dof))
        handle, sent = self._send(GoalPoints(np.zeros(0), nothing, nothing, nothing), 0.0)
        commanded.add(sent, np.zeros(1), np.asarray(positions, dtype=float)[None, :])
        self._target = np.asarray(positions, dtype=float).copy()
        return handle, sent

    def _send(self, points: GoalPoints, stamp: float) -> tuple[Any, float]:
        """A goal of `points` stamped `stamp` (0: the controller's next update); its handle and when it was sent."""
        goal = self.types.goal()
        goal.trajectory = self._joint_trajectory(
            self.robot.joint_names, points.times, points.positions, points.velocities, points.accelerations, stamp
        )
        sent = time.time()
        handle = self.client.send_goal(goal, transition_cb=self._delivered(sent))
        self._handles.append(handle)
        return handle, sent

    def _delivered(self, sent: float) -> Any:
        """actionlib's transition callback for a goal sent at `sent`: the first status of it from the controller
        (accepted, or refused) ends its delivery, measured for the stops' lead."""
        from actionlib import CommState

        heard = threading.Event()

        def transition(handle: Any) -> None:
            if handle.get_comm_state() != CommState.WAITING_FOR_GOAL_ACK and not heard.is_set():
                heard.set()
                with self._lead_lock:
                    self.lead.add("delivery", time.time() - sent)

        return transition

    @staticmethod
    def _done(handle: Any) -> bool:
        from actionlib import CommState

        return bool(handle.get_comm_state() == CommState.DONE)

    @staticmethod
    def _outcome(handle: Any) -> tuple[int, int | None, str]:
        result = handle.get_result()
        if result is None:
            return int(handle.get_goal_status()), None, handle.get_goal_status_text()
        return int(handle.get_goal_status()), int(result.error_code), str(result.error_string)


def _applied(press: Press, now: float) -> tuple[AppliedPress, float]:
    """What is recorded of a press taken at `now` (wall time), and its time: its stamp, or when it arrived if it has
    none or one on another clock (a page that keeps the stream's /clock in a session of both links). Its lateness
    is from its stamp to `now`, when the replacement's braking is planned from."""
    arrived = press.arrival if math.isfinite(press.arrival) else now
    if press.stamp > 0 and abs(press.stamp - arrived) <= STAMP_WINDOW:
        late = max(now - press.stamp, 0.0)
        return AppliedPress(press.source, late, press.input_delay, press.arrival_delay), press.stamp
    return AppliedPress(press.source, 0.0, press.input_delay, math.nan), arrived
