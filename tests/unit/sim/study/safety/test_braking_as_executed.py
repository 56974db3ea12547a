"""The stop as a trajectory controller executes it: the approach as one goal, a press at any time (between the plan's
samples too), and sim.study.safety.braking's stop sent as a replacement stamped a little ahead, from the desired
state query_state gives for then. What the controller makes of it (its own quintics between the stop's samples, and
its bridge from the approach) never exceeds the Panda's published acceleration or jerk limits, at any press time.

test_braking.py checks the stop's own profile at the plan's samples; this checks what the arm is asked to do."""

from __future__ import annotations

import numpy as np
import pytest

from sim.engine.trajectory_controller import GoalTolerances, JointState, Point, TrajectoryController, TrajectoryMessage
from sim.study.safety.braking import PathGeometry, PathState, arc_length, brake
from sim.study.safety.limits import limits_for
from tests.unit.sim.study.safety.plans import PANDA, panda_plan

DT = 0.004  # the replacement's sample step
LEAD = 0.05  # s: the replacement is sent this long before its stamp (the press's look-ahead)
PRESSES = 24  # per plan, spread over the whole approach and off its sample grid
SAMPLE = 0.0005  # s: how finely the executed desired state is read


def approach_goal(geometry: PathGeometry, path) -> TrajectoryMessage:  # type: ignore[no-untyped-def]
    arc, accelerations = arc_length(path), np.gradient(path.speeds, path.dt)
    points = []
    for k in range(1, len(arc)):
        q, v, a = geometry.joint_state(PathState(arc[k], path.speeds[k], accelerations[k]))
        points.append(Point(float(path.times[k]), q, v, a))
    return TrajectoryMessage(0.0, PANDA.joint_names, points)


@pytest.mark.parametrize("name, speed", [("diagonal", 0.5), ("vertical", 0.5), ("lateral_arc", 0.3)])
def test_the_executed_stop_stays_within_the_pandas_acceleration_and_jerk_limits_at_any_press_time(name, speed) -> None:
    path, joints = panda_plan(name, speed)
    geometry = PathGeometry(path, joints)
    limits = limits_for(PANDA)
    assert limits.acceleration is not None and limits.jerk is not None
    goal = approach_goal(geometry, path)
    start = JointState.at_rest(joints[0])
    end = float(path.times[-1])
    presses = np.linspace(LEAD + 0.013, end - 0.011, PRESSES)  # 0.013 and 0.011: never on the 0.02 s grid
    braked = 0
    for press in presses:
        controller = TrajectoryController(PANDA.joint_names, joints[0])
        assert controller.on_goal("approach", goal, GoalTolerances(), 0.0, start).accepted
        sent = press - LEAD
        desired = controller.desired_at(press)  # query_state at the press's stamp
        stop = brake(geometry, desired.positions, desired.velocities, desired.accelerations, DT)
        if stop is None:  # the plan rests before braking would: it is left running
            continue
        braked += 1
        points = [
            Point(float(t), q, v, a)
            for t, q, v, a in zip(stop.times[1:], stop.positions[1:], stop.velocities[1:], stop.accelerations[1:])
        ]
        replacement = TrajectoryMessage(press, PANDA.joint_names, points)
        verdict = controller.on_goal("stop", replacement, GoalTolerances(), sent, controller.desired_at(sent))
        assert verdict.accepted, verdict.text
        times = np.arange(press - 0.01, press + stop.duration + 0.01, SAMPLE)
        states = [controller.desired_at(t) for t in times]
        accelerations = np.array([s.accelerations for s in states])
        jerks = np.diff(accelerations, axis=0) / SAMPLE  # a step in acceleration would show here, as a huge jerk
        where = f"{name}, press at {press:.3f} s"
        assert np.all(np.abs(accelerations) <= limits.acceleration), (where, np.abs(accelerations).max(axis=0))
        assert np.all(np.abs(jerks) <= limits.jerk), (where, np.abs(jerks).max(axis=0))
        np.testing.assert_allclose(states[-1].velocities, 0.0, atol=1e-9)  # at rest
        np.testing.assert_allclose(states[-1].positions, stop.positions[-1], atol=1e-9)  # where braking rests
    assert braked >= PRESSES // 2, f"{name}: only {braked} of {PRESSES} presses braked"
