"""What the fault bench (bench.fault_bench) runs beside the study's runner, in its own rospy node: the runner's phases
and the arm's joint states as heard; every goal and cancel the controller hears (for sim.engine.executed's replay);
the controller's topics and query_state relayed under RELAY, each goal passable through a hook and query_state
droppable or slowed; a tracker of the resting hand that can be lost. In nodes of their own: the joint states relayed
with a fault (bench.fault_state_relay), and query_state served (bench.fault_query_relay), killed and started anew.

Every relay here is a real rospy endpoint on loopback; each one's close() unregisters what it made.
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from sim.engine.executed import Heard
from sim.engine.trajectory_server import trajectory_from_message
from sim.processes import PYTHON, REPO, kill_process

NS = "/position_joint_trajectory_controller"  # franka_ros's, the runner's preset
JOINT_STATES = "/franka_state_controller/joint_states"
RELAY = "/relayed_controller"  # the namespace the runner talks to when the bench relays the controller
RELAYED_STATES = "/relayed/joint_states"


class Watch:
    """The runner's phases (index, phase, wall time heard) and the arm's joint states (wall time heard, positions,
    velocities), as this process hears them."""

    def __init__(self, rospy: Any) -> None:
        from sensor_msgs.msg import JointState
        from std_msgs.msg import String

        from sim.study.run.protocol import STATUS_TOPIC

        self.lock = threading.Condition()
        self.phases: list[tuple[int, str, float]] = []
        self.states: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._subscribers = [
            rospy.Subscriber(STATUS_TOPIC, String, self._on_status),
            rospy.Subscriber(JOINT_STATES, JointState, self._on_state, queue_size=1000, tcp_nodelay=True),
        ]

    def _on_status(self, message: Any) -> None:
        from sim.study.run.protocol import status_from_json

        status = status_from_json(message.data)
        with self.lock:
            self.phases.append((status.index, status.phase, time.time()))
            self.lock.notify_all()

    def _on_state(self, message: Any) -> None:
        with self.lock:
            self.states.append((time.time(), np.array(message.position), np.array(message.velocity)))

    def forget_states(self) -> None:
        """The joint states heard so far forgotten: a stand-in started anew rests where the last one never was."""
        with self.lock:
            self.states.clear()

    def forget_phases(self) -> None:
        with self.lock:
            self.phases.clear()

    def heard(self, index: int, phase: str) -> float | None:
        """When the runner said (index, phase) first; None while it has not."""
        with self.lock:
            return next((at for k, said, at in self.phases if (k, said) == (index, phase)), None)

    def wait(self, index: int, phase: str, runner: subprocess.Popen, timeout: float) -> float | None:
        """Until the runner says (index, phase) (when, returned), ends, or `timeout` s pass (None)."""
        deadline = time.monotonic() + timeout
        with self.lock:
            while time.monotonic() < deadline and runner.poll() is None:
                at = next((at for k, said, at in self.phases if (k, said) == (index, phase)), None)
                if at is not None:
                    return at
                self.lock.wait(0.1)
        return self.heard(index, phase)

    def between(self, since: float, until: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
        with self.lock:
            return [state for state in self.states if since <= state[0] <= until]

    def at_rest(self, timeout: float, states: int = 15) -> np.ndarray | None:
        """The arm's positions once its last `states` joint states barely move (None after `timeout` s)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                recent = self.states[-states:]
            if len(recent) == states:
                positions = np.array([q for _, q, _ in recent])
                speeds = np.abs(np.array([v for _, _, v in recent]))
                if np.ptp(positions, axis=0).max() < 1e-4 and speeds.max() < 1e-3:
                    return positions[-1]
            time.sleep(0.05)
        return None

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()


class HeardGoals:
    """Every goal and cancel on the controller's action topics, for sim.engine.executed's replay. A goal's arrival is
    when the controller took it: the stamp of the first status that lists it (actionlib's server publishes one as it
    accepts or rejects a goal, stamped on the controller's clock), which a listener's own hearing is not: on a
    loaded machine, a listener that hears the stop late would replay a late bridge the controller never made. A goal
    whose status was not heard keeps its hearing; so does a cancel."""

    def __init__(self, rospy: Any, types: Any, namespace: str = NS) -> None:
        from actionlib_msgs.msg import GoalID, GoalStatusArray

        self.lock = threading.Lock()
        self.events: list[Heard] = []
        self._taken_at: dict[str, float] = {}  # goal id: the stamp of its first status
        action = f"{namespace}/follow_joint_trajectory"
        self._subscribers = [
            rospy.Subscriber(f"{action}/goal", types.action_goal, self._on_goal, tcp_nodelay=True),
            rospy.Subscriber(f"{action}/cancel", GoalID, self._on_cancel, tcp_nodelay=True),
            rospy.Subscriber(f"{action}/status", GoalStatusArray, self._on_status, tcp_nodelay=True),
        ]

    def _on_goal(self, message: Any) -> None:
        heard = Heard(time.time(), "goal", message.goal_id.id, trajectory_from_message(message.goal.trajectory))
        with self.lock:
            self.events.append(heard)

    def _on_cancel(self, message: Any) -> None:
        with self.lock:
            self.events.append(Heard(time.time(), "cancel", message.id))

    def _on_status(self, message: Any) -> None:
        stamp = message.header.stamp.to_sec()
        with self.lock:
            for status in message.status_list:
                self._taken_at.setdefault(status.goal_id.id, stamp)

    def taken(self) -> list[Heard]:
        """The goals and cancels in the order the controller took them."""
        with self.lock:
            events = [
                replace(event, arrival=self._taken_at[event.goal_id])
                if event.kind == "goal" and event.goal_id in self._taken_at
                else event
                for event in self.events
            ]
        return sorted(events, key=lambda event: event.arrival)

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()


class ControllerRelay:
    """The stand-in's controller as the runner sees it under RELAY: its action's five topics relayed by this process,
    each goal passed through `on_goal(number, action_goal)` (1 for the first), which may change it; query_state
    offered here (query=True), each answer held back `query_delay` s, or not at all (query=False: QueryNode's)."""

    def __init__(
        self, rospy: Any, types: Any, on_goal: Callable[[int, Any], None] | None = None, query: bool = True
    ) -> None:
        from actionlib_msgs.msg import GoalID, GoalStatusArray

        self.rospy, self.types = rospy, types
        self.on_goal = on_goal or (lambda number, goal: None)
        self.goals = 0
        self.query_delay = 0.0
        here, there = f"{RELAY}/follow_joint_trajectory", f"{NS}/follow_joint_trajectory"
        goal = rospy.Publisher(f"{there}/goal", types.action_goal, queue_size=10)
        cancel = rospy.Publisher(f"{there}/cancel", GoalID, queue_size=10)
        status = rospy.Publisher(f"{here}/status", GoalStatusArray, queue_size=10)
        feedback = rospy.Publisher(f"{here}/feedback", types.action_feedback, queue_size=10)
        result = rospy.Publisher(f"{here}/result", types.action_result, queue_size=10)
        self._goal_out = goal
        self._closed = threading.Event()
        self._publishers: list[Any] = [goal, cancel, status, feedback, result]
        self._subscribers: list[Any] = [
            rospy.Subscriber(f"{here}/goal", types.action_goal, self._on_goal),
            rospy.Subscriber(f"{here}/cancel", GoalID, self._forward(cancel)),
            rospy.Subscriber(f"{there}/status", GoalStatusArray, self._forward(status)),
            rospy.Subscriber(f"{there}/feedback", types.action_feedback, self._forward(feedback)),
            rospy.Subscriber(f"{there}/result", types.action_result, self._forward(result)),
        ]
        self._ask: Any = None
        self._service: Any = None
        if query:
            self._ask = rospy.ServiceProxy(f"{NS}/query_state", types.query_state, persistent=True)
            self._service = rospy.Service(f"{RELAY}/query_state", types.query_state, self._on_query)

    def _forward(self, publisher: Any) -> Callable[[Any], None]:
        def forward(message: Any) -> None:
            if not self._closed.is_set():  # a message rospy still delivers as the relay closes goes nowhere
                publisher.publish(message)

        return forward

    def _on_goal(self, message: Any) -> None:
        if self._closed.is_set():
            return
        self.goals += 1  # rospy calls one subscriber's callbacks on one thread
        self.on_goal(self.goals, message)
        self._goal_out.publish(message)

    def _on_query(self, request: Any) -> Any:
        if self.query_delay > 0:
            time.sleep(self.query_delay)
        return self._ask(request.time)

    def close(self) -> None:
        self._closed.set()
        if self._service is not None:
            self._service.shutdown()
            self._ask.close()
        for endpoint in self._subscribers + self._publishers:
            endpoint.unregister()


class QueryNode:
    """The controller's query_state offered under RELAY by a node of its own (bench.fault_query_relay): killed, the
    service is gone and its connections close; started anew, a controller restarted."""

    def __init__(self, rospy: Any, env: dict[str, str], log: Path) -> None:
        self.rospy, self.env, self.log = rospy, env, log
        self.process: subprocess.Popen | None = None
        self.start()

    def start(self) -> None:
        with open(self.log, "a") as log:
            self.process = subprocess.Popen(
                [PYTHON, "-m", "bench.fault_query_relay", NS, RELAY], env=self.env, cwd=REPO, stdout=subprocess.PIPE,
                stderr=log, text=True, start_new_session=True,
            )  # fmt: skip
        assert self.process.stdout is not None
        ready = self.process.stdout.readline().strip()
        if ready != "ready":
            self.stop()
            raise SystemExit(f"fault bench: the query_state relay did not start (see {self.log})")
        self.rospy.wait_for_service(f"{RELAY}/query_state", 30)

    def stop(self) -> None:
        if self.process is not None:
            kill_process(self.process, first_signal=signal.SIGKILL)
            self.process = None


class StateRelay:
    """The arm's joint states relayed on RELAYED_STATES by a node of its own (bench.fault_state_relay), `fault` injected
    on `inject()` (or from the first state with `from_start`); `close()` ends it."""

    def __init__(self, env: dict[str, str], log: Path, fault: str, from_start: bool = False) -> None:
        with open(log, "a") as output:
            self.process = subprocess.Popen(
                [PYTHON, "-m", "bench.fault_state_relay", JOINT_STATES, RELAYED_STATES, fault,
                 *(["--from-start"] if from_start else [])],
                env=env, cwd=REPO, stdout=subprocess.PIPE, stderr=output, text=True, start_new_session=True,
            )  # fmt: skip
        assert self.process.stdout is not None
        if self.process.stdout.readline().strip() != "ready":
            self.close()
            raise RuntimeError(f"the joint-state relay did not start (see {log})")

    def inject(self) -> None:
        os.kill(self.process.pid, signal.SIGUSR1)

    def close(self) -> None:
        kill_process(self.process)


class Tracker:
    """A tracker following the participant's right hand at 60 Hz, at rest on the scene's hand; `lose()` stops its
    poses (a gap that lasts)."""

    def __init__(self, rospy: Any, place: np.ndarray) -> None:
        from geometry_msgs.msg import PoseStamped

        from sim.study.run.protocol import POSE_FRAME, POSE_TOPICS

        self.rospy, self.place, self.frame = rospy, place, POSE_FRAME
        self._pose = PoseStamped
        self._out = rospy.Publisher(POSE_TOPICS["right_hand"], PoseStamped, queue_size=10)
        self.tracking, self.running = threading.Event(), threading.Event()
        self.tracking.set()
        self.running.set()
        self._thread = threading.Thread(target=self._track, name="tracker", daemon=True)
        self._thread.start()

    def _track(self) -> None:
        while self.running.is_set():  # bounded: close() clears it
            if self.tracking.is_set():
                pose = self._pose()
                pose.header.stamp = self.rospy.Time.from_sec(time.time())
                pose.header.frame_id = self.frame
                pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = (float(x) for x in self.place)
                pose.pose.orientation.w = 1.0
                self._out.publish(pose)
            time.sleep(1 / 60)

    def lose(self) -> None:
        self.tracking.clear()

    def close(self) -> None:
        self.running.clear()
        self._thread.join(timeout=5)
        self._out.unregister()
