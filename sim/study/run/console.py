"""The runner's lines to the observer's terminal (stderr): one prefix, flushed at once so that they interleave in
order with the runner's prompts."""

from __future__ import annotations

import sys

__all__ = ["say"]


def say(text: str) -> None:
    print(f"sim.study run: {text}", file=sys.stderr, flush=True)
