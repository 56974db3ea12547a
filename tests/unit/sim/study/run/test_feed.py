"""The trajectory link's joint feed: a malformed or non-finite state is a fault kept with its arrival, never a state
and never an error for good; waits are on the link's clock and never spin."""

from __future__ import annotations

import math
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

from sim.robots import load_robot
from sim.study.run.links.feed import JointFeed

ROBOT = load_robot("panda")


def joint_state(stamp: float, positions: list[float] | None = None, names: list[str] | None = None) -> SimpleNamespace:
    """A sensor_msgs/JointState as the feed reads it (no rospy in the unit lane)."""
    header = SimpleNamespace(stamp=SimpleNamespace(to_sec=lambda: stamp))
    position = [0.0] * ROBOT.dof if positions is None else positions
    return SimpleNamespace(header=header, name=names or ROBOT.joint_names, position=position, velocity=[])


def test_good_states_are_kept_in_the_robots_joint_order_with_their_arrival_on_the_links_clock() -> None:
    feed = JointFeed(ROBOT, lambda: 42.0)
    feed.callback(joint_state(100.0, list(range(ROBOT.dof)), list(ROBOT.joint_names)))
    state = feed.latest()
    assert state is not None and state.stamp == 100.0 and state.arrival == 42.0
    assert np.allclose(state.positions, range(ROBOT.dof)) and np.all(np.isnan(state.velocities))


def test_a_malformed_or_non_finite_state_is_a_fault_not_a_state_and_a_good_one_after_it_is_read_again() -> None:
    now = [1.0]
    feed = JointFeed(ROBOT, lambda: now[0])
    feed.callback(joint_state(100.0))
    faulty = [
        joint_state(100.1, [0.0] * (ROBOT.dof - 1)),  # 6 positions for 7 joints
        joint_state(100.2, [math.nan] + [0.0] * (ROBOT.dof - 1)),
        joint_state(100.3, [math.inf] + [0.0] * (ROBOT.dof - 1)),
        joint_state(0.0),  # unstamped: no tracking error can be measured against it
    ]
    for k, message in enumerate(faulty):
        now[0] = 2.0 + k
        feed.callback(message)
    latest = feed.latest()
    assert latest is not None and latest.stamp == 100.0  # never replaced by a fault
    reasons = [fault.reason for fault in feed.faults_since(1.5)]
    assert len(reasons) == 4 and "non-finite position" in reasons[1] and "non-finite position" in reasons[2]
    assert "stamped 0.0" in reasons[3]
    assert [f.arrival for f in feed.faults_since(3.5)] == [4.0, 5.0]
    now[0] = 9.0
    feed.callback(joint_state(101.0))  # the driver recovers: read again
    latest = feed.latest()
    assert latest is not None and latest.stamp == 101.0 and feed.count() == 2


def test_a_fault_ends_a_wait_as_a_state_does() -> None:
    feed = JointFeed(ROBOT, time.monotonic)
    feed.callback(joint_state(100.0))
    looked = time.monotonic()
    timer = threading.Timer(0.05, feed.callback, (joint_state(100.0, [math.nan] * ROBOT.dof),))
    timer.start()
    began = time.monotonic()
    feed.wait(looked, 5.0)
    assert time.monotonic() - began < 2.0 and len(feed.faults_since(looked)) == 1
    timer.join()


def test_a_wait_with_nothing_new_blocks_until_its_timeout_instead_of_spinning() -> None:
    calls = [0]

    def clock() -> float:
        calls[0] += 1
        return time.monotonic()

    feed = JointFeed(ROBOT, clock)
    feed.callback(joint_state(100.0))
    assert feed.wait(clock(), 0.3) is None
    assert calls[0] < 50  # a spin reads the clock hundreds of thousands of times in 0.3 s


def test_the_clocks_offset_is_the_least_of_the_last_states_so_late_deliveries_do_not_move_it() -> None:
    now = [0.0]
    feed = JointFeed(ROBOT, lambda: now[0])
    assert feed.least_offset() is None

    def arrive(k: int, delivery: float, clock_behind: float = 0.010) -> None:  # states every 33 ms
        now[0] = 100.0 + k * 0.033 + clock_behind + delivery
        feed.callback(joint_state(100.0 + k * 0.033))

    for k in range(15):
        arrive(k, 0.001)
    assert feed.least_offset(0.5) == pytest.approx(0.011)
    # a starved stretch: states late by 40 to 105 ms, delivered in bursts as a loaded machine does
    for k in range(15, 25):
        arrive(k, 0.040 + 0.005 * (k - 15))
    assert feed.least_offset(0.5) == pytest.approx(0.011)  # one prompt state in the last 0.5 s tells the clock
    assert feed.least_offset(0.2) > 0.05  # ...which a window shorter than the stretch misses
    for k in range(25, 45):  # the robot's clock steps 0.2 s back: every offset rises
        arrive(k, 0.001, clock_behind=0.210)
    assert feed.least_offset(0.5) == pytest.approx(0.211)
