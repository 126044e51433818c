"""What a render returns: the pass names (the keys of ``RenderOutput.passes``) and their
names in Blender, ``RenderOutput``, and the callbacks every integrator takes.

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
