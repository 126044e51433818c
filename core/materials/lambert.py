"""Lambert (Diffuse BSDF at roughness 0) and Translucent (Lambert on the far side) lobes, in
the local shading frame (z = the shading normal, wo.z > 0). f in 1/sr, without the cosine;
``sample`` returns (wix, wiy, wiz, weight = f cos / pdf, pdf), cosine-weighted."""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..sampling import cosine_hemisphere

INV_PI = 1.0 / np.pi


@njit(cache=True, error_model="numpy")
def eval(wiz):
    """Lambert: 1 / pi above the surface."""
    return INV_PI if wiz > 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def pdf(wiz):
    """Cosine-weighted pdf of ``sample``."""
    return wiz * INV_PI if wiz > 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def sample(u1, u2):
    """Cosine-weighted direction: weight 1 (f cos / pdf)."""
    x, y, z = cosine_hemisphere(u1, u2)
    return x, y, z, 1.0, z * INV_PI


@njit(cache=True, error_model="numpy")
def translucent_eval(wiz):
    """Translucent: 1 / pi below the surface (the far side)."""
    return INV_PI if wiz < 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def translucent_pdf(wiz):
    """Cosine-weighted pdf about -z."""
    return -wiz * INV_PI if wiz < 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def translucent_sample(u1, u2):
    """Cosine-weighted direction on the far side: weight 1."""
    x, y, z = cosine_hemisphere(u1, u2)
    return x, y, -z, 1.0, z * INV_PI
