"""The runner's robot link, chosen per condition: how the runner moves the arm, stops it and reads its state.

- stream (stream.py): today's stand-in link: one-point commands per step on `<robot>/arm_controller/command`, the
  runner owning /clock (lockstep, or paced by the wall clock with --realtime).
- trajectory controller (trajectory.py): a real arm's ros_control joint_trajectory_controller on wall time: each
  approach one follow_joint_trajectory goal, a press a braking replacement, the arm's joint states read at whatever
  rate its driver publishes them; no /clock.
"""

from __future__ import annotations

__all__: list[str] = []
