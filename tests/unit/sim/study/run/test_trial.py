"""sim.study.run.trial driven against the physics in lockstep, as the runner node will drive it: without a press the
robot rests at the planned stand-off; a press brakes it along the path, and the distances at the press, at rest and
by the thesis's extrapolation are what the motion shows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.engine.physics import Mode, PhysicsWorld
from sim.study.design.feasibility import SceneWorld, plan_approach, plan_combination
from sim.study.design.paths import ON_TOP, approach_path
from sim.study.design.scene import load_scene, scene_robot
from sim.study.errors import StudyError
from sim.study.run.stop import STOP_DECELERATION
from sim.study.run.trial import TrialRun, state_at
from sim.wire.contract import STEP_S

SCENE = load_scene()
ROBOT = scene_robot(SCENE)


@pytest.fixture(scope="module")
def world():
    with SceneWorld(ROBOT, SCENE) as made:
        yield made


@pytest.fixture(scope="module")
def planned(world):
    return plan_combination(ROBOT, SCENE, ("vertical", ON_TOP, 0.2), STEP_S, world)


def trial_of(planned, world) -> TrialRun:
    return TrialRun(ROBOT, planned, world.hand_distance)


def run(planned, world, press_below: float | None = None, mode: Mode = Mode.PHYSICS, hold_s: float = 1.0) -> TrialRun:
    """Step the physics along the trial; press once the achieved distance is below `press_below`."""
    trial = trial_of(planned, world)
    with PhysicsWorld(ROBOT, mode=mode, dt=trial.dt, q0=planned.positions[0]) as world:
        trial.record_state(0.0, world.state().positions)
        k = 0
        while k < trial.steps + round(hold_s / trial.dt):
            k += 1
            world.set_targets(*trial.target(k))
            state = world.step()
            trial.record_state(k * trial.dt, state.positions)
            if press_below is not None and trial.stopped is None and trial.hand_distance(state.positions) < press_below:
                trial.press(k * trial.dt)
    return trial


def test_without_a_press_the_robot_rests_at_the_planned_standoff(planned, world):
    measures = run(planned, world).measures()
    assert not measures.pressed and math.isnan(measures.distance_at_press)
    assert measures.distance_at_rest == pytest.approx(ON_TOP, abs=5e-4)


def test_a_press_brakes_along_the_path_and_the_distances_tell_it(planned, world):
    trial = run(planned, world, press_below=0.15)
    measures = trial.measures()
    assert measures.pressed and 0.14 < measures.distance_at_press < 0.15
    # straight down onto the hand: the distance shrinks by exactly the braking distance, v² / (2a)
    assert measures.distance_at_press - measures.distance_at_rest == pytest.approx(measures.braking_distance, abs=1e-3)
    assert measures.braking_distance <= 0.2**2 / (2 * STOP_DECELERATION) + 1e-9
    assert measures.distance_at_rest > ON_TOP + 0.1  # stopped well before the plan's end
    assert measures.distance_extrapolated == pytest.approx(measures.distance_at_press, abs=1e-3)


def test_only_the_first_press_counts_and_targets_hold_at_rest(planned, world):
    trial = trial_of(planned, world)
    trial.press(1.0)
    first = trial.stopped
    trial.press(0.5)
    assert trial.stopped is first
    positions, velocities = trial.target(10_000)
    np.testing.assert_array_equal(positions, first.joint_positions[-1])
    assert not velocities.any()


def test_bad_trials_and_states_are_named(planned, world):
    fast = plan_approach(ROBOT, SCENE, approach_path(SCENE, "lateral_arc", 0.05, 1.0), world)
    with pytest.raises(StudyError, match="is not feasible: .*velocity limit"):
        trial_of(fast, world)
    trial = trial_of(planned, world)
    with pytest.raises(StudyError, match="no joint state was recorded"):
        trial.measures()
    with pytest.raises(StudyError, match="needs 7 finite positions"):
        trial.record_state(0.0, [0.0] * 6)


def test_the_achieved_state_at_a_press_is_interpolated_between_the_samples_around_it(planned, world):
    # Joint states 1/30 s apart (franka's feed), the arm moving linearly in time: the state at a press between two of
    # them is on the line between them, per joint, not the nearest sample (which would be up to half a step off).
    trial = trial_of(planned, world)
    h = 1 / 30
    start, step = planned.positions[0], np.linspace(0.001, 0.007, ROBOT.dof)
    for k in (0, 2, 1, 3):  # out of order: a late delivery
        trial.record_state(k * h, start + k * step)
    np.testing.assert_allclose(trial.positions_at(1.5 * h), start + 1.5 * step, atol=1e-12)
    np.testing.assert_allclose(trial.positions_at(0.2 * h), start + 0.2 * step, atol=1e-12)
    np.testing.assert_allclose(trial.positions_at(2 * h), start + 2 * step, atol=1e-12)  # on a sample: that one
    np.testing.assert_allclose(trial.positions_at(-1.0), start)  # before the first and after the last: held
    np.testing.assert_allclose(trial.positions_at(10 * h), start + 3 * step)
    trial.press(1.5 * h)
    distance = trial.measures().distance_at_press
    assert distance == pytest.approx(world.hand_distance(start + 1.5 * step), abs=1e-9)


def test_of_samples_at_one_time_the_last_recorded_counts():
    # a trajectory link records the arm at rest at its start, then the controller's first state stamped there too
    q0, q1, q2 = np.zeros(2), np.ones(2), np.full(2, 3.0)
    np.testing.assert_allclose(state_at([(0.0, q0), (0.0, q1), (1.0, q2)], 0.5), np.full(2, 2.0))
    with pytest.raises(StudyError, match="no joint state"):
        state_at([], 0.0)
