"""The whole study with simulated participants, end to end: its own roscore, endpoint, engines, runners and
simulated participants, then the report. (The sample size in sim.study.power simulates studies without any of
them.)"""

from __future__ import annotations

__all__: list[str] = []
