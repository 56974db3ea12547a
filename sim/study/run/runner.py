"""The study runner: a participant's session plan run trial by trial, in the runner's rospy node
(sim.study.run.node: `python -m sim.study run --plan PLAN --out DIR`).

Per trial: move to the path's start (a quintic in joint space), wait for go (`/study/go`, the observer's keyboard,
or at once with --auto-go), judge the pages' clocks (sim.study.run.clocks; trust_page_clocks), run the approach
sample by sample (sim.study.run.trial), stopping along the path when a press comes (`/study/stop`), rest, then ask
for test 1's perceived distance, and after each group of test 2 for the preference. The trial's phase goes out on
`/study/trial` and the inputs come back (sim.study.run.dialogue; sim.study.run.protocol has the whole interface).
Every row is written to the participant's CSV as soon as its trial ends; the session's bag (sim.study.run.bag)
records the robot's topics, /clock and every /study topic.

The plan's questionnaires are asked at their places, before the first trial or after the trial they follow; the
questions go out and the answers come in through sim.study.run.asking.

The robot is driven through each condition's link (sim.study.run.links): the stream (the commander's topics, through
the same controller node and stepper, for the engine stand-in or Unity), or a real arm's ros_control trajectory
controller on wall time (--link CONDITION=PRESET). On the stream in lockstep (default) the runner owns /clock and the
engine steps once per value, so a session takes seconds of wall time; while the runner waits for go or an answer,
the clock stands still. --realtime: /clock and the commands are paced by the wall clock (a VR headset), and the robot
is held at its target while the runner waits. A trajectory controller holds on its own and has no /clock. When the
trajectory link stops the arm on its own (sim.study.run.links.trajectory), the session ends after that trial.

A press's time is its stamp on ROS time (a zero stamp: when it arrives); a press whose stamp has already passed is
applied at once, and how late it was is logged. Presses before the approach starts are ignored. In lockstep the
runner holds the clock at a test-2 approach's start until the participant's press is in (at most
RunnerOptions.press_grace of wall time): a simulated participant plans its press and sends it, stamped ahead, when
the approach begins, and the lockstep would otherwise outrun it. Each press's latency is recorded in two parts: its
input delay (the client's, in the Header's seq) and its arrival delay (the runner's ROS time when it came, minus its
stamp).

The participant's tracked head and hands are measured per approach, and their pose sources recorded per condition
(sim.study.run.bodies). The approach's window, its press and every measure are placed on the instant the arm began to
move, as its link reports it (ApproachOutcome.motion_start; the record's motion_start): the stream's first step, at
the `moving` status; a trajectory controller's approach goal stamp, its planning and start lead later.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Mapping

from sim.control.controller_node import DRAIN_TIMEOUT_S, unwritten_subscribers
from sim.control.stepper import Pacing
from sim.robots import RobotSpec
from sim.study.design.feasibility import Approaches
from sim.study.design.plan import PlannedTrial, SessionPlan
from sim.study.design.scene import Scene
from sim.study.run.asking import Asking
from sim.study.run.bodies import TrackedBodies
from sim.study.run.clocks import FOLDER as CLOCKS
from sim.study.run.clocks import PAGE_CLOCK_SETTLE_S, PageClocks, write_session_clocks
from sim.study.run.console import say
from sim.study.run.dialogue import Dialogue
from sim.study.run.inputs import Inputs
from sim.study.run.links.base import RobotLink, SafetyStopped
from sim.study.run.links.choose import make_links, unique
from sim.study.run.links.specs import STREAM, TrajectoryLinkSpec
from sim.study.run.protocol import PAGE_CLOCK_TOPIC, PROTOCOL, STATUS_TOPIC, TrialStatus
from sim.study.run.records import TrialRecord, write_records
from sim.study.run.trial import TrialRun

__all__ = ["RunnerOptions", "StudyRunner"]

PAGE_CLOCK_POLL_S = 0.1  # s: how often a page's unsettled clock is looked at again, the arm held meanwhile


@dataclass(frozen=True)
class RunnerOptions:
    pacing: Pacing = Pacing(step_timeout=10.0)
    auto_go: bool = False
    keyboard: bool = False  # the observer types at this terminal: go, stop, distances, preferences, answers
    settle: float = 0.5  # s held after the motion ends, before it counts as at rest
    response_timeout: float = 300.0  # the longest wait for go or an answer; then the trial goes on without it
    deceleration: float = 1.0  # m/s² along the path on a press
    # Lockstep only: before a test-2 approach, how long (s of wall time) the runner waits for the participant's press.
    # An approach of seconds of ROS time takes a fraction of a second of wall time in lockstep, so a press sent on
    # `moving` by a participant short of CPU landed after its stamp, or after the approach (measured beside other
    # work: presses 0.1-0.3 s late in wall time). Waiting keeps ROS time still until the press is in; a participant
    # who does not press costs this once per trial.
    press_grace: float = 2.0
    # At an approach's end, how long (s of wall time) the runner waits for the poses up to its end (see
    # sim.study.run.bodies); a tracker that stops sending costs this once per trial, and its gap is measured.
    pose_grace: float = 1.0
    # by condition, a pose source named by hand: over any announcement on /study/tracking (session_tracking)
    pose_sources: Mapping[str, str] = field(default_factory=dict)


class StudyRunner:
    """A participant's session, trial after trial: the robot link of each condition (the stream unless
    `trajectory_links` names a trajectory controller for it), the dialogue with the participant and the observer,
    what is asked of them, and their tracked bodies; the rows."""

    def __init__(
        self,
        robot: RobotSpec,
        scene: Scene,
        plan: SessionPlan,
        approaches: Approaches,
        options: RunnerOptions,
        stop: threading.Event,
        trajectory_links: Mapping[str, TrajectoryLinkSpec] | None = None,
    ) -> None:
        import rospy
        from std_msgs.msg import String

        self.rospy = rospy
        self.robot, self.stop = robot, stop
        self.scene, self.plan, self.approaches, self.options = scene, plan, approaches, options
        self.inputs = Inputs()
        self.safety_stops: list[str] = []  # the trials in which the runner stopped the arm on its own, and why
        self.unmonitored: set[str] = set()  # the conditions on a real arm said to have no tracker on the hands
        self.status_pub = self.rospy.Publisher(STATUS_TOPIC, String, queue_size=10, latch=True)
        # only the conditions the plan runs have a link: a link not used waits for no arm
        run = list(dict.fromkeys(t.condition for t in plan.trials)) or list(plan.conditions[:1])
        watched = (STATUS_TOPIC, self.status_pub)
        self.links = make_links(robot, run, options.pacing, stop, trajectory_links or {}, watched)
        self.link: RobotLink = self.links[run[0]]
        self._started: set[int] = set()  # the links started (by id)
        self._lockstep_began: dict[int, tuple[Any, float]] = {}  # lockstep links (by id): the link, its clock at start
        self.dialogue = Dialogue(
            self.status_pub, self.inputs, lambda: self.link, options.keyboard, options.response_timeout, stop
        )
        self.asking = Asking(plan, self.dialogue, options.response_timeout)
        self.bodies = TrackedBodies(
            scene, approaches, lambda: self.link, options.pose_grace, options.pose_sources, options.pacing.dt, stop
        )
        self.page_clocks = PageClocks(quantum=options.pacing.dt)  # the pages' clocks (sim.study.run.clocks)
        self._page_clock_sub = rospy.Subscriber(
            PAGE_CLOCK_TOPIC, String, lambda message: self.page_clocks.heard_json(message.data, say)
        )

    # --- time -----------------------------------------------------------------------------------------------
    @property
    def clock(self) -> float:
        """The current condition's link's time: the stream's ROS time (its last step's end), or the wall clock."""
        return self.link.clock

    def use_link(self, condition: str) -> None:
        """Make `condition`'s link the current one, started the first time it is used."""
        self.link = self.links[condition]
        if id(self.link) not in self._started:
            self._started.add(id(self.link))
            self.link.start(self.options.pacing.step_timeout)
            if not self.link.realtime:
                self._lockstep_began[id(self.link)] = (self.link, self.link.clock)

    def lockstep_time(self) -> float | None:
        """s of ROS time the lockstep links' clocks have advanced (None when every link ran on wall time)."""
        if not self._lockstep_began:
            return None
        return sum(link.clock - began for link, began in self._lockstep_began.values())

    # --- trials ---------------------------------------------------------------------------------------------
    def status(self, trial: PlannedTrial, phase: str, **extra: Any) -> TrialStatus:
        return TrialStatus(
            self.plan.participant,
            trial.index,
            len(self.plan.trials),
            phase,
            trial.condition,
            trial.test,
            trial.path,
            trial.standoff,
            trial.peak_speed,
            trial.speed_set,
            trial.group,
            **extra,
        )

    def run_session(self, records_path: Path, log: Callable[[str], None]) -> list[TrialRecord]:
        """The session: the trials' records in `records_path`, the questionnaires' beside it (in its folder)."""
        self.use_link(next(iter(self.links)))
        records: list[TrialRecord] = []
        self.asking.administer(0, records_path.parent, log)
        for trial in self.plan.trials:
            record = self.run_trial(trial, log)
            records.append(record)
            group = self._group_of(trial)
            if group and group[-1] is trial:  # the group's last trial: which approach was preferred?
                paths = tuple(t.path for t in group)
                preferred = self.asking.ask_preference(self.status(trial, "preference", group_paths=paths), log)
                indices = {t.index for t in group}
                records = [replace(r, preferred_path=preferred) if r.index in indices else r for r in records]
            write_records(records_path, records)  # after every trial: a crash loses at most the one running
            if self.bodies.tracked:
                self.bodies.write_tracking(records_path.parent, self.plan.participant)
            robots = {link.name: link.clock_offset for link in unique(self.links.values())}
            clocks = records_path.parent / CLOCKS / f"participant_{self.plan.participant:02d}.json"
            write_session_clocks(clocks, self.plan.participant, robots, self.page_clocks)
            if self.safety_stops:
                raise SafetyStopped(f"the session ends: the runner stopped the arm in {'; '.join(self.safety_stops)}")
            self.asking.administer(trial.index, records_path.parent, log)
        self.dialogue.publish_status(TrialStatus(self.plan.participant, 0, len(self.plan.trials), "done"))
        return records

    def _group_of(self, trial: PlannedTrial) -> list[PlannedTrial]:
        """Test 2's group that `trial` belongs to, in the order run; empty for test 1."""
        if trial.test != 2:
            return []
        return [
            t for t in self.plan.trials if t.test == 2 and t.condition == trial.condition and t.group == trial.group
        ]

    def run_trial(self, trial: PlannedTrial, log: Callable[[str], None]) -> TrialRecord:
        """One trial from wherever the robot is; its record (preference still empty)."""
        planned = self.approaches.plan((trial.path, trial.standoff, trial.peak_speed))
        self.use_link(trial.condition)
        self.bodies.condition = trial.condition  # whose announced pose source's poses count from now on
        began = self.clock  # poses from here on are this trial's
        self.dialogue.publish_status(self.status(trial, "to_start"))
        self.link.move_to(planned.positions[0], self.bodies.hand_watch(began))
        self.dialogue.publish_status(self.status(trial, "ready"))
        if not self.options.auto_go and self.dialogue.wait_for_input("go") is None:
            log(f"trial {trial.index}: no go within {self.options.response_timeout:g} s; starting anyway")
        self.trust_page_clocks(trial, log)
        hand = self.bodies.hand_watch(began)
        if self.link.name != STREAM and not hand.tracked and trial.condition not in self.unmonitored:
            self.unmonitored.add(trial.condition)
            log(
                f"{trial.condition}: no tracker follows the hands: the arm's separation is to the scene's hand, taken "
                "at rest (the hand is not monitored)"
            )
        run = TrialRun(self.robot, planned, self.approaches.hand_distance, self.options.deceleration, hand)
        start = self.clock  # presses count from here; the arm starts at the link's reported start, later in reality
        self.dialogue.publish_status(self.status(trial, "moving", motion_start=start))
        if trial.test == 2 and not self.link.realtime and not self.options.auto_go:
            self.inputs.wait_for_press(self.options.press_grace, self.stop)  # see RunnerOptions.press_grace
        outcome = self.link.approach(run, lambda until: self.inputs.take_press(until), self.options.settle)
        if outcome.safety_stop:
            log(f"trial {trial.index}: the arm was stopped: {outcome.safety_stop}")
        start = outcome.motion_start  # from now on the arm's own start, as the link reports it (the row's)
        self.dialogue.publish_status(self.status(trial, "at_rest", motion_start=start))
        measures = run.measures()
        press = outcome.press
        window = outcome.window(self.clock, measures.press_time)  # the run's times are from the arm's actual start
        motion, source = self.bodies.motion(trial, run, began, window, log)
        perceived = math.nan
        if trial.test == 1:
            perceived = self.asking.ask_distance(self.status(trial, "distance", motion_start=start), log)
        position = self.plan.conditions.index(trial.condition) + 1
        record = TrialRecord(
            self.plan.participant,
            trial.index,
            trial.condition,
            position,
            trial.test,
            trial.path,
            trial.standoff,
            trial.peak_speed,
            trial.speed_set,
            trial.group,
            window.start,
            measures.pressed,
            measures.press_time,
            press.source if press else "",
            press.late if press else 0.0,
            measures.distance_at_press,
            measures.distance_at_rest,
            measures.distance_extrapolated,
            measures.braking_distance if math.isnan(outcome.braking_planned) else outcome.braking_planned,
            perceived,
            "",
            press.input_delay if press else math.nan,
            press.arrival_delay if press else math.nan,
            motion.tracked_hand,
            motion.withdrawal_distance,
            motion.withdrawal_peak_speed,
            motion.head_distance_at_press,
            motion.hand_untracked,
            motion.head_untracked,
            self.link.name,
            outcome.goal_result,
            -1 if outcome.error_code is None else outcome.error_code,
            outcome.tracking_error,
            outcome.replacement_sent,
            outcome.braking_began,
            outcome.braking_achieved,
            outcome.safety_stop,
            outcome.start_lead,
            outcome.stop_lead,
            outcome.hand_monitored,
            outcome.least_separation_predicted,
            outcome.least_separation,
            source.name,
            source.calibration_id,
            outcome.robot_clock_offset,
            outcome.robot_clock_drift,
            *self.page_clocks.trial(PROTOCOL.stop_source(trial.condition)),
            outcome.move_least_separation,
        )
        if outcome.safety_stop:
            self.safety_stops.append(f"trial {trial.index}: {outcome.safety_stop}")
        return record

    def trust_page_clocks(self, trial: PlannedTrial, log: Callable[[str], None]) -> None:
        """At go: ClockError (the session ends before the approach) when a page's clock cannot be trusted. In real time
        a clock beyond the limit as it stands is first given PAGE_CLOCK_SETTLE_S to come within it, the arm held at the
        start; in lockstep ROS time runs only as the runner steps it, and a page's estimate of it would not settle."""
        unsettled = self.page_clocks.unsettled() if self.link.realtime else ""
        if unsettled:
            log(f"trial {trial.index}: {unsettled}: the arm holds at the start up to {PAGE_CLOCK_SETTLE_S:g} s")
            deadline = time.monotonic() + PAGE_CLOCK_SETTLE_S
            while self.page_clocks.unsettled() and time.monotonic() < deadline and not self.stop.is_set():
                self.link.idle(PAGE_CLOCK_POLL_S)
        self.page_clocks.refuse()
        self.page_clocks.approach_begins()

    def connect(self, timeout: float, recorder: str | None) -> str:
        """Wait until every link's arm is there and linked (and the status reaches the engine); their names."""
        return ", ".join(link.connect(timeout, recorder) for link in unique(self.links.values()))

    def recorded_topics(self) -> list[str]:
        return [topic for link in unique(self.links.values()) for topic in link.recorded_topics()]

    def close(self) -> None:
        self.dialogue.close()
        self._page_clock_sub.unregister()
        self.bodies.close()
        # the last status to its slow subscribers (a recorder) before it goes: a stream link drains it too, a
        # trajectory controller's link does not know it
        deadline = time.monotonic() + DRAIN_TIMEOUT_S
        while unwritten_subscribers(self.status_pub) and time.monotonic() < deadline:
            time.sleep(0.005)
        for link in unique(self.links.values()):
            link.close()
        self.status_pub.unregister()
