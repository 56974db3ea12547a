"""The trajectory-controller link: a real arm's ros_control joint_trajectory_controller (or the physics node's
stand-in of it), on wall time. rospy and actionlib.

- No /clock: the link's clock is wall time carried by the monotonic clock (sim.study.run.links.clock), the time a
  driver stamps with. A motion (a move to a path's start, an approach) and a stop are stamped ahead by leads measured
  on this connection (sim.study.run.links.lead): the controller starts a goal at its stamp, so the link knows when
  the commanded path began, and a start in the past drops its first points.
- A motion is one follow_joint_trajectory goal: an approach of the planned samples, a move along the straight line
  in joint space to a path's start.
- A press is a replacement: sim.study.safety.braking's stop along the motion's path (the approach's, or the move's
  line), from the controller's desired state at the replacement's start, continuous in position, velocity and
  acceleration. The desired state comes from query_state; when the controller cannot be asked (the service gone, a
  connection broken, no answer in time), from the path the link commanded. A stop the controller refuses (it came
  after its last point was due) is planned and sent anew. A stop before the motion has begun is a rest at the
  motion's start, stamped like a braking. Never a bare cancel or an empty trajectory: with franka's
  stop_trajectory_duration of 0 either holds the measured position at once, a step that makes libfranka abort.
- Every exit of a motion brakes (sim.study.run.links.supervision's brakes_on_exit): an error, the observer's Ctrl-C
  or a SIGTERM, a lost query_state. During a motion, braking included, the link watches the arm until it rests: on
  each look it reads its feed, its clocks and the goal in force, and sim.study.run.links.supervision's watchdogs say
  whether to stop it on its own (the same replacement): the feed gone stale or bringing a malformed state, the wall
  clock stepped, the robot's clock off, the tracking error past the tolerance, the achieved distance to the hand off
  the commanded path's or under the floor, the speed and separation monitor, or the controller ending the goal
  otherwise than by success. Such a fault during braking, or a braking that does not succeed, ends the session.
  These are the toolkit's checks, never instead of the robot's own stop.
- If the runner's process dies (SIGKILL), nothing more is sent: the goal runs on to its end, at the stand-off at rest
  (ros_control's action server does not cancel a goal when its client goes away).

Goals are followed through actionlib's ActionClient, each by its own handle (SimpleActionClient drops a result that
comes before its send_goal has returned).
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np

from sim.control.controller_node import ControllerError
from sim.control.scenarios import approach
from sim.robots import RobotSpec
from sim.study.run.console import say
from sim.study.run.links.base import AppliedPress, ApproachOutcome, Press, SafetyStopped, TakePress
from sim.study.run.links.clock import SKEW_LIMIT, STEP_LIMIT, LinkClock
from sim.study.run.links.feed import FedState, JointFeed
from sim.study.run.links.goals import GOAL_STATUS, GoalPoints, goal_points, speed_fell
from sim.study.run.links.joint_line import MOVE_DECELERATION, MOVE_JERK, JointLine
from sim.study.run.links.lead import START, START_FLOOR, Leads, delivery_part
from sim.study.run.links.specs import TrajectoryLinkSpec
from sim.study.run.links.supervision import (
    POLL,
    RESULT_GRACE,
    Look,
    Motion,
    Tolerances,
    Watchdogs,
    brakes_on_exit,
    watched_to_rest,
)
from sim.study.run.trial import TrialRun, state_at
from sim.study.safety.braking import STOP_JERK, PathGeometry, arc_length, brake
from sim.study.safety.separation import PlannedTravel, SeparationMonitor, SeparationParameters
from sim.wire.contract import positions_by_name

__all__ = ["QUERY_PROBES", "TrajectoryLink"]

QUERY_PROBES = 10  # query_state round trips measured at connect, before any stop needs one
SKEW_STATES = 15  # joint states whose arrival against their stamps tells at connect whether the clocks agree
SKEW_WINDOW = 1.0  # s: the robot's clock is the least offset of the states that came in this long (feed.least_offset)
QUERY_TIMEOUT = 0.1  # s: a query_state answer later than this is not waited for (the stop brakes from the path)
PROBE_TIMEOUT = 2.0  # s: query_state's answer before a motion, which waits for it (no stop does)
SUCCEEDED = 3
REJECTED = 5
STAMP_WINDOW = 5.0  # s: a press stamped further from the wall clock is on another clock (the stream's /clock)
NO_QUERY = ("planning", "delivery")  # what a stop's preparation waits for when it brakes from the commanded path


class _Guard:
    """A motion as sim.study.run.links.supervision's brakes_on_exit sees it."""

    def __init__(self, link: TrajectoryLink, motion: Motion) -> None:
        self.link, self.motion = link, motion

    def settled(self) -> bool:
        motion = self.motion
        return motion.stopped or (self.link._done(motion.handle) and not self.link._failure(motion))

    def fail_safe(self, why: str) -> None:
        self.link._fail_safe(self.motion, why)


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
        self._clock = LinkClock()
        ns = spec.namespace
        self.client = actionlib.ActionClient(f"{ns}/follow_joint_trajectory", self.types.action)
        self._proxy: Any = None  # query_state's persistent proxy, made anew after a failure (see _query)
        self.feed = JointFeed(robot, self._clock)
        self.subscriber = rospy.Subscriber(
            spec.joint_states_topic, JointState, self.feed.callback, tcp_nodelay=True, queue_size=1000
        )
        self._target = robot.home.copy()
        self.lead = Leads()  # the delays measured on this connection, and the leads they give
        self._lead_lock = threading.Lock()  # goals' deliveries are measured on actionlib's threads
        self._connected = False
        tolerances = Tolerances(spec.stale_after, spec.tracking_tolerance, spec.surface_tolerance, spec.floor)
        self._watchdogs = Watchdogs(tolerances, 0.0, spec.speed_scale)  # its skew is measured at connect

    # --- RobotLink -------------------------------------------------------------------------------------------
    @property
    def clock(self) -> float:
        return self._clock()

    def now(self) -> float:
        return self._clock()

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
            self.rospy.wait_for_service(f"{ns}/query_state", timeout)
        except self.rospy.ROSException:
            raise ControllerError(f"no service {ns}/query_state within {timeout:g} s") from None
        for _ in range(QUERY_PROBES):
            self._query(self._clock(), timeout)
        if self.feed.wait(-math.inf, timeout, self.stop) is None:
            raise ControllerError(f"no joint state on {self.spec.joint_states_topic} within {timeout:g} s")
        skew = self._clocks_agree(timeout)
        self._watchdogs = Watchdogs(self._watchdogs.tolerances, skew, self.spec.speed_scale)
        self._connected = True
        topic, skew = self.spec.joint_states_topic, skew * 1e3
        return f"trajectory controller {ns} (the arm's joint states on {topic}, arriving {skew:+.1f} ms after stamping)"

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
        """A quintic from where the arm is along the straight line in joint space, as one goal, supervised like an
        approach to its end; SafetyStopped when the link stopped it on its own (the arm then rests on the line)."""
        here = self._begin_motion().positions
        there = np.asarray(positions, dtype=float)
        if float(np.linalg.norm(there - here)) <= 1e-6:
            return here
        samples, speeds = approach(self.robot, here, there, self.dt)
        points = goal_points(samples, speeds, self.dt)
        line = JointLine(here, there)
        accelerations = np.gradient(speeds, self.dt, axis=0)
        self._time_planning(line, samples, speeds, accelerations, MOVE_DECELERATION, MOVE_JERK)
        motion, _ = self._go("the move to the path's start", line, MOVE_DECELERATION, MOVE_JERK, samples[0], points)
        self._target = there.copy()
        with brakes_on_exit(_Guard(self, motion)):
            self._supervise(motion, None, None, 0.0)
        self._target = self._latest().positions.copy()
        why = motion.reason or motion.after_stop or self._failure(motion)
        if why:
            raise SafetyStopped(f"{motion.what} was stopped: {why}")
        return self._target

    def approach(self, run: TrialRun, take_press: TakePress, settle: float) -> ApproachOutcome:
        planned = run.planned
        first = self._begin_motion()
        run.record_state(0.0, first.positions)
        geometry = PathGeometry(planned.path, planned.positions)
        accelerations = np.gradient(planned.velocities, run.dt, axis=0)
        self._time_planning(geometry, planned.positions, planned.velocities, accelerations, run.deceleration, STOP_JERK)
        points = goal_points(planned.positions, planned.velocities, run.dt, self.spec.speed_scale)
        rest = planned.positions[0]
        motion, start_lead = self._go("the approach", geometry, run.deceleration, STOP_JERK, rest, points)
        path = planned.path
        tracked = run.hand is not None and run.hand.tracked
        motion.monitor = SeparationMonitor(
            SeparationParameters(floor=self.spec.floor, deceleration=run.deceleration),
            tracked,
            PlannedTravel(path.times, planned.distances, arc_length(path), path.speeds),
        )
        self._target = planned.positions[-1].copy()
        with brakes_on_exit(_Guard(self, motion)):
            applied, press_at, tracking = self._supervise(motion, run, take_press, settle)
        handle = motion.handle
        status, code, text = self._outcome(handle) if self._done(handle) else (-1, None, "no result")
        seen = self.feed.since(motion.start)
        stamps = np.array([s.stamp for s in seen])
        speeds = np.array([float(np.linalg.norm(s.velocities)) for s in seen])
        achieved = math.nan
        if not math.isnan(press_at) and seen:
            at_press = state_at([(s.stamp, s.positions) for s in seen], press_at)  # as the trial's measures are
            zeros = np.zeros(self.robot.dof)
            rest = geometry.project(seen[-1].positions, zeros, zeros)
            achieved = rest.arc - geometry.project(at_press, zeros, zeros).arc
        self._target = seen[-1].positions.copy() if seen else self._target
        safety_stop = "; ".join(
            why for why in (motion.reason, motion.after_stop and f"then {motion.after_stop}", self._failure(motion))
            if why
        )  # fmt: skip
        return ApproachOutcome(
            motion_start=motion.start,  # the goal's stamp: the controller starts the arm there
            speed_scale=self.spec.speed_scale,
            press=applied,
            goal_result=GOAL_STATUS.get(status, "NO RESULT"),
            error_code=code,
            tracking_error=tracking,
            replacement_sent=motion.stop_sent - press_at,
            braking_began=speed_fell(stamps, speeds, press_at) if seen and not math.isnan(press_at) else math.nan,
            braking_planned=motion.braking.distance if motion.braking is not None else math.nan,
            braking_achieved=achieved,
            safety_stop=safety_stop,
            start_lead=start_lead,
            stop_lead=motion.stop_lead,
            hand_monitored="tracked" if tracked else "untracked",
            least_separation_predicted=motion.monitor.least_predicted,
            least_separation=motion.least_separation if math.isfinite(motion.least_separation) else math.nan,
        )

    def close(self) -> None:
        if self._connected:  # the lead the session ended with, for the lab's record
            with self._lead_lock:
                say(f"{self.name}: a stop would now be stamped {self.lead.choose().describe()}")
        self.subscriber.unregister()
        if self._proxy is not None:
            self._proxy.close()
        client = self.client
        for endpoint in (client.pub_goal, client.pub_cancel, client.status_sub, client.result_sub, client.feedback_sub):
            endpoint.unregister()

    def _clocks_agree(self, timeout: float) -> float:
        """s: how far the joint states arrive after their stamps (the robot's clock behind this machine's, plus their
        quickest delivery), the least of the first SKEW_STATES and more; ControllerError naming the disagreement beyond
        SKEW_LIMIT: a goal's stamp, the tracking and every lead assume the two clocks agree."""
        deadline = self._clock() + timeout
        while self.feed.count() < SKEW_STATES and self._clock() < deadline and not self.stop.is_set():
            self.feed.wait(self._clock(), POLL, self.stop)
        skew = self.feed.least_offset(SKEW_WINDOW)
        if skew is None:
            raise ControllerError(f"no joint state on {self.spec.joint_states_topic} within {timeout:g} s")
        if abs(skew) > SKEW_LIMIT:
            raise ControllerError(
                f"the robot's clock and this machine's disagree: its joint states on {self.spec.joint_states_topic} "
                f"arrive {skew:+.3f} s after their stamps (limit {SKEW_LIMIT:g} s); synchronise the clocks (chrony)"
            )
        return skew

    # --- a motion --------------------------------------------------------------------------------------------
    def _begin_motion(self) -> FedState:
        """Before a motion: the link's clock anchored to the wall clock again, query_state answering, and a fresh
        good joint state (which it returns). ControllerError when one is missing: no motion starts."""
        step = self._clock.step()
        if abs(step) > STEP_LIMIT:
            say(f"{self.name}: the wall clock stepped {step:+.3f} s since the last motion; anchored to it again")
        self._clock.anchor()
        try:
            self._query(self._clock(), PROBE_TIMEOUT)
        except ControllerError:  # a controller restarted since: its query_state is found anew
            self._query(self._clock(), PROBE_TIMEOUT)
        return self._latest()

    def _go(
        self,
        what: str,
        geometry: PathGeometry | JointLine,
        deceleration: float,
        jerk: float,
        rest: np.ndarray,
        points: GoalPoints,
    ) -> tuple[Motion, float]:
        """The motion's goal, stamped a start lead ahead; the motion and its lead."""
        with self._lead_lock:
            lead = max(self.lead.choose(START).lead, START_FLOOR)
        start = self._clock() + lead
        motion = Motion(what, geometry, deceleration, jerk, start, start + points.duration, start + points.duration)
        motion.commanded.add(
            start,
            np.concatenate([[0.0], points.times]),
            np.vstack([rest, points.positions]),
            np.vstack([np.zeros_like(rest), points.velocities]),
            np.vstack([np.zeros_like(rest), points.accelerations]),
        )
        handle, _ = self._send(points, start)
        motion.handles.append(handle)
        return motion, lead

    def _supervise(
        self, motion: Motion, run: TrialRun | None, take_press: TakePress | None, settle: float
    ) -> tuple[AppliedPress | None, float, float]:
        """Watch the motion until it rests `settle` s after its end, stopping it on a press (`take_press`) or on its
        own. The press applied, its time (the link's clock; NaN: none), and the largest tracking error (rad)."""
        applied: AppliedPress | None = None
        press_at = math.nan
        tracking = 0.0
        looked = self._clock() - self.spec.stale_after  # the first look takes the states of the last stale_after s
        while True:
            self.feed.wait(looked, POLL, self.stop)  # a new state, or POLL s without one: never a spin
            now = self._clock()
            if self.stop.is_set():
                raise ControllerError("interrupted")  # the guard brakes
            for fed in self.feed.since(looked):
                looked = fed.arrival  # each state once
                if fed.stamp >= motion.start:
                    if run is not None:  # on the plan's time, as the press is (slower in the rehearsal)
                        run.record_state((fed.stamp - motion.start) * self.spec.speed_scale, fed.positions)
                    unsure = motion.replaced and not self._taken(motion.handle)
                    tracking = max(tracking, motion.commanded.error(fed.stamp, fed.positions, unsure))
            why = self._unsafe(now, tracking, run, motion)
            if not motion.stopped:
                press = take_press(now) if take_press is not None else None
                if press is not None or why:
                    press_at = now
                    if press is not None:
                        applied, when = _applied(press, now)
                        press_at = min(max(when, motion.start), now)
                    else:
                        motion.reason = why
                    if run is not None:
                        elapsed = max(press_at - motion.start, 0.0) * self.spec.speed_scale
                        run.press(min(elapsed, run.planned.path.duration))
                    self._stop(motion)
            else:
                if why and not motion.after_stop:
                    motion.after_stop = why
                    say(f"{self.name}: while {motion.what} was stopping: {why}")
                self._stop_anew_if_refused(motion)
            if watched_to_rest(now, motion, settle, self._done(motion.handle)):
                return applied, press_at, tracking

    def _unsafe(self, now: float, tracking: float, run: TrialRun | None, motion: Motion) -> str:
        """Why the arm must be stopped now ("" when it need not): what the link sees, judged by the watchdogs."""
        return self._watchdogs.reason(self._look(now, tracking, run, motion), motion)

    def _look(self, now: float, tracking: float, run: TrialRun | None, motion: Motion) -> Look:
        """What the link sees of `motion` at `now`, the largest tracking error so far `tracking` (rad)."""
        latest = self.feed.latest()
        surface_off = distance = math.nan
        if run is not None and latest is not None:
            if latest.stamp >= motion.start:
                achieved = run.hand_distance(latest.positions)
                unsure = motion.replaced and not self._taken(motion.handle)
                possible = motion.commanded.possible(latest.stamp, unsure)
                surface_off = min(abs(achieved - run.hand_distance(q)) for q in possible)
            if now < motion.moves_until:  # a hand coming on to an arm at rest is the person's own move
                distance = run.live_hand_distance(latest.positions)
        hand = run.hand if run is not None else None
        with self._lead_lock:
            stop_lead = self.lead.choose().lead
        return Look(
            now=now,
            latest=latest,
            faults=self.feed.faults_since(motion.start - self.spec.stale_after),
            clock_step=self._clock.step(),
            least_offset=self.feed.least_offset(SKEW_WINDOW),
            tracking=tracking,
            surface_off=surface_off,
            distance=distance,
            hand_places=hand.places_after(motion.hand_seen) if hand is not None else [],
            stop_lead=stop_lead,
            goal_failure=self._failure(motion),
        )

    def _failure(self, motion: Motion) -> str:
        """How the goal in force ended, if not by success ("" while it runs, and when it succeeded)."""
        if not self._done(motion.handle):
            return ""
        status, code, text = self._outcome(motion.handle)
        if status == SUCCEEDED or (status == REJECTED and motion.replaced):
            return ""  # a refused stop is sent anew
        goal = "the braking replacement" if motion.replaced else "the controller ended the goal"
        return f"{goal} {'ended ' if motion.replaced else ''}{GOAL_STATUS.get(status, status)} ({code}): {text}"

    # --- the stop --------------------------------------------------------------------------------------------
    def _stop(self, motion: Motion) -> None:
        """The motion's replacement: braking from the controller's desired state a measured lead from now (from the
        commanded path when the controller cannot be asked in the lead's time for it), or a rest where the motion has
        not begun. A stop whose preparation overran its stamp (it would reach the controller after its braking was
        due, and be bridged to with a jerk) is planned anew, later, from the commanded path. Leaves the motion
        stopped; sends nothing when the plan rests sooner than braking would."""
        motion.stopped = True
        began = self._clock()
        with self._lead_lock:
            choice = self.lead.choose()
        at = began + choice.lead
        after_query = sum(value for part, value in choice.parts.items() if part != "query" and math.isfinite(value))
        source = ""
        try:  # the query may take what the lead left it: then planning and delivery must still fit
            desired = self._query(at, min(max(at - after_query - began, 0.0), QUERY_TIMEOUT))
            q = positions_by_name(desired.name, desired.position, self.robot.joint_names)
            qd = positions_by_name(desired.name, desired.velocity, self.robot.joint_names)
            qdd = positions_by_name(desired.name, desired.acceleration, self.robot.joint_names)
        except Exception as error:  # the stop must go out whatever became of query_state
            q, qd, qdd = motion.commanded.state(at)
            source = f" from the commanded path ({error})"
        planning = self._clock()
        braking = brake(motion.geometry, q, qd, qdd, self.dt, motion.deceleration, motion.jerk)
        delivery = choice.parts.get("delivery", math.nan)
        if self._clock() + (delivery if math.isfinite(delivery) else 0.0) > at:
            with self._lead_lock:
                choice = self.lead.choose(NO_QUERY)
            left = at - self._clock()
            at = self._clock() + choice.lead
            q, qd, qdd = motion.commanded.state(at)
            braking = brake(motion.geometry, q, qd, qdd, self.dt, motion.deceleration, motion.jerk)
            source += f"; planned anew from the commanded path ({left * 1e3:.1f} ms to its stamp were too few)"
        if braking is not None and len(braking.times) >= 2:
            points = GoalPoints(
                braking.times[1:], braking.positions[1:], braking.velocities[1:], braking.accelerations[1:]
            )
            motion.commanded.add(at, braking.times, braking.positions, braking.velocities, braking.accelerations)
            motion.braking, motion.stop_lead = braking, choice.lead
            what = "a stop"
        elif braking is not None and at < motion.ends:
            # At rest while the link commanded motion: it has not begun, or the controller has not yet taken its
            # goal. A rest where it waits, stamped like a braking (never a cancel, which holds with a step).
            points = GoalPoints(np.array([self.dt]), q[None, :], np.zeros((1, len(q))), np.zeros((1, len(q))))
            motion.commanded.add(at, np.array([0.0, self.dt]), np.vstack([q, q]))
            motion.braking, motion.stop_lead = None, math.nan
            what = "a rest"
        else:
            return  # the plan rests sooner than braking would (or rests already): it is its own stop
        motion.moves_until = at + points.duration
        motion.ends = max(motion.ends, motion.moves_until)  # watched to the motion's planned end at least
        handle, sent = self._send(points, at)
        motion.handles.append(handle)
        motion.stop_sent = sent
        with self._lead_lock:
            self.lead.add("planning", sent - planning)
        self._target = points.positions[-1].copy()
        say(
            f"{self.name}: {what} stamped {choice.describe()}{source}; sent {(sent - began) * 1e3:.1f} ms after its "
            f"preparation began ({'before' if sent < at else 'AFTER'} its stamp)"
        )

    def _stop_anew_if_refused(self, motion: Motion) -> None:
        """The controller refused the stop (it came after its last point was due, on a starved machine), so the
        motion goes on: forget it was commanded, and stop the motion anew from where it is now commanded to be."""
        if motion.replaced and self._refused(motion.handle):
            motion.commanded.discard_last()
            motion.handles.pop()
            self._stop(motion)

    def _fail_safe(self, motion: Motion, why: str) -> None:
        """The guard's stop on an exit of the motion's code: brake, then watch the arm to rest (not stopped by the
        stop event, which may be why). Never raises: it says what it could not do."""
        try:
            if not motion.stopped:
                say(f"{self.name}: {motion.what} left ({why}): braking")
                motion.reason = motion.reason or f"the motion's code exited: {why}"
                self._stop(motion)
            while self._clock() < motion.ends + RESULT_GRACE and not self._done(motion.handle):
                self.feed.wait(self._clock(), POLL)
                self._stop_anew_if_refused(motion)
            failed = self._failure(motion)
            say(f"{self.name}: {motion.what}: {failed or 'the arm braked to rest'}")
        except BaseException as error:  # noqa: BLE001 — the exit goes on; the observer must know
            say(f"{self.name}: could not brake {motion.what}: {type(error).__name__}: {error}")

    # --- the parts -------------------------------------------------------------------------------------------
    def _latest(self) -> FedState:
        """The latest good joint state, once one is fresh (ControllerError after stale_after s without)."""
        state = self.feed.wait(self._clock() - self.spec.stale_after, self.spec.stale_after, self.stop)
        latest = self.feed.latest()
        if state is None or latest is None or self._clock() - latest.arrival > self.spec.stale_after:
            raise ControllerError(f"no joint state on {self.spec.joint_states_topic} for {self.spec.stale_after:g} s")
        return latest

    def _query(self, at: float, timeout: float) -> Any:
        """query_state's answer for link time `at`, its round trip measured for the stops' lead. ControllerError when
        it fails or has not answered within `timeout` s. rospy's persistent proxy does not reconnect: after a
        failure it is closed (which also ends a call stuck on its socket) and the next query makes a new one."""
        if self._proxy is None:
            self._proxy = self.rospy.ServiceProxy(
                f"{self.spec.namespace}/query_state", self.types.query_state, persistent=True
            )
        proxy, answer = self._proxy, {}
        asked = self._clock()

        def ask() -> None:
            try:
                answer["desired"] = proxy(self.rospy.Time.from_sec(at))
            except Exception as error:  # rospy's ServiceException, ROSException, a closed socket's OSError
                answer["error"] = error

        worker = threading.Thread(target=ask, name="query_state", daemon=True)
        worker.start()
        worker.join(timeout)
        if "desired" in answer:
            with self._lead_lock:
                self.lead.add("query", self._clock() - asked)
            return answer["desired"]
        failure = answer.get("error") or f"no answer within {timeout * 1e3:.0f} ms"  # before closing fails the call
        self._proxy = None
        proxy.close()
        raise ControllerError(f"{self.spec.namespace}/query_state failed: {failure}")

    def _time_planning(
        self,
        geometry: PathGeometry | JointLine,
        positions: np.ndarray,
        velocities: np.ndarray,
        accelerations: np.ndarray,
        deceleration: float,
        jerk: float,
    ) -> None:
        """Plan a stop from the motion's fastest sample (the longest stop) and keep how long it took: this machine's
        planning time now, before a press needs it."""
        k = int(np.argmax(np.linalg.norm(velocities, axis=1)))
        began = self._clock()
        brake(geometry, positions[k], velocities[k], accelerations[k], self.dt, deceleration, jerk)
        with self._lead_lock:
            self.lead.add("planning", self._clock() - began)

    @staticmethod
    def _taken(handle: Any) -> bool:
        """The controller has said it took the goal (not yet heard of, or refused: not taken)."""
        from actionlib import CommState

        heard = handle.get_comm_state() != CommState.WAITING_FOR_GOAL_ACK
        return bool(heard and not TrajectoryLink._refused(handle))

    @staticmethod
    def _refused(handle: Any) -> bool:
        """The controller has said it refused the goal: its status says REJECTED, which is final. Not only once the
        goal is done: actionlib's handle is done when the result comes, which the server sends on a topic of its own
        (the status array on another), and the status may come first. Until the result, the handle waits for it with
        the status REJECTED: counted as taken then, the refused stop was taken for the arm's path, and the arm, going
        on with the approach it was refused in, was found 34.6 mm off it (a machine beside two CPU burners)."""
        return int(handle.get_goal_status()) == REJECTED

    def _send(self, points: GoalPoints, stamp: float) -> tuple[Any, float]:
        """A goal of `points` stamped `stamp` (the link's clock); its handle and when it was sent."""
        goal = self.types.goal()
        goal.trajectory = self._joint_trajectory(
            self.robot.joint_names, points.times, points.positions, points.velocities, points.accelerations, stamp
        )
        sent = self._clock()
        handle = self.client.send_goal(goal, transition_cb=self._delivered(sent, delivery_part(len(points.times))))
        return handle, sent

    def _delivered(self, sent: float, part: str) -> Any:
        """actionlib's transition callback for a goal sent at `sent`: the first status of it from the controller
        (accepted, or refused) ends its delivery, measured for the leads as `part`."""
        from actionlib import CommState

        heard = threading.Event()

        def transition(handle: Any) -> None:
            if handle.get_comm_state() != CommState.WAITING_FOR_GOAL_ACK and not heard.is_set():
                heard.set()
                with self._lead_lock:
                    self.lead.add(part, self._clock() - sent)

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
    """What is recorded of a press taken at `now` (the link's clock), and its time: its stamp, or when it arrived if
    it has none or one on another clock (a page that keeps the stream's /clock in a session of both links). Its
    lateness is from its stamp to `now`, when the replacement's braking is planned from."""
    arrived = press.arrival if math.isfinite(press.arrival) else now
    if press.stamp > 0 and abs(press.stamp - arrived) <= STAMP_WINDOW:
        late = max(now - press.stamp, 0.0)
        return AppliedPress(press.source, late, press.input_delay, press.arrival_delay), press.stamp
    return AppliedPress(press.source, 0.0, press.input_delay, math.nan), arrived
