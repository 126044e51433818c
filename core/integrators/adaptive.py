"""Adaptive sampling: camera samples go where a pixel is still noisy.

A camera pass with ``settings.adaptive_threshold`` > 0 gives every pixel ``min_samples``
samples, then doubles the samples of each pixel whose ``relative_error`` is above the
threshold, round after round, up to ``settings.samples`` (Cycles' Noise Threshold, Min
Samples and Max Samples). The noise of a camera sample is mostly what the camera path
finds by BSDF sampling (glossy and rough-glass bounces, the light seen through them, a
small light's reflection), which varies by orders of magnitude from pixel to pixel: a
matte wall lit through the photon maps converges at the minimum while the frosted glass
beside it takes every sample.

The error of a pixel is the one the benchmarks measure (benchmarks/tradeoff.py's relMSE):
the estimated variance of its mean over (its mean^2 + 0.01), averaged over the channels,
square-rooted, so the threshold is a relative standard error (0.05: 5 % of the pixel's
value, or of 0.1 in the dark). Stopping on an estimate is slightly biased (a pixel whose
samples have not yet met a rare bright path looks converged and stops dark): the
neighbour rule (``NEIGHBOURS``: a pixel keeps sampling while a pixel near it in its row
does) is the main guard, ``min_samples`` the second (the glass sphere under an area light,
against Cycles at threshold 0.1: -2.7 % with the minimum alone, -0.89 % with the rule;
docs/photon_rendering.md, "Adaptive sampling").
"""

from __future__ import annotations

import numpy as np

from ..settings import RenderSettings

EPSILON = 0.01
"""Added to a pixel's mean^2 in its relative error (linear radiance units): the dark
pixels' noise is measured against 0.1, as relMSE does."""


def min_samples(settings: RenderSettings) -> int:
    """Samples every pixel takes first: ``settings.samples`` without adaptive sampling,
    else ``adaptive_min_samples``, or when that is 0 a quarter of ``samples`` (at least 4),
    never more than ``samples``."""
    if settings.adaptive_threshold <= 0.0:
        return settings.samples
    wanted = settings.adaptive_min_samples or max(4, settings.samples // 4)
    return min(wanted, settings.samples)


class Moments:
    """Running per-pixel sums of a tile's sample values: total (P, 3), squares (P, 3)
    float64 and count (P,) int64."""

    def __init__(self, pixels: int):
        self.total = np.zeros((pixels, 3))
        self.squares = np.zeros((pixels, 3))
        self.count = np.zeros(pixels, np.int64)

    def add(self, rows: np.ndarray, values: np.ndarray, per_pixel: int):
        """Add ``per_pixel`` consecutive samples' values (len(rows) * per_pixel, 3) to each
        pixel of rows (R,) int64."""
        v = values.reshape(rows.shape[0], per_pixel, 3)
        self.total[rows] += v.sum(axis=1)
        self.squares[rows] += (v * v).sum(axis=1)
        self.count[rows] += per_pixel


NEIGHBOURS = 2
"""A pixel keeps sampling while a pixel of its row up to this many columns away does
(Cycles filters its convergence the same way, in both directions): a rare bright path (the
light through glass) that a pixel's first samples missed is likely met by one of its
neighbours', so the pixel does not stop dark. Rows only: the camera pass's tiles are whole
rows when it samples adaptively, so the image does not depend on the tiling."""


def unconverged(moments: Moments, pixels: np.ndarray, width: int, threshold: float):
    """(P,) bool: the pixels ``pixels`` (P,) int64 (frame indices y * width + x, increasing,
    whole rows) whose ``relative_error`` is above ``threshold``, or who have such a pixel
    within NEIGHBOURS columns in their row."""
    noisy = relative_error(moments) > threshold
    if noisy.all() or not noisy.any():
        return noisy
    lo = int(pixels[0])
    dense = np.zeros(int(pixels[-1]) - lo + 1, bool)
    dense[pixels - lo] = noisy
    x = pixels % width
    out = noisy.copy()
    for dx in range(-NEIGHBOURS, NEIGHBOURS + 1):
        q = pixels - lo + dx
        ok = (q >= 0) & (q < dense.shape[0]) & (x + dx >= 0) & (x + dx < width)
        out[ok] |= dense[q[ok]]
    return out


def relative_error(moments: Moments) -> np.ndarray:
    """(P,) float64: sqrt(mean over channels of var(mean) / (mean^2 + EPSILON)), the
    variance from the samples (unbiased, n - 1); inf for a pixel of one sample."""
    n = moments.count.astype(np.float64)[:, None]
    mean = moments.total / np.maximum(n, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        var = np.maximum(moments.squares - n * mean * mean, 0.0) / (n - 1.0)
        err = np.mean(var / n / (mean * mean + EPSILON), axis=1)
    return np.where(moments.count > 1, np.sqrt(err), np.inf)
