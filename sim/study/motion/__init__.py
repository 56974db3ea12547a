"""The participant's own motion during each approach, from their tracked head and hands (the trial protocol's pose
topics): which hand is under the robot, how far and how fast it withdrew, where the head was at the press, and how
long tracking was lost (measures.py); and a tracker calibrated into the scene's world from touched points, with its
jitter at rest (calibration.py). Pure logic: the runner and the tracker relay feed it the poses they received."""

from __future__ import annotations

__all__: list[str] = []
