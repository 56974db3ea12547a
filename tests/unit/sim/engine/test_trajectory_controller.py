"""The stand-in's trajectory controller (sim.engine.trajectory_controller): one test per documented case of
ros_controllers' joint_trajectory_controller that the issue lists, and the spline orders."""

from __future__ import annotations

import numpy as np
import pytest

from sim.engine.trajectory_controller import (
    ControllerError,
    Ending,
    ErrorCode,
    GoalTolerances,
    JointState,
    JointTolerance,
    Point,
    TrajectoryController,
    TrajectoryMessage,
)

JOINTS = ("a", "b")
HOME = JointState.at_rest([0.0, 0.0])


def controller(**options: float) -> TrajectoryController:
    return TrajectoryController(JOINTS, [0.0, 0.0], **options)  # type: ignore[arg-type]


def to(positions: list[float], at: float, stamp: float = 0.0, **given: list[float]) -> TrajectoryMessage:
    return TrajectoryMessage(stamp, JOINTS, [Point(at, positions, **given)])  # type: ignore[arg-type]


def follow(c: TrajectoryController, t: float) -> JointState:
    """The desired state at t, as a perfectly tracking robot would measure it."""
    return c.desired_at(t)


def test_a_stamp_of_zero_starts_at_the_next_update() -> None:
    c = controller()
    assert c.on_command(to([1.0, 2.0], 1.0), now=10.0, actual=HOME).accepted
    np.testing.assert_allclose(c.desired_at(10.0).positions, [0.0, 0.0])
    np.testing.assert_allclose(c.desired_at(10.5).positions, [0.5, 1.0])  # positions only: linear
    np.testing.assert_allclose(c.desired_at(11.0).positions, [1.0, 2.0])
    np.testing.assert_allclose(c.desired_at(12.0).velocities, [0.0, 0.0])  # held at rest after the last point


def test_a_stamp_in_the_future_keeps_the_current_motion_until_then() -> None:
    c = controller()
    c.on_command(to([1.0, 1.0], 2.0), now=0.0, actual=HOME)
    before = c.desired_at(1.5)
    assert c.on_command(to([0.0, 0.0], 1.0, stamp=1.0), now=0.5, actual=follow(c, 0.5)).accepted
    np.testing.assert_allclose(c.desired_at(0.9).positions, [0.45, 0.45])  # the old trajectory, untouched
    np.testing.assert_allclose(c.desired_at(1.0).positions, [0.5, 0.5])
    np.testing.assert_allclose(c.desired_at(2.0).positions, [0.0, 0.0])
    assert not np.allclose(c.desired_at(1.5).positions, before.positions)


def test_points_at_or_before_the_start_are_dropped() -> None:
    c = controller()
    message = TrajectoryMessage(0.0, JOINTS, [Point(0.0, [5.0, 5.0]), Point(1.0, [1.0, 1.0])])
    assert c.on_command(message, now=3.0, actual=HOME).accepted
    # The point due now is dropped: the bridge goes from where the robot is wanted to the next point.
    np.testing.assert_allclose(c.desired_at(3.0).positions, [0.0, 0.0])
    np.testing.assert_allclose(c.desired_at(3.5).positions, [0.5, 0.5])


def test_a_trajectory_all_in_the_past_is_refused_and_the_motion_carries_on() -> None:
    c = controller()
    c.on_goal("g1", to([1.0, 1.0], 2.0), GoalTolerances(), now=0.0, actual=HOME)
    verdict = c.on_goal("g2", to([3.0, 3.0], 0.5, stamp=0.2), GoalTolerances(), now=1.0, actual=follow(c, 1.0))
    assert not verdict.accepted and verdict.code == ErrorCode.INVALID_GOAL and verdict.ended == ()
    assert c.active_goal == "g1"
    np.testing.assert_allclose(c.desired_at(2.0).positions, [1.0, 1.0])
    assert not c.on_command(to([3.0, 3.0], 0.5, stamp=0.2), now=1.0, actual=follow(c, 1.0)).accepted
    assert c.active_goal == "g1"


def test_a_first_point_due_at_a_future_start_is_reached_by_a_step_there() -> None:
    # ros_controllers bridges from the desired state at the start to a point due then: a bridge of no length.
    c = controller()
    message = TrajectoryMessage(2.0, JOINTS, [Point(0.0, [1.0, 1.0]), Point(1.0, [2.0, 2.0])])
    assert c.on_command(message, now=1.0, actual=HOME).accepted
    np.testing.assert_allclose(c.desired_at(1.999).positions, [0.0, 0.0])  # the hold, up to the start
    np.testing.assert_allclose(c.desired_at(2.0).positions, [1.0, 1.0])  # then the point, at once
    np.testing.assert_allclose(c.desired_at(2.5).positions, [1.5, 1.5])


def test_a_point_due_before_its_future_start_is_refused() -> None:
    c = controller()
    message = TrajectoryMessage(2.0, JOINTS, [Point(-0.5, [1.0, 1.0]), Point(1.0, [2.0, 2.0])])
    verdict = c.on_command(message, now=1.0, actual=HOME)
    assert (
        not verdict.accepted
        and verdict.code == ErrorCode.INVALID_GOAL
        and "before the trajectory's start" in (verdict.text)
    )
    np.testing.assert_allclose(c.desired_at(3.0).positions, [0.0, 0.0])


def test_query_state_answers_the_desired_state_the_updates_will_follow() -> None:
    c = controller()
    c.on_goal("g1", to([1.0, 1.0], 2.0, velocities=[0.0, 0.0]), GoalTolerances(), 0.0, HOME)
    ahead = c.desired_at(1.5)  # asked at t = 0 for t = 1.5, as query_state is
    update = c.update(1.5, follow(c, 1.5))
    np.testing.assert_allclose(ahead.positions, update.desired.positions)
    np.testing.assert_allclose(ahead.velocities, update.desired.velocities)
    np.testing.assert_allclose(ahead.accelerations, update.desired.accelerations)


def test_a_goal_with_no_points_holds_and_succeeds_once_the_arm_has_stopped() -> None:
    c = controller(goal_time=1.0)
    c.on_goal("g1", to([1.0, 1.0], 2.0), GoalTolerances(), 0.0, HOME)
    measured = JointState(np.array([0.5, 0.5]), np.array([0.5, 0.5]), np.zeros(2))
    verdict = c.on_goal("g2", TrajectoryMessage(0.0, JOINTS, []), GoalTolerances(), 1.0, measured)
    assert verdict.accepted and [(e.goal_id, e.ending) for e in verdict.ended] == [("g1", Ending.CANCELED)]
    np.testing.assert_allclose(c.desired_at(3.0).positions, [0.5, 0.5])
    assert c.update(1.1, measured).ended == ()  # still moving: within the goal time it waits
    (event,) = c.update(1.3, JointState.at_rest([0.52, 0.52])).ended
    assert event.goal_id == "g2" and event.ending is Ending.SUCCEEDED


def test_a_lone_point_at_time_zero_is_dropped() -> None:
    # Today's one-point stream: stamp 0, time_from_start 0. A real controller refuses it; the robot does not move.
    c = controller()
    verdict = c.on_command(to([1.0, 1.0], 0.0), now=5.0, actual=HOME)
    assert not verdict.accepted and verdict.code == ErrorCode.INVALID_GOAL
    np.testing.assert_allclose(c.desired_at(6.0).positions, [0.0, 0.0])


def test_replacement_mid_motion_bridges_from_the_desired_state_without_a_jump() -> None:
    c = controller()
    approach = TrajectoryMessage(
        0.0,
        JOINTS,
        [Point(1.0, [0.5, 0.5], [1.0, 1.0], [0.0, 0.0]), Point(2.0, [1.0, 1.0], [0.0, 0.0], [0.0, 0.0])],
    )
    c.on_command(approach, now=0.0, actual=HOME)
    at = c.desired_at(1.2)
    stop = TrajectoryMessage(0.0, JOINTS, [Point(0.5, [0.8, 0.8], [0.0, 0.0], [0.0, 0.0])])
    assert c.on_command(stop, now=1.2, actual=at).accepted
    for dt in (1e-6, -1e-6):
        near = c.desired_at(1.2 + dt)
        np.testing.assert_allclose(near.positions, at.positions, atol=1e-5)
        np.testing.assert_allclose(near.velocities, at.velocities, atol=1e-4)
        np.testing.assert_allclose(near.accelerations, at.accelerations, atol=1e-2)
    np.testing.assert_allclose(c.desired_at(1.7).positions, [0.8, 0.8])


@pytest.mark.parametrize(
    "given, order",
    [
        ({}, "linear"),
        ({"velocities": [0.0, 0.0]}, "cubic"),
        ({"velocities": [0.0, 0.0], "accelerations": [0, 0]}, "quintic"),
    ],
)
def test_the_spline_follows_what_the_points_give(given: dict[str, list[float]], order: str) -> None:
    c = controller()
    first = Point(1.0, [1.0, 1.0], **given)  # type: ignore[arg-type]
    c.on_command(TrajectoryMessage(0.0, JOINTS, [first, Point(2.0, [2.0, 2.0], **given)]), 0.0, HOME)  # type: ignore[arg-type]
    middle = c.desired_at(1.5)
    if order == "linear":
        np.testing.assert_allclose(middle.velocities, [1.0, 1.0])
        np.testing.assert_allclose(middle.accelerations, [0.0, 0.0], atol=1e-12)
    elif order == "cubic":
        np.testing.assert_allclose(middle.velocities, [1.5, 1.5])  # 3/2 · Δp/T for a rest-to-rest cubic
    else:
        np.testing.assert_allclose(middle.velocities, [1.875, 1.875])  # 15/8 · Δp/T for a rest-to-rest quintic
    np.testing.assert_allclose(c.desired_at(1.0).positions, [1.0, 1.0])


def test_a_command_message_during_a_goal_cancels_the_goal() -> None:
    c = controller()
    c.on_goal("g1", to([1.0, 1.0], 2.0), GoalTolerances(), 0.0, HOME)
    verdict = c.on_command(to([0.0, 0.0], 1.0), now=1.0, actual=follow(c, 1.0))
    assert verdict.accepted and c.active_goal is None
    (event,) = verdict.ended
    assert event.goal_id == "g1" and event.ending is Ending.CANCELED
    np.testing.assert_allclose(c.desired_at(2.0).positions, [0.0, 0.0])


def test_a_new_goal_cancels_the_one_before() -> None:
    c = controller()
    c.on_goal("g1", to([1.0, 1.0], 2.0), GoalTolerances(), 0.0, HOME)
    verdict = c.on_goal("g2", to([2.0, 2.0], 2.0), GoalTolerances(), 1.0, follow(c, 1.0))
    assert verdict.accepted and [(e.goal_id, e.ending) for e in verdict.ended] == [("g1", Ending.CANCELED)]
    assert c.active_goal == "g2"


def test_cancel_with_no_stop_duration_holds_the_measured_position_at_once() -> None:
    c = controller()
    c.on_goal("g1", to([1.0, 1.0], 2.0), GoalTolerances(), 0.0, HOME)
    measured = JointState(np.array([0.4, 0.45]), np.array([0.5, 0.5]), np.zeros(2))  # lagging its desired 0.5
    (event,) = c.on_cancel("g1", now=1.0, actual=measured)
    assert event.ending is Ending.CANCELED and c.active_goal is None
    held = c.update(1.0, measured).desired
    np.testing.assert_allclose(held.positions, [0.4, 0.45])  # the measured position: a step in velocity
    np.testing.assert_allclose(held.velocities, [0.0, 0.0])
    assert c.on_cancel("g1", 1.1, measured) == ()  # no longer active


def test_cancel_with_a_stop_duration_decelerates_from_the_measured_state() -> None:
    c = controller(stop_trajectory_duration=0.4)
    c.on_goal("g1", to([1.0, 1.0], 2.0), GoalTolerances(), 0.0, HOME)
    measured = JointState(np.array([0.5, 0.5]), np.array([0.5, -1.0]), np.zeros(2))
    c.on_cancel("g1", now=1.0, actual=measured)
    start = c.desired_at(1.0)
    np.testing.assert_allclose(start.positions, [0.5, 0.5])
    np.testing.assert_allclose(start.velocities, [0.5, -1.0])  # no step in velocity
    np.testing.assert_allclose(start.accelerations, [0.0, 0.0], atol=1e-12)
    # ros_controllers' stop: the midpoint of the quintic from (p, v) to (p, -v) over 2T, at p + 5/8·v·T.
    stopped = c.desired_at(1.4 - 1e-9)
    np.testing.assert_allclose(stopped.positions, [0.5 + 0.5 * 0.25, 0.5 - 1.0 * 0.25], atol=1e-8)
    np.testing.assert_allclose(stopped.velocities, [0.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(c.desired_at(2.0).positions, [0.625, 0.25])
    np.testing.assert_allclose(c.desired_at(2.0).velocities, [0.0, 0.0])


def test_a_path_violation_aborts_the_goal_but_the_trajectory_goes_on() -> None:
    c = controller()
    tolerances = GoalTolerances(path=[JointTolerance("a", position=0.05)])
    c.on_goal("g1", to([1.0, 1.0], 2.0), tolerances, 0.0, HOME)
    assert c.update(0.5, follow(c, 0.5)).ended == ()
    lagging = JointState(np.array([0.1, 0.5]), np.array([0.5, 0.5]), np.zeros(2))  # joint a 0.4 behind
    update = c.update(1.0, lagging)
    (event,) = update.ended
    assert event.ending is Ending.ABORTED and event.code == ErrorCode.PATH_TOLERANCE_VIOLATED and "a off" in event.text
    np.testing.assert_allclose(c.desired_at(1.5).positions, [0.75, 0.75])  # still following the trajectory


def test_the_goal_succeeds_within_its_goal_tolerance_after_the_last_point() -> None:
    c = controller(goal_time=0.5)
    c.on_goal("g1", to([1.0, 1.0], 1.0), GoalTolerances(goal=[JointTolerance("a", position=0.01)]), 0.0, HOME)
    assert c.update(0.99, JointState.at_rest([0.5, 1.0])).ended == ()  # before the last point: no goal check
    assert c.update(1.0, JointState.at_rest([0.9, 1.0])).ended == ()  # outside, within the goal time: waits
    (event,) = c.update(1.2, JointState.at_rest([0.995, 1.0])).ended
    assert event.ending is Ending.SUCCEEDED and event.code == ErrorCode.SUCCESSFUL


def test_a_goal_time_of_zero_aborts_at_the_first_update_after_the_last_point_when_outside() -> None:
    # ros_controllers: no time left to settle; the default stopped-velocity tolerance (0.01) holds the velocity.
    c = controller()
    c.on_goal("g1", to([1.0, 1.0], 1.0), GoalTolerances(), 0.0, HOME)
    moving = JointState(np.array([1.0, 1.0]), np.array([0.02, 0.0]), np.zeros(2))
    (event,) = c.update(1.0, moving).ended
    assert event.ending is Ending.ABORTED and event.code == ErrorCode.GOAL_TOLERANCE_VIOLATED and "a off" in event.text
    c.on_goal("g2", to([0.0, 0.0], 1.0), GoalTolerances(), 2.0, JointState.at_rest([1.0, 1.0]))
    (event,) = c.update(3.0, JointState.at_rest([0.0, 0.0])).ended
    assert event.ending is Ending.SUCCEEDED


def test_a_goal_time_tolerance_overrides_the_default_and_a_negative_one_means_none() -> None:
    c = controller(goal_time=0.5)
    moving = JointState(np.array([0.0, 0.0]), np.array([0.2, 0.0]), np.zeros(2))  # not stopped
    c.on_goal("g1", to([0.0, 0.0], 1.0), GoalTolerances(goal_time=1.0), 0.0, HOME)
    assert c.update(1.6, moving).ended == ()  # the goal's 1.0 s, not the default 0.5 s
    (event,) = c.update(2.0, moving).ended
    assert event.ending is Ending.ABORTED and event.code == ErrorCode.GOAL_TOLERANCE_VIOLATED
    c.on_goal("g2", to([0.0, 0.0], 1.0), GoalTolerances(goal_time=-1.0), 3.0, HOME)
    (event,) = c.update(4.0, moving).ended
    assert event.ending is Ending.ABORTED


def test_wrong_joints_are_invalid_joints_and_the_motion_carries_on() -> None:
    c = controller()
    c.on_goal("g1", to([1.0, 1.0], 2.0), GoalTolerances(), 0.0, HOME)
    wrong = TrajectoryMessage(0.0, ("a", "c"), [Point(1.0, [0.0, 0.0])])
    verdict = c.on_goal("g2", wrong, GoalTolerances(), 1.0, follow(c, 1.0))
    assert not verdict.accepted and verdict.code == ErrorCode.INVALID_JOINTS and "'c'" in verdict.text
    assert not c.on_command(wrong, 1.0, follow(c, 1.0)).accepted
    partial = TrajectoryMessage(0.0, ("a",), [Point(1.0, [0.0])])
    assert c.on_goal("g3", partial, GoalTolerances(), 1.0, follow(c, 1.0)).code == ErrorCode.INVALID_JOINTS
    assert c.active_goal == "g1"
    np.testing.assert_allclose(c.desired_at(2.0).positions, [1.0, 1.0])


def test_joints_in_another_order_are_matched_by_name() -> None:
    c = controller()
    c.on_command(TrajectoryMessage(0.0, ("b", "a"), [Point(1.0, [2.0, 1.0])]), 0.0, HOME)
    np.testing.assert_allclose(c.desired_at(1.0).positions, [1.0, 2.0])


def test_an_empty_trajectory_means_hold_and_cancels_the_goal() -> None:
    c = controller()
    c.on_goal("g1", to([1.0, 1.0], 2.0), GoalTolerances(), 0.0, HOME)
    measured = follow(c, 1.0)
    verdict = c.on_command(TrajectoryMessage(0.0, (), []), 1.0, measured)
    assert verdict.accepted and [e.ending for e in verdict.ended] == [Ending.CANCELED]
    np.testing.assert_allclose(c.desired_at(3.0).positions, measured.positions)


def test_settings_that_cannot_work_are_refused() -> None:
    with pytest.raises(ControllerError, match="stop_trajectory_duration"):
        controller(stop_trajectory_duration=-1.0)
    with pytest.raises(ControllerError, match="distinct joint names"):
        TrajectoryController(("a", "a"), [0.0, 0.0])
