"""The sample size before anyone is recruited: whole studies simulated from the participant model and analysed
as a real one is, their report, and the pre-registration summary."""

from __future__ import annotations

__all__: list[str] = []
