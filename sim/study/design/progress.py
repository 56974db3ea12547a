"""Progress of the study's long work (a scene proposed for an arm, a design's combinations planned) on stderr, as a
tqdm bar: on a terminal only (tqdm's own test), so a pipe or a log gets the result alone."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Callable

from tqdm import tqdm

__all__ = ["Progress", "progress_bar"]

# (done so far, of how many, what was just done): what the long work reports after each step
Progress = Callable[[int, int, str], None]


@contextmanager
def progress_bar(what: str, unit: str) -> Iterator[Progress]:
    """A Progress that moves a bar named `what` on stderr, at most twice a second; closed (and wiped) on leaving."""
    with tqdm(desc=what, unit=unit, file=sys.stderr, disable=None, leave=False, mininterval=0.5) as bar:

        def step(done: int, total: int, line: str) -> None:
            bar.total = total
            bar.set_postfix_str(line[:60], refresh=False)
            bar.update(done - bar.n)

        yield step
