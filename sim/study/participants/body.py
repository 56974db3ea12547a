"""A simulated participant's tracked body (body_poses: the poses the protocol's pose topics carry, in the scene's
world frame), a pure function of the time:
  head                  at the seat (the eyes), looking at the hand, with a small slow sway (HEAD_SWAY);
  right_hand            the hand under the robot: resting on the scene hand's top surface, palm down along the scene
                        hand; after the press (at once, or late) it withdraws by the trial's distance,
                        horizontally toward the seat (out from under the robot's approach from above: across the
                        direction to the end effector, so the measure counts it whole), on a minimum-jerk profile
                        over the trial's duration: so its farthest displacement is the distance put in and its peak
                        speed 1.875 x distance / duration;
  left_hand             resting on the table between the seat and the hand, to the participant's left;
  each position carries the tracker's jitter (TRACKING_JITTER, normal per axis) when a random stream is given.

Pure logic. What the participant does (how far and when the hand withdraws, drawn per trial) is
sim.study.participants.model's; this module is where their body is while they do it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Tuple

import numpy as np

from sim.geometry.frames import euler_xyz_to_quat
from sim.study.participants.errors import ParticipantError
from sim.study.participants.model import WITHDRAWAL_DURATION, WithdrawalTiming
from sim.study.run.protocol import BODIES

if TYPE_CHECKING:  # only its fields are read
    from sim.study.design.scene import Scene

__all__ = [
    "TRACKING_JITTER",
    "HEAD_SWAY",
    "min_jerk",
    "withdrawal_peak_speed",
    "BodyLayout",
    "body_layout",
    "Pose",
    "body_poses",
]

TRACKING_JITTER = 0.0001  # m, SD per axis: a headset's and its controllers' tracking noise is sub-millimetre
HEAD_SWAY = (0.004, 5.0)  # m and s: the head's sway from side to side, its amplitude and period
_LEFT_HAND_FORWARD, _LEFT_HAND_ASIDE = 0.3, 0.2  # m from under the eyes: toward the scene hand, to the left

AT_ONCE = WithdrawalTiming(0.0, WITHDRAWAL_DURATION)  # a withdrawal at the press, quick: body_poses' default

Pose = Tuple[np.ndarray, np.ndarray]  # position (x, y, z) and orientation as a unit quaternion (x, y, z, w)


def min_jerk(fraction: float) -> float:
    """How much of a minimum-jerk movement is done at `fraction` of its duration (0 before, 1 after): 10τ³ − 15τ⁴ +
    6τ⁵, at rest at both ends; its speed peaks at τ = ½ with 1.875 x distance / duration."""
    tau = min(max(fraction, 0.0), 1.0)
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


def withdrawal_peak_speed(distance: float, duration: float = WITHDRAWAL_DURATION) -> float:
    """The peak speed (m/s) of a withdrawal of `distance` m over `duration` s (minimum jerk)."""
    return 1.875 * distance / duration


@dataclass(frozen=True)
class BodyLayout:
    """Where the participant's body rests in a scene (world frame), and which way the hand withdraws."""

    head: np.ndarray  # (3,) the eyes: the scene's seat
    hand: np.ndarray  # (3,) the hand under the robot at rest: the centre of the scene hand's top
    other_hand: np.ndarray  # (3,) the other hand at rest, on the table
    away: np.ndarray  # (3,) unit, horizontal: from the hand toward the seat, the way the hand withdraws
    aside: np.ndarray  # (3,) unit, horizontal: the participant's left, facing the hand from the seat
    orientations: dict[str, np.ndarray]  # by body: its unit quaternion (x, y, z, w), which stays


def _unit(vector: np.ndarray, what: str) -> np.ndarray:
    norm = float(np.linalg.norm(vector))
    if not (math.isfinite(norm) and norm > 1e-6):
        raise ParticipantError(f"no direction {what}: the scene's seat and hand are at the same place")
    return vector / norm


def body_layout(scene: Scene) -> BodyLayout:
    """The participant seated at `scene.seat`, their right hand on the scene hand (under the robot), their left on
    the table between them and it; looking at the hand."""
    hand = scene.hand.top
    seat = np.asarray(scene.seat, dtype=float)
    toward = _unit(np.array([hand[0] - seat[0], hand[1] - seat[1], 0.0]), "from the seat to the hand")
    aside = np.array([-toward[1], toward[0], 0.0])  # a quarter turn to the left about z (up)
    table_top = float(scene.table.top[2])
    other_hand = seat + _LEFT_HAND_FORWARD * toward + _LEFT_HAND_ASIDE * aside
    other_hand[2] = table_top + float(scene.hand.size[2])  # on the table, at a hand's height as the other
    look = hand - seat
    heading = math.atan2(toward[1], toward[0])
    pitch = math.atan2(-look[2], math.hypot(look[0], look[1]))  # positive: looking down
    return BodyLayout(
        head=seat,
        hand=hand,
        other_hand=other_hand,
        away=-toward,
        aside=aside,
        orientations={
            "head": euler_xyz_to_quat(0.0, pitch, heading),
            "left_hand": euler_xyz_to_quat(0.0, 0.0, heading),  # palm down, fingers toward the hand
            "right_hand": euler_xyz_to_quat(0.0, 0.0, scene.hand.yaw),  # palm down along the scene hand
        },
    )


def body_poses(
    layout: BodyLayout,
    t: float,
    withdrawal: float = 0.0,
    press_time: float = math.nan,
    jitter: np.random.Generator | None = None,
    timing: WithdrawalTiming = AT_ONCE,
) -> dict[str, Pose]:
    """Each body's pose (BODIES) at time `t` (s, on the trial's clock). The hand under the robot (right_hand)
    withdraws by `withdrawal` m, `timing.delay` after `press_time` over `timing.duration` (NaN press: no press, it
    stays); with `jitter`, each position carries the tracking's noise, drawn from it in the order of BODIES."""
    if not (math.isfinite(withdrawal) and withdrawal >= 0.0):
        raise ParticipantError(f"a withdrawal must be >= 0 m, got {withdrawal!r}")
    amplitude, period = HEAD_SWAY
    head = layout.head + amplitude * math.sin(2.0 * math.pi * t / period) * layout.aside
    hand = layout.hand
    if math.isfinite(press_time):
        hand = hand + withdrawal * min_jerk((t - press_time - timing.delay) / timing.duration) * layout.away
    positions = {"head": head, "left_hand": layout.other_hand, "right_hand": hand}
    if jitter is not None:
        noise = jitter.normal(0.0, TRACKING_JITTER, (len(BODIES), 3))
        positions = {body: positions[body] + noise[k] for k, body in enumerate(BODIES)}
    return {body: (positions[body], layout.orientations[body]) for body in BODIES}
