"""The pixels of a colour in a screenshot, for the web pages' tests."""

from __future__ import annotations

import numpy as np


def pixels_like(image: np.ndarray, colour: tuple[int, int, int], tolerance: int = 60) -> int:
    """Pixels of about that colour, lit or shaded: the same hue, within `tolerance` per channel once the brightness
    is matched, and saturated (white, grey and black are not colours)."""
    reference = np.array(colour, dtype=float)
    brightness = image.sum(axis=2, keepdims=True) / max(reference.sum(), 1.0)
    matched = np.abs(image - brightness * reference).max(axis=2) < tolerance
    saturated = image.max(axis=2) - image.min(axis=2) > 60
    return int((matched & saturated).sum())
