"""The perception study the thesis proposes (§2.3): the scene, approach paths, session plans, the runner with the
VR stop trigger, simulated participants, the analysis."""

from __future__ import annotations

__all__: list[str] = []
