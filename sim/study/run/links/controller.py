"""A trajectory controller's two interfaces as the trajectory link uses them: its follow_joint_trajectory action and
its query_state service, their deliveries and round trips measured for the stops' leads (sim.study.run.links.lead).
rospy and actionlib.

Goals are followed through actionlib's ActionClient, each by its own handle (SimpleActionClient drops a result that
comes before its send_goal has returned). query_state is a persistent proxy, made anew after any failure: rospy's
does not reconnect, so after a controller restart every query would fail.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any

from sim.control.controller_node import ControllerError
from sim.study.run.links.clock import LinkClock
from sim.study.run.links.goals import GoalPoints
from sim.study.run.links.lead import Leads, delivery_part

__all__ = ["REJECTED", "SUCCEEDED", "Controller"]

SUCCEEDED = 3
REJECTED = 5


class Controller:
    """One trajectory controller under `namespace`, its goals for `joint_names` stamped on the link's `clock`, the
    deliveries and query_state's round trips measured into `leads` under `lock` (goals' deliveries are measured on
    actionlib's threads)."""

    def __init__(
        self,
        rospy: Any,
        namespace: str,
        joint_names: Sequence[str],
        clock: LinkClock,
        leads: Leads,
        lock: threading.Lock,
    ) -> None:
        import actionlib

        from sim.wire.control_types import control_types, joint_trajectory

        self.rospy, self.namespace, self.joint_names = rospy, namespace, list(joint_names)
        self.types = control_types()
        self._joint_trajectory = joint_trajectory
        self._clock, self.leads, self._lock = clock, leads, lock
        self.client = actionlib.ActionClient(f"{namespace}/follow_joint_trajectory", self.types.action)
        self._proxy: Any = None  # query_state's persistent proxy, made anew after a failure (see query)

    def wait_for_server(self, timeout: float) -> bool:
        return bool(self.client.wait_for_server(self.rospy.Duration(timeout)))

    def close(self) -> None:
        if self._proxy is not None:
            self._proxy.close()
        client = self.client
        for endpoint in (client.pub_goal, client.pub_cancel, client.status_sub, client.result_sub, client.feedback_sub):
            endpoint.unregister()

    def query(self, at: float, timeout: float) -> Any:
        """query_state's answer for link time `at`, its round trip measured for the stops' lead. ControllerError when
        it fails or has not answered within `timeout` s. rospy's persistent proxy does not reconnect: after a
        failure it is closed (which also ends a call stuck on its socket) and the next query makes a new one."""
        if self._proxy is None:
            self._proxy = self.rospy.ServiceProxy(
                f"{self.namespace}/query_state", self.types.query_state, persistent=True
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
            with self._lock:
                self.leads.add("query", self._clock() - asked)
            return answer["desired"]
        failure = answer.get("error") or f"no answer within {timeout * 1e3:.0f} ms"  # before closing fails the call
        self._proxy = None
        proxy.close()
        raise ControllerError(f"{self.namespace}/query_state failed: {failure}")

    @staticmethod
    def taken(handle: Any) -> bool:
        """The controller has said it took the goal (not yet heard of, or refused: not taken)."""
        from actionlib import CommState

        heard = handle.get_comm_state() != CommState.WAITING_FOR_GOAL_ACK
        return bool(heard and not Controller.refused(handle))

    @staticmethod
    def refused(handle: Any) -> bool:
        """The controller has said it refused the goal: its status says REJECTED, which is final. Not only once the
        goal is done: actionlib's handle is done when the result comes, which the server sends on a topic of its own
        (the status array on another), and the status may come first. Until the result, the handle waits for it with
        the status REJECTED: counted as taken then, the refused stop was taken for the arm's path, and the arm, going
        on with the approach it was refused in, was found 34.6 mm off it (a machine beside two CPU burners)."""
        return int(handle.get_goal_status()) == REJECTED

    def send(self, points: GoalPoints, stamp: float) -> tuple[Any, float]:
        """A goal of `points` stamped `stamp` (the link's clock); its handle and when it was sent."""
        goal = self.types.goal()
        goal.trajectory = self._joint_trajectory(
            self.joint_names, points.times, points.positions, points.velocities, points.accelerations, stamp
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
                with self._lock:
                    self.leads.add(part, self._clock() - sent)

        return transition

    @staticmethod
    def done(handle: Any) -> bool:
        from actionlib import CommState

        return bool(handle.get_comm_state() == CommState.DONE)

    @staticmethod
    def outcome(handle: Any) -> tuple[int, int | None, str]:
        result = handle.get_result()
        if result is None:
            return int(handle.get_goal_status()), None, handle.get_goal_status_text()
        return int(handle.get_goal_status()), int(result.error_code), str(result.error_string)
