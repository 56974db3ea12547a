"""The study's inputs and what is planned from them, before anyone comes in: the scene (where the robot, the
table and the hand are), the design (which combinations each test presents, and each test's SESOI), the approach
paths, each participant's session plan, and the check that makes every combination joint motion that can run."""

from __future__ import annotations

__all__: list[str] = []
