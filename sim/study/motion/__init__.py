"""The participant's own motion during each approach, from their tracked head and hands (the trial protocol's pose
topics): which hand is under the robot, how far and how fast it withdrew, where the head was at the press, and how
long tracking was lost (measures.py). Pure logic: the runner feeds it the poses it received."""

from __future__ import annotations

__all__: list[str] = []
