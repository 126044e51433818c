"""Sheen BSDF ("Microfiber", Cycles 4.x): Zeltner, Burley and Chiang's practical
multiple-scattering sheen, a linearly transformed cosine (LTC) fitted per (cos theta_o,
roughness), as Cycles evaluates it (bsdf_sheen.h). The LTC coefficients (a, b) and the
lobe's directional albedo come from Cycles' fitted table (``albedo_tables``: ``sheen``).

Local frame: z = the normal, x = wo projected on the surface (wo = (sin, 0, cos)); the
caller rotates into it (``frame_of``). f (1/sr, without the cosine) is normalised: its
cosine-weighted integral is 1 and the closure weight carries the albedo, like Cycles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..sampling import concentric_disk


@njit(cache=True, error_model="numpy")
def frame_of(wox, woy):
    """(cos, sin) of the rotation about z that puts wo in the +x half of the xz plane."""
    ln = np.sqrt(wox * wox + woy * woy)
    if ln < 1e-7:
        return 1.0, 0.0
    return wox / ln, woy / ln


@njit(cache=True, error_model="numpy")
def eval(a, b, x, y, z):
    """LTC value / cos (1/sr) for a direction (x, y, z) in the sheen frame."""
    if z <= 0.0:
        return 0.0
    l2 = (a * x + b * z) ** 2 + (a * y) ** 2 + z * z
    return (a / l2) ** 2 / np.pi


@njit(cache=True, error_model="numpy")
def pdf(a, b, x, y, z):
    """The LTC is sampled exactly: pdf = eval * cos."""
    return eval(a, b, x, y, z) * max(z, 0.0)


@njit(cache=True, error_model="numpy")
def sample(a, b, u1, u2):
    """(x, y, z, weight, pdf) in the sheen frame: weight 1 where the direction is above the
    surface (the LTC is normalised), 0 below."""
    dx, dy = concentric_disk(u1, u2)
    dz = np.sqrt(max(0.0, 1.0 - dx * dx - dy * dy))
    x, y, z = dx - dz * b, dy, dz * a
    ln = np.sqrt(x * x + y * y + z * z)
    x, y, z = x / ln, y / ln, z / ln
    if z <= 0.0:
        return x, y, z, 0.0, 0.0
    return x, y, z, 1.0, pdf(a, b, x, y, z)
