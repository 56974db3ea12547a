"""The toolkit's own safety checks for a robot near a person, before and during motion: the robots' published motion
limits and the check of a plan against them (limits.py), and the stop on a press as one smooth trajectory along the
path for a trajectory controller (braking.py), speed and separation monitoring by ISO/TS 15066's protective
separation distance, live and over a plan (separation.py), and an approach's IK without the collision world for
their tests and benches (kinematic_plan.py). Pure. They never replace the robot's own stop."""

from __future__ import annotations

__all__: list[str] = []
