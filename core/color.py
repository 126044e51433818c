"""Colour: the one luminance table (Rec. 709 / sRGB primaries, what Blender's scene-linear
space uses). Power shares, Russian-roulette-free weights and the exporter's lobe weights all
measure "how bright" with it."""

from __future__ import annotations

import numpy as np

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""Rec. 709 luminance weights of linear R, G, B."""


def luminance(rgb) -> np.ndarray:
    """Luminance of linear RGB values (..., 3) -> (...) float64."""
    return np.asarray(rgb, np.float64) @ LUMINANCE
