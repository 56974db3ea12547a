"""The runner as a ROS node, one per session (`python -m sim.study run --plan PLAN --out DIR`): the node and its
signals, the session's bag (sim.study.run.bag: `rosbag record`, started before the session and stopped after it),
the observer's keyboard on a thread of its own, the wait for the arm and the participant's topics, the session
(sim.study.run.runner) and what it says at the end; its exit code."""

from __future__ import annotations

import signal
import sys
import threading
import time
from pathlib import Path
from typing import Mapping

from sim.control.controller_node import ControllerError
from sim.processes import stop_recorder
from sim.robots import RobotSpec
from sim.study.design.feasibility import Approaches
from sim.study.design.plan import SessionPlan
from sim.study.design.scene import Scene
from sim.study.run.bag import RECORDER_DRAIN, record_session
from sim.study.run.clocks import ClockError
from sim.study.run.console import say
from sim.study.run.links.base import SafetyStopped
from sim.study.run.links.specs import TrajectoryLinkSpec
from sim.study.run.questionnaires import FOLDER as QUESTIONNAIRES
from sim.study.run.runner import RunnerOptions, StudyRunner

__all__ = ["EXIT_OK", "EXIT_ROS", "EXIT_SAFETY", "EXIT_INTERRUPTED", "run_node"]


EXIT_OK, EXIT_ROS, EXIT_SAFETY, EXIT_INTERRUPTED = 0, 4, 5, 130


def run_node(
    robot: RobotSpec,
    scene: Scene,
    plan: SessionPlan,
    approaches: Approaches,
    options: RunnerOptions,
    out: Path,
    record: bool = True,
    connect_timeout: float = 60.0,
    trajectory_links: Mapping[str, TrajectoryLinkSpec] | None = None,
) -> int:
    """The runner as a ROS node (rospy.init_node: once per process): the session, its CSV and its bag in `out`."""
    import rospy

    from sim.wire.rosnode import init_node

    stop = threading.Event()
    init_node("study_runner")
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    stem = f"participant_{plan.participant:02d}"
    bag, records_path = out / "bags" / f"{stem}.bag", out / f"{stem}.csv"
    recorder_node = f"study_recorder_{plan.participant}"
    sim_time = bool(rospy.get_param("/use_sim_time", False))
    runner = StudyRunner(robot, scene, plan, approaches, options, stop, trajectory_links)
    try:
        topics = runner.recorded_topics()
        recorder = record_session(topics, bag, recorder_node, out / "logs", sim_time) if record else None
    except BaseException:
        runner.close()
        raise
    if options.keyboard:
        threading.Thread(target=runner.dialogue.read_keyboard, args=(sys.stdin,), name="keyboard", daemon=True).start()
    started = time.monotonic()
    try:
        partner = runner.connect(connect_timeout, recorder_node if recorder else None)
        runner.dialogue.wait_for_inputs(connect_timeout, recorder_node if recorder else None)
        say(
            f"{partner} connected; participant {plan.participant}, {len(plan.trials)} trials, conditions "
            f"{' then '.join(plan.conditions)}"
        )
        records = runner.run_session(records_path, say)
        if recorder is not None:
            stop.wait(RECORDER_DRAIN)  # see RECORDER_DRAIN
    except ControllerError as error:
        say(f"error: {error}")
        return EXIT_INTERRUPTED if stop.is_set() else EXIT_ROS
    except ClockError as error:  # a page's clock (sim.study.run.clocks), refused as a robot's is at connect
        say(f"error: {error}")
        return EXIT_ROS
    except SafetyStopped as error:
        say(f"error: {error}")
        print(f"records: {records_path}")
        return EXIT_SAFETY
    finally:
        runner.close()
        if recorder is not None:
            stop_recorder(recorder, bag)
        rospy.signal_shutdown("study session done")
    presses = sum(record.pressed for record in records)
    lockstep = runner.lockstep_time()
    print(
        f"participant {plan.participant}: {len(records)} trials ({presses} stopped by a press) in "
        f"{time.monotonic() - started:.1f} s of wall time"
        + ("" if lockstep is None else f", {lockstep:.1f} s of ROS time in lockstep")
    )
    print(f"records: {records_path}")
    if plan.questionnaires:
        print(f"questionnaires: {out / QUESTIONNAIRES}")
    if recorder is not None:
        print(f"bag:     {bag}")
    return EXIT_OK
