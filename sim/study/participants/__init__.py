"""Participants that are not people: the model of how they judge and react (traits drawn from a population), and
the simulated participant that answers the runner through the endpoint, as a VR scene would."""

from __future__ import annotations

__all__: list[str] = []
