"""sim.engine.commands: the engine's target for the end of each step (CommandBuffer), and when a clock-driven step
waits for its command (command_is_due)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from sim.engine.commands import CommandBuffer, command_is_due
from sim.wire.rosmsgs import TrajectoryCommand

NAN = np.nan
START = np.array([0.1, 0.2, 0.3])


def command(stamp: float, positions, velocities=None) -> TrajectoryCommand:
    return TrajectoryCommand(
        stamp, np.array(positions, dtype=float), None if velocities is None else np.array(velocities, dtype=float)
    )


# --- CommandBuffer --------------------------------------------------------------------------------------------


def test_before_any_command_the_target_is_the_start_pose_at_rest_whatever_the_time():
    buffer = CommandBuffer(START)
    for t in (0.0, 0.02, 100.0):
        target = buffer.target_at(t)
        np.testing.assert_array_equal(target.positions, START)
        np.testing.assert_array_equal(target.velocities, np.zeros(3))
    assert buffer.newest_stamp is None and buffer.received == 0


def test_the_buffer_copies_its_start_pose_and_hands_out_copies():
    start = START.copy()
    buffer = CommandBuffer(start)
    start[:] = 9.0
    target = buffer.target_at(0.0)
    target.positions[:] = -9.0
    np.testing.assert_array_equal(buffer.target_at(0.0).positions, START)


def test_a_command_for_the_step_end_is_the_target_exactly():
    buffer = CommandBuffer(START)
    buffer.store(command(1.0, [1.0, 2.0, 3.0], [0.5, -0.5, 0.25]))
    target = buffer.target_at(1.0)
    np.testing.assert_array_equal(target.positions, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(target.velocities, [0.5, -0.5, 0.25])
    assert buffer.newest_stamp == 1.0 and buffer.received == 1


@pytest.mark.parametrize("offset", [1e-9, -1e-9, 3e-16, 1e-6])
def test_a_stamp_a_nanosecond_off_the_step_end_is_not_extrapolated(offset):
    # ROS stamps are whole nanoseconds (rospy's Time.from_sec truncates): "stamped t" arrives as t ± 1 ns, and
    # no_physics must still reproduce the commanded positions exactly.
    buffer = CommandBuffer(START)
    buffer.store(command(1.16 + offset, [1.0, 2.0, 3.0], [5.0, -5.0, 0.3]))
    np.testing.assert_array_equal(buffer.target_at(1.16).positions, [1.0, 2.0, 3.0])


def test_the_target_is_extrapolated_along_the_velocity_to_the_step_end():
    buffer = CommandBuffer(START)
    buffer.store(command(1.0, [1.0, 2.0, 3.0], [0.5, -1.0, 0.0]))
    target = buffer.target_at(1.04)
    np.testing.assert_allclose(target.positions, [1.02, 1.96, 3.0], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(target.velocities, [0.5, -1.0, 0.0])
    # backwards too (a step ending before the newest command's stamp)
    np.testing.assert_allclose(buffer.target_at(0.98).positions, [0.99, 2.02, 3.0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("t, ahead", [(1.5, 0.1), (100.0, 0.1), (0.5, -0.1)])
def test_extrapolation_is_clamped_to_max_extrapolation_either_way(t, ahead):
    buffer = CommandBuffer(START, max_extrapolation_s=0.1)
    buffer.store(command(1.0, [1.0, 2.0, 3.0], [0.5, -1.0, 2.0]))
    expected = np.array([1.0, 2.0, 3.0]) + np.array([0.5, -1.0, 2.0]) * ahead
    np.testing.assert_allclose(buffer.target_at(t).positions, expected, rtol=0, atol=1e-12)


def test_a_command_without_velocities_holds_its_positions():
    buffer = CommandBuffer(START)
    buffer.store(command(1.0, [1.0, 2.0, 3.0], [1.0, 1.0, 1.0]))
    buffer.store(command(2.0, [4.0, 5.0, 6.0]))
    target = buffer.target_at(2.05)
    np.testing.assert_array_equal(target.positions, [4.0, 5.0, 6.0])
    np.testing.assert_array_equal(target.velocities, np.zeros(3))


def test_an_unstamped_command_is_not_extrapolated():
    buffer = CommandBuffer(START)
    buffer.store(command(0.0, [1.0, 2.0, 3.0], [1.0, 1.0, 1.0]))
    assert buffer.newest_stamp is None
    np.testing.assert_array_equal(buffer.target_at(0.05).positions, [1.0, 2.0, 3.0])


def test_joints_a_command_does_not_name_keep_their_target_and_get_no_velocity():
    buffer = CommandBuffer(START)
    buffer.store(command(1.0, [1.0, 2.0, 3.0]))
    buffer.store(command(1.02, [NAN, 7.0, NAN], [NAN, 1.0, NAN]))  # only joint 2 named
    target = buffer.target_at(1.04)
    np.testing.assert_allclose(target.positions, [1.0, 7.02, 3.0], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(target.velocities, [0.0, 1.0, 0.0])
    # a joint never named holds its start position
    fresh = CommandBuffer(START)
    fresh.store(command(1.0, [NAN, NAN, 9.0]))
    np.testing.assert_array_equal(fresh.target_at(1.0).positions, [0.1, 0.2, 9.0])


def test_velocities_that_are_not_finite_count_as_not_given():
    buffer = CommandBuffer(START)
    buffer.store(command(1.0, [1.0, 2.0, 3.0], [np.inf, NAN, 1.0]))
    target = buffer.target_at(1.05)
    np.testing.assert_allclose(target.positions, [1.0, 2.0, 3.05], rtol=0, atol=1e-12)
    assert np.all(np.isfinite(target.velocities))


def test_wait_for_stamp_times_out_without_a_new_enough_command():
    buffer = CommandBuffer(START)
    assert buffer.wait_for_stamp(1.0, timeout=0.01) is False
    buffer.store(command(0.98, [1.0, 2.0, 3.0]))
    assert buffer.wait_for_stamp(1.0, timeout=0.01) is False
    assert buffer.wait_for_stamp(0.98, timeout=0.0) is True
    assert buffer.wait_for_stamp(0.98 + 5e-7, timeout=0.0) is True  # within the 1 µs tolerance


def test_wait_for_stamp_wakes_when_another_thread_stores_the_command():
    buffer = CommandBuffer(START)
    started, result = threading.Event(), {}

    def waiter():
        started.set()
        result["ok"] = buffer.wait_for_stamp(1.0, timeout=5.0)

    thread = threading.Thread(target=waiter)
    thread.start()
    assert started.wait(5.0)
    buffer.store(command(0.5, [0.0, 0.0, 0.0]))  # too old: keeps waiting
    buffer.store(command(1.0, [1.0, 2.0, 3.0]))
    thread.join(5.0)
    assert not thread.is_alive()
    assert result == {"ok": True}


def test_a_wait_past_a_count_skips_a_stale_command_stamped_later_than_the_step():
    buffer = CommandBuffer(START)
    buffer.store(command(0.32, [1.0, 2.0, 3.0]))  # the end of a run before /clock restarted at 0
    stale = buffer.received
    assert buffer.wait_for_stamp(0.02, timeout=0.0) is True
    assert buffer.wait_for_stamp(0.02, timeout=0.01, received_after=stale) is False
    buffer.store(command(0.02, [0.0, 0.0, 0.0]))
    assert buffer.wait_for_stamp(0.02, timeout=0.0, received_after=stale) is True


# --- command_is_due ---------------------------------------------------------------------------------------------

DT = 0.02


@pytest.mark.parametrize("streaming", [False, True])
@pytest.mark.parametrize("first", [False, True])
def test_a_command_already_here_is_never_waited_for(streaming, first):
    assert not command_is_due(0.1 + 4e-7, 0.1, DT, streaming, first)


@pytest.mark.parametrize("newest", [None, 0.32, 0.0, 0.08])
def test_the_first_step_after_an_anchor_waits_whatever_came_before(newest):
    """Before any command of this run has arrived, the tick may have won the race against the first one."""
    assert command_is_due(newest, 0.1, DT, streaming=False, first_after_anchor=True)


def test_a_streaming_controller_is_waited_for_after_it_sent_the_previous_step():
    assert command_is_due(0.08, 0.1, DT, streaming=True, first_after_anchor=False)
    assert not command_is_due(0.06, 0.1, DT, streaming=True, first_after_anchor=False)  # it stopped streaming
    assert not command_is_due(None, 0.1, DT, streaming=True, first_after_anchor=False)


def test_a_controller_stamping_its_current_time_is_not_waited_for_between_anchors():
    """Its command for the step ending at t is stamped t - dt, exactly like a lockstep command that lost its race;
    only the streaming flag, set by a command that was on time, tells them apart."""
    assert not command_is_due(0.08, 0.1, DT, streaming=False, first_after_anchor=False)
