"""The wait for a goal's end on the way to a path's start: it looks at the goal on each new joint state and at least
every POLL s, never in a spin, and says a stale feed, a stop and an overdue goal."""

from __future__ import annotations

import math
import threading
import time
from types import SimpleNamespace

import pytest

from sim.control.controller_node import ControllerError
from sim.robots import load_robot
from sim.study.run.links.trajectory import POLL, JointFeed, await_goal_end

ROBOT = load_robot("panda")


def joint_state(stamp: float) -> SimpleNamespace:
    """A sensor_msgs/JointState as the feed reads it (no rospy in the unit lane)."""
    header = SimpleNamespace(stamp=SimpleNamespace(to_sec=lambda: stamp))
    return SimpleNamespace(header=header, name=ROBOT.joint_names, position=[0.0] * ROBOT.dof, velocity=[])


class Driver:
    """A driver publishing joint states at `rate` Hz on its own thread for `seconds` s."""

    def __init__(self, feed: JointFeed, rate: float, seconds: float) -> None:
        self.feed, self.period, self.seconds = feed, 1.0 / rate, seconds
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        began = time.monotonic()
        while time.monotonic() - began < self.seconds:
            self.feed.callback(joint_state(time.time()))
            time.sleep(self.period)

    def __enter__(self) -> Driver:
        self.feed.callback(joint_state(time.time()))  # the state read before the goal went
        self.thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.thread.join()


class Goal:
    """A goal done `after` s from now; it counts how often it was looked at."""

    def __init__(self, after: float) -> None:
        self.ends, self.looks = time.monotonic() + after, 0

    def done(self) -> bool:
        self.looks += 1
        return time.monotonic() >= self.ends


def test_a_goal_is_looked_at_per_joint_state_or_poll_not_in_a_spin() -> None:
    feed = JointFeed(ROBOT)
    goal = Goal(0.5)
    with Driver(feed, 30, 0.6):
        await_goal_end(feed, goal.done, time.time(), time.time() + 5, 0.25, threading.Event())
    # 0.5 s looked at on each of ~15 states or after each POLL without one: a few dozen looks, where a spin makes
    # hundreds of thousands
    assert goal.looks <= 2 * (0.5 / POLL + 15)


def test_a_feed_that_goes_stale_on_the_way_to_a_start_is_an_error_naming_its_age() -> None:
    feed = JointFeed(ROBOT)
    with Driver(feed, 30, 0.2), pytest.raises(ControllerError, match=r"stale for over 0.25 s .*\(none for 0\.2"):
        await_goal_end(feed, Goal(math.inf).done, time.time(), time.time() + 5, 0.25, threading.Event())


def test_a_goal_not_done_by_its_deadline_or_a_stop_ends_the_wait() -> None:
    feed = JointFeed(ROBOT)
    with Driver(feed, 30, 0.5), pytest.raises(ControllerError, match="did not end the move to the start"):
        await_goal_end(feed, Goal(math.inf).done, time.time(), time.time() + 0.2, 0.25, threading.Event())
    stop = threading.Event()
    stop.set()
    with Driver(feed, 30, 0.1), pytest.raises(ControllerError, match="interrupted"):
        await_goal_end(feed, Goal(math.inf).done, time.time(), time.time() + 5, 0.25, stop)
