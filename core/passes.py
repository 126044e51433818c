"""What a render returns: the pass names (the keys of ``RenderOutput.passes``) and their
names in Blender, ``RenderOutput``, the callbacks every integrator takes, and
``consecutive_mean``, the per-pixel (per-sample) mean of rows of samples (gather rays).

PASSES lists the terms summed into "combined", in summation order (the seed lecture's
split: emission, environment, direct, specular, caustics, indirect diffuse); LIGHT_PASSES
adds the participating media's Volume Direct and Volume Indirect (VOLUME_PASSES), produced
only for a scene with a medium (core/integrators/volume.py).
BLENDER_PASS_NAMES maps our keys to the pass names Blender 5 uses in its render results and
EXR files ("Emission" and "Environment" are Blender's own passes; the others are
registered by the engine).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from numba import njit, prange

from . import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)


PASSES = ("emission", "environment", "direct", "specular", "caustics", "indirect")
"""The light passes of every render."""
VOLUME_PASSES = ("volume_direct", "volume_indirect")
"""The passes of the media terms: only a render of a scene with a medium produces them."""
LIGHT_PASSES = PASSES + VOLUME_PASSES
"""Every light pass, in summation order (the ``pass_*`` settings)."""

BLENDER_PASS_NAMES = {
    "combined": "Combined",
    "emission": "Emission",
    "environment": "Environment",
    "direct": "Direct",
    "specular": "Specular",
    "caustics": "Caustics",
    "indirect": "Indirect",
    "volume_direct": "Volume Direct",
    "volume_indirect": "Volume Indirect",
}

ProgressFn = Callable[[float, str], None]
"""on_progress(fraction in [0, 1], message): the render's progress, for a bar and a status line."""
TileFn = Callable[[int, dict], None]
"""on_tile(done, passes): the image so far, while a long render fills in (``done``: pixels
for the photon-mapping integrator, passes for the progressive one)."""
StopFn = Callable[[], bool]
"""should_stop() -> True to stop: the render ends between two batches, keeping what it has."""


@dataclass
class UsedPhotonMaps:
    """The photon maps the camera pass read: core.photons.PhotonMap or None (term skipped
    or not built)."""

    global_map: object = None
    caustic_map: object = None


@dataclass
class RenderOutput:
    """passes: name -> (H, W, 3) float32 ("photons": (H, W, 4)); stats: counters and
    timings; cancelled: stopped early; photon_maps: the UsedPhotonMaps of the render, None
    when it used no photon map (the viewport display shows them, photon_engine/overlay.py)."""

    passes: dict[str, np.ndarray]
    stats: dict = field(default_factory=dict)
    cancelled: bool = False
    photon_maps: UsedPhotonMaps | None = None


@njit(cache=True, parallel=True, error_model="numpy")
def _consecutive_mean_kernel(values, count, out):
    for p in prange(out.shape[0]):
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        base = p * count
        for s in range(count):
            a0 += values[base + s, 0]
            a1 += values[base + s, 1]
            a2 += values[base + s, 2]
        out[p, 0] = a0 / count
        out[p, 1] = a1 / count
        out[p, 2] = a2 / count


def consecutive_mean(values: np.ndarray, count: int) -> np.ndarray:
    """(N, 3) float64 mean of each run of ``count`` consecutive rows of ``values``
    (N * count, 3) float64, summed in row order: a pixel's samples, a camera sample's
    gather rays. Deterministic, and equal bit for bit to numpy's
    ``values.reshape(N, count, 3).mean(axis=1)`` (also summed in order), on all threads."""
    out = np.empty((values.shape[0] // count, 3))
    _consecutive_mean_kernel(values, count, out)
    return out
