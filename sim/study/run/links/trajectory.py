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
  The move to a path's start is watched against the trial's hand as the approach is: its live place, and the speed
  and separation monitor with the move's own samples along its joint line as the plan. These are the toolkit's
  checks, never instead of the robot's own stop.
- If the runner's process dies (SIGKILL), nothing more is sent: the goal runs on to its end, at the stand-off at rest
  (ros_control's action server does not cancel a goal when its client goes away).

The controller's action and query_state, and the measuring of their deliveries, are sim.study.run.links.controller's.

Long because a motion is one life: its going, its watching and its stop share the goal in force, the clocks and the path
commanded. What stands alone already does: the watchdogs' rules (supervision), the controller's wire (controller), the
leads (lead).
"""

from __future__ import annotations

import math
import threading

import numpy as np

from sim.control.controller_node import ControllerError
from sim.control.scenarios import approach
from sim.robots import RobotSpec
from sim.study.run.console import say
from sim.study.run.links.base import AppliedPress, ApproachOutcome, Press, SafetyStopped, TakePress
from sim.study.run.links.clock import SKEW_LIMIT, STEP_LIMIT, LinkClock, RobotClockSpan
from sim.study.run.links.controller import REJECTED, SUCCEEDED, Controller
from sim.study.run.links.feed import FedState, JointFeed
from sim.study.run.links.goals import GOAL_STATUS, GoalPoints, goal_points, speed_fell
from sim.study.run.links.hand import HandWatch
from sim.study.run.links.joint_line import MOVE_DECELERATION, MOVE_JERK, JointLine
from sim.study.run.links.lead import START, START_FLOOR, Leads
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
STAMP_WINDOW = 5.0  # s: a press stamped further from the wall clock is on another clock (the stream's /clock)
NO_QUERY = ("planning", "delivery")  # what a stop's preparation waits for when it brakes from the commanded path


class _Guard:
    """A motion as sim.study.run.links.supervision's brakes_on_exit sees it."""

    def __init__(self, link: TrajectoryLink, motion: Motion) -> None:
        self.link, self.motion = link, motion

    def settled(self) -> bool:
        motion = self.motion
        return motion.stopped or (self.link.controller.done(motion.handle) and not self.link._failure(motion))

    def fail_safe(self, why: str) -> None:
        self.link._fail_safe(self.motion, why)


class TrajectoryLink:
    """One trajectory controller: its action, its query_state service and the arm's joint states."""

    realtime = True

    def __init__(self, robot: RobotSpec, spec: TrajectoryLinkSpec, dt: float, stop: threading.Event) -> None:
        import rospy
        from sensor_msgs.msg import JointState

        self.rospy, self.robot, self.spec, self.dt, self.stop = rospy, robot, spec, dt, stop
        self.name = spec.label
        self._clock = LinkClock()
        self.lead = Leads()  # the delays measured on this connection, and the leads they give
        self._lead_lock = threading.Lock()  # goals' deliveries are measured on actionlib's threads
        self.controller = Controller(rospy, spec.namespace, robot.joint_names, self._clock, self.lead, self._lead_lock)
        self.feed = JointFeed(robot, self._clock)
        self.subscriber = rospy.Subscriber(
            spec.joint_states_topic, JointState, self.feed.callback, tcp_nodelay=True, queue_size=1000
        )
        self._target = robot.home.copy()
        self._connected = False
        tolerances = Tolerances(spec.stale_after, spec.tracking_tolerance, spec.surface_tolerance, spec.floor)
        self._watchdogs = Watchdogs(tolerances, 0.0)  # its skew is measured at connect
        self._move_least = math.nan  # m: the last move's least separation, for the next approach's outcome

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
        if not self.controller.wait_for_server(timeout):
            raise ControllerError(f"no action server {ns}/follow_joint_trajectory within {timeout:g} s")
        try:
            self.rospy.wait_for_service(f"{ns}/query_state", timeout)
        except self.rospy.ROSException:
            raise ControllerError(f"no service {ns}/query_state within {timeout:g} s") from None
        for _ in range(QUERY_PROBES):
            self.controller.query(self._clock(), timeout)
        if self.feed.wait(-math.inf, timeout, self.stop) is None:
            raise ControllerError(f"no joint state on {self.spec.joint_states_topic} within {timeout:g} s")
        skew = self._clocks_agree(timeout)
        self._watchdogs = Watchdogs(self._watchdogs.tolerances, skew)
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

    def move_to(self, positions: np.ndarray, hand: HandWatch | None = None) -> np.ndarray:
        """A quintic from where the arm is along the straight line in joint space, as one goal, supervised like an
        approach to its end, against the trial's `hand` when given (its live place for the floor, and speed and
        separation monitoring with the move's own samples as the plan, from the goal's start); SafetyStopped when the
        link stopped it on its own (the arm then rests on the line)."""
        self._move_least = math.nan
        here = self._begin_motion().positions
        there = np.asarray(positions, dtype=float)
        if float(np.linalg.norm(there - here)) <= 1e-6:
            return here
        samples, speeds = approach(self.robot, here, there, self.dt)
        points = goal_points(samples, speeds, self.dt)
        line = JointLine(here, there)
        accelerations = np.gradient(speeds, self.dt, axis=0)
        self._time_planning(line, samples, speeds, accelerations, MOVE_DECELERATION, MOVE_JERK)
        travel = None
        if hand is not None:
            travel = line.travel(samples, speeds, self.dt, np.array([hand.hand_distance(q) for q in samples]))
        motion, _ = self._go("the move to the path's start", line, MOVE_DECELERATION, MOVE_JERK, samples[0], points)
        self._target = there.copy()
        with brakes_on_exit(_Guard(self, motion)):
            self._supervise(motion, None, None, 0.0, hand, travel)
        self._move_least = motion.least_separation if math.isfinite(motion.least_separation) else math.nan
        self._target = self._latest().positions.copy()
        why = motion.reason or motion.after_stop or self._failure(motion)
        if why:
            raise SafetyStopped(f"{motion.what} was stopped: {why}")
        return self._target

    def approach(self, run: TrialRun, take_press: TakePress, settle: float) -> ApproachOutcome:
        planned = run.planned
        first = self._begin_motion()
        robot_clock = RobotClockSpan(self._robot_offset())  # the press and the start are placed on this machine's clock
        run.record_state(0.0, first.positions)
        geometry = PathGeometry(planned.path, planned.positions)
        accelerations = np.gradient(planned.velocities, run.dt, axis=0)
        self._time_planning(geometry, planned.positions, planned.velocities, accelerations, run.deceleration, STOP_JERK)
        points = goal_points(planned.positions, planned.velocities, run.dt, self.spec.speed_scale)
        rest = planned.positions[0]
        motion, start_lead = self._go("the approach", geometry, run.deceleration, STOP_JERK, rest, points)
        motion.speed_scale = self.spec.speed_scale
        path = planned.path
        tracked = run.hand is not None and run.hand.tracked
        motion.monitor = SeparationMonitor(
            SeparationParameters(floor=self.spec.floor, deceleration=run.deceleration),
            tracked,
            PlannedTravel(path.times, planned.distances, arc_length(path), path.speeds),
        )
        self._target = planned.positions[-1].copy()
        motion.robot_clock = robot_clock
        with brakes_on_exit(_Guard(self, motion)):
            applied, press_at, tracking = self._supervise(motion, run, take_press, settle)
        press_stamp = robot_clock.on_robot_clock(press_at)  # as the joint states are stamped (NaN stays NaN)
        handle = motion.handle
        status, code, text = (
            self.controller.outcome(handle) if self.controller.done(handle) else (-1, None, "no result")
        )
        seen = self.feed.since(motion.start)
        stamps = np.array([s.stamp for s in seen])
        speeds = np.array([float(np.linalg.norm(s.velocities)) for s in seen])
        achieved = math.nan
        if not math.isnan(press_at) and seen:
            at_press = state_at([(s.stamp, s.positions) for s in seen], press_stamp)  # as the trial's measures are
            zeros = np.zeros(self.robot.dof)
            rest = geometry.project(seen[-1].positions, zeros, zeros)
            achieved = rest.arc - geometry.project(at_press, zeros, zeros).arc
        self._target = seen[-1].positions.copy() if seen else self._target
        safety_stop = "; ".join(
            why for why in (motion.reason, motion.after_stop and f"then {motion.after_stop}", self._failure(motion))
            if why
        )  # fmt: skip
        return ApproachOutcome(
            # the goal's stamp, at which the controller starts the arm on the robot's clock, on the runner's
            motion_start=motion.start + robot_clock.offset,
            speed_scale=self.spec.speed_scale,
            press=applied,
            goal_result=GOAL_STATUS.get(status, "NO RESULT"),
            error_code=code,
            tracking_error=tracking,
            replacement_sent=motion.stop_sent - press_at,
            braking_began=speed_fell(stamps, speeds, press_stamp) if seen and not math.isnan(press_at) else math.nan,
            braking_planned=motion.braking.distance if motion.braking is not None else math.nan,
            braking_achieved=achieved,
            safety_stop=safety_stop,
            start_lead=start_lead,
            stop_lead=motion.stop_lead,
            hand_monitored="tracked" if tracked else "untracked",
            least_separation_predicted=motion.monitor.least_predicted,
            least_separation=motion.least_separation if math.isfinite(motion.least_separation) else math.nan,
            robot_clock_offset=robot_clock.offset,
            robot_clock_drift=robot_clock.drift,
            move_least_separation=self._move_least,
        )

    @property
    def clock_offset(self) -> float:
        """s: the robot's clock behind this machine's as measured at connect (NaN before)."""
        return self._watchdogs.skew if self._connected else math.nan

    def _robot_offset(self) -> float:
        """s: the robot's clock behind this machine's now, the least offset of the last joint states."""
        offset = self.feed.least_offset(SKEW_WINDOW)
        if offset is None:
            raise ControllerError(f"no joint state on {self.spec.joint_states_topic}")
        return offset

    def close(self) -> None:
        if self._connected:  # the lead the session ended with, for the lab's record
            with self._lead_lock:
                say(f"{self.name}: a stop would now be stamped {self.lead.choose().describe()}")
        self.subscriber.unregister()
        self.controller.close()

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
            self.controller.query(self._clock(), PROBE_TIMEOUT)
        except ControllerError:  # a controller restarted since: its query_state is found anew
            self.controller.query(self._clock(), PROBE_TIMEOUT)
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
        handle, _ = self.controller.send(points, start)
        motion.handles.append(handle)
        return motion, lead

    def _supervise(
        self,
        motion: Motion,
        run: TrialRun | None,
        take_press: TakePress | None,
        settle: float,
        hand: HandWatch | None = None,
        travel: PlannedTravel | None = None,
    ) -> tuple[AppliedPress | None, float, float]:
        """Watch the motion until it rests `settle` s after its end, stopping it on a press (`take_press`) or on its
        own, against the approach's `run` or a move's `hand`. A move's `travel` is monitored for speed and separation
        from the goal's start on: whether a tracker follows the hand is read then, once the trial's first poses have
        come. The press applied, its time (the link's clock; NaN: none), and the largest tracking error (rad)."""
        hand = run.hand if run is not None else hand
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
                    unsure = motion.replaced and not self.controller.taken(motion.handle)
                    tracking = max(tracking, motion.commanded.error(fed.stamp, fed.positions, unsure))
            if travel is not None and hand is not None and motion.monitor is None and now >= motion.start:
                parameters = SeparationParameters(self.spec.floor, deceleration=MOVE_DECELERATION, jerk=MOVE_JERK)
                motion.monitor = SeparationMonitor(parameters, hand.tracked, travel)
            why = self._unsafe(now, tracking, motion, run, hand)
            if not motion.stopped:
                press = take_press(now) if take_press is not None else None
                if press is not None or why:
                    press_at = now
                    if press is not None:
                        applied, when = _applied(press, now)
                        press_at = min(max(when, motion.start), now)
                    else:
                        motion.reason = why
                    if run is not None:  # the press on the robot's clock, as the arm's start and states are
                        on_robot = motion.robot_clock.on_robot_clock(press_at) if motion.robot_clock else press_at
                        elapsed = max(on_robot - motion.start, 0.0) * self.spec.speed_scale
                        run.press(min(elapsed, run.planned.path.duration))
                    self._stop(motion)
            else:
                if why and not motion.after_stop:
                    motion.after_stop = why
                    say(f"{self.name}: while {motion.what} was stopping: {why}")
                self._stop_anew_if_refused(motion)
            if watched_to_rest(now, motion, settle, self.controller.done(motion.handle)):
                return applied, press_at, tracking

    def _unsafe(self, now: float, tracking: float, motion: Motion, run: TrialRun | None, hand: HandWatch | None) -> str:
        """Why the arm must be stopped now ("" when it need not): what the link sees, judged by the watchdogs."""
        return self._watchdogs.reason(self._look(now, tracking, motion, run, hand), motion)

    def _look(self, now: float, tracking: float, motion: Motion, run: TrialRun | None, hand: HandWatch | None) -> Look:
        """What the link sees of `motion` at `now`, the largest tracking error so far `tracking` (rad): against an
        approach's `run`, the distance to the hand off the commanded path's, and for an approach or a move, the
        distance to the `hand`'s live place (the run's hand) and its tracked places. A move's tracking error is
        judged in joint space (the floor and the separation judge the achieved state's distance): the surface
        tolerance is an approach's, sized for its end near the hand."""
        latest = self.feed.latest()
        surface_off = distance = math.nan
        if run is not None and latest is not None and latest.stamp >= motion.start:
            achieved = run.hand_distance(latest.positions)
            unsure = motion.replaced and not self.controller.taken(motion.handle)
            possible = motion.commanded.possible(latest.stamp, unsure)
            surface_off = min(abs(achieved - run.hand_distance(q)) for q in possible)
        live = run.live_hand_distance if run is not None else hand.live_hand_distance if hand is not None else None
        if live is not None and latest is not None and now < motion.moves_until:
            distance = live(latest.positions)  # a hand coming on to an arm at rest is the person's own move
        with self._lead_lock:
            stop_lead = self.lead.choose().lead
        least_offset = self.feed.least_offset(SKEW_WINDOW)
        if motion.robot_clock is not None:
            motion.robot_clock.looked(least_offset)
        return Look(
            now=now,
            latest=latest,
            faults=self.feed.faults_since(motion.start - self.spec.stale_after),
            clock_step=self._clock.step(),
            least_offset=least_offset,
            tracking=tracking,
            surface_off=surface_off,
            distance=distance,
            hand_places=hand.places_after(motion.hand_seen) if hand is not None else [],
            stop_lead=stop_lead,
            goal_failure=self._failure(motion),
        )

    def _failure(self, motion: Motion) -> str:
        """How the goal in force ended, if not by success ("" while it runs, and when it succeeded)."""
        if not self.controller.done(motion.handle):
            return ""
        status, code, text = self.controller.outcome(motion.handle)
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
            desired = self.controller.query(at, min(max(at - after_query - began, 0.0), QUERY_TIMEOUT))
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
        handle, sent = self.controller.send(points, at)
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
        if motion.replaced and self.controller.refused(motion.handle):
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
            while self._clock() < motion.ends + RESULT_GRACE:
                self._stop_anew_if_refused(motion)  # before the done check: a refusal ends the stop's goal too
                if self.controller.done(motion.handle):
                    break
                self.feed.wait(self._clock(), POLL)
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


def _applied(press: Press, now: float) -> tuple[AppliedPress, float]:
    """What is recorded of a press taken at `now` (the link's clock), and its time: its stamp, or when it arrived if
    it has none or one on another clock (a page that keeps the stream's /clock in a session of both links). Its
    lateness is from its stamp to `now`, when the replacement's braking is planned from."""
    arrived = press.arrival if math.isfinite(press.arrival) else now
    if press.stamp > 0 and abs(press.stamp - arrived) <= STAMP_WINDOW:
        late = max(now - press.stamp, 0.0)
        return AppliedPress(press.source, late, press.input_delay, press.arrival_delay), press.stamp
    return AppliedPress(press.source, 0.0, press.input_delay, math.nan), arrived
