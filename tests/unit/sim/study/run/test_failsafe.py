"""Every exit of a motion brakes: an exception of any kind, a return with the arm still commanded to move; an exit at
rest or with a stop in force sends nothing more. The link's clock carries wall time on the monotonic clock and
measures a step of the wall clock. A move brakes along its line in joint space."""

from __future__ import annotations

import numpy as np
import pytest

from sim.study.run.errors import RunError
from sim.study.run.links.clock import LinkClock
from sim.study.run.links.joint_line import MOVE_DECELERATION, MOVE_JERK, JointLine
from sim.study.run.links.supervision import brakes_on_exit
from sim.study.safety.braking import brake


class Motion:
    def __init__(self, settled: bool) -> None:
        self.is_settled = settled
        self.braked: list[str] = []

    def settled(self) -> bool:
        return self.is_settled

    def fail_safe(self, why: str) -> None:
        self.braked.append(why)
        self.is_settled = True


@pytest.mark.parametrize("error", [RuntimeError("lost"), KeyboardInterrupt(), SystemExit(4), ValueError()])
def test_an_exception_of_any_kind_brakes_a_moving_arm_and_goes_on(error: BaseException) -> None:
    motion = Motion(settled=False)
    with pytest.raises(type(error)), brakes_on_exit(motion):
        raise error
    assert motion.braked == [f"{type(error).__name__}: {error}" if str(error) else type(error).__name__]


def test_a_return_with_the_arm_still_commanded_to_move_brakes_it() -> None:
    motion = Motion(settled=False)
    with brakes_on_exit(motion):
        pass
    assert motion.braked == ["the motion's code ended with the arm still commanded to move"]


def test_an_exit_at_rest_or_with_a_stop_in_force_sends_nothing() -> None:
    motion = Motion(settled=True)
    with pytest.raises(RuntimeError), brakes_on_exit(motion):
        raise RuntimeError("after the stop")
    with brakes_on_exit(motion):
        pass
    assert motion.braked == []


def test_the_links_clock_is_not_moved_by_a_step_of_the_wall_clock_and_measures_it() -> None:
    wall, monotonic = [1000.0], [5.0]
    clock = LinkClock(lambda: wall[0], lambda: monotonic[0])
    monotonic[0] += 1.0
    wall[0] += 1.0
    assert clock() == pytest.approx(1001.0) and clock.step() == pytest.approx(0.0)
    wall[0] -= 2.0  # stepped back 2 s
    monotonic[0] += 0.5
    wall[0] += 0.5
    assert clock() == pytest.approx(1001.5) and clock.step() == pytest.approx(-2.0)
    clock.anchor()
    assert clock() == pytest.approx(999.5) and clock.step() == pytest.approx(0.0)


def test_a_move_brakes_along_its_line_in_joint_space_continuously_and_within_its_deceleration() -> None:
    start, end = np.zeros(3), np.array([0.6, -0.8, 0.0])
    line = JointLine(start, end)
    assert line.length == pytest.approx(1.0)
    speed = 0.5  # rad/s along the line, at its middle
    q, qd = line.joints(0.5), line.direction * speed
    stop = brake(line, q, qd, np.zeros(3), 0.002, MOVE_DECELERATION, MOVE_JERK)
    assert stop is not None
    assert np.allclose(stop.positions[0], q) and np.allclose(stop.velocities[0], qd)
    assert np.allclose(stop.velocities[-1], 0.0) and np.allclose(stop.accelerations[-1], 0.0, atol=1e-9)
    along = stop.positions @ line.direction
    assert np.all(np.diff(along) >= -1e-12) and along[-1] < line.length  # forward only, short of the end
    assert np.allclose(np.cross(stop.positions - start, line.direction[None, :]), 0.0)  # on the line
    assert np.max(np.linalg.norm(stop.accelerations, axis=1)) <= MOVE_DECELERATION + 1e-9
    assert stop.distance == pytest.approx(
        speed**2 / (2 * MOVE_DECELERATION) + speed * MOVE_DECELERATION / (2 * MOVE_JERK), rel=0.02
    )
    with pytest.raises(RunError, match="no length"):
        JointLine(start, start)
