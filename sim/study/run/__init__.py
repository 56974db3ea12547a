"""A session as it runs: the runner node, its trial steps, the stop on a press, the protocol that the runner and
whoever answers it (a VR page, a simulated participant, the observer) speak, and the records it writes."""

from __future__ import annotations

__all__: list[str] = []
