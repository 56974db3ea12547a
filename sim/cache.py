"""What sim/ computes once and keeps between runs (self-contact verdicts, scenes proposed for arms): where it
lives, and how an entry is read and written, keyed by the hash of what it was computed from."""

from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path

__all__ = ["cache_dir", "entry_path", "keep"]

log = logging.getLogger(__name__)


def cache_dir() -> Path:
    """$VR_SIM_CACHE, else $XDG_CACHE_HOME/vr_sim, else ~/.cache/vr_sim."""
    if os.environ.get("VR_SIM_CACHE"):
        return Path(os.environ["VR_SIM_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "vr_sim"


def entry_path(kind: str, identity: str, suffix: str) -> Path:
    """The file of the entry of `kind` computed from `identity` (a text that changes whenever the result would)."""
    return cache_dir() / kind / f"{hashlib.sha256(identity.encode()).hexdigest()}{suffix}"


def keep(path: Path, text: str) -> None:
    """Write an entry whole or not at all, for a concurrent reader. A cache that cannot be written is a warning:
    the result stands, only the next run computes it again."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_suffix(f".{os.getpid()}.tmp")
        partial.write_text(text, encoding="utf-8")
        partial.replace(path)
    except OSError as error:
        log.warning("cannot keep %s in the cache %s: %s", path.name, path.parent, error)
