"""The Henyey-Greenstein phase function: eval, sample, pdf.

Convention: ``cos_theta`` is the cosine between the propagation direction before and after
scattering (both pointing along the light's travel), so g > 0 scatters forward, as
Cycles' Volume Scatter anisotropy. p(cos) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^(3/2)),
per steradian; it integrates to 1 over the sphere and sampling is exact (pdf = value).
|g| is clamped to MAX_ANISOTROPY (scene/media.py), where the peak is still finite in float64.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..sampling import to_world
from ..scene.media import MAX_ANISOTROPY

_INV_4PI = 1.0 / (4.0 * math.pi)
# Below this |g| the inversion formula loses digits to (1 - g^2) / (2 g): sample the
# isotropic limit instead (the density differs from isotropic by < 3e-4 relative).
_G_ISOTROPIC = 1e-4


@njit(cache=True, error_model="numpy")
def clamp_g(g):
    """g limited to [-MAX_ANISOTROPY, MAX_ANISOTROPY]."""
    return min(max(g, -MAX_ANISOTROPY), MAX_ANISOTROPY)


@njit(cache=True, error_model="numpy")
def hg_eval(g, cos_theta):
    """Phase function value, 1/sr (equal to the sampling pdf)."""
    g = clamp_g(g)
    denom = 1.0 + g * g - 2.0 * g * cos_theta
    return _INV_4PI * (1.0 - g * g) / (denom * math.sqrt(denom))


@njit(cache=True, error_model="numpy")
def hg_sample_cos(g, u):
    """cos_theta distributed as hg_eval(g, .) for u uniform in [0, 1)."""
    g = clamp_g(g)
    if abs(g) < _G_ISOTROPIC:
        c = 1.0 - 2.0 * u
    else:
        k = (1.0 - g * g) / (1.0 - g + 2.0 * g * u)
        c = (1.0 + g * g - k * k) / (2.0 * g)
    return min(max(c, -1.0), 1.0)


@njit(cache=True, error_model="numpy")
def hg_sample(g, dx, dy, dz, u1, u2):
    """A scattered unit direction for the unit propagation direction d and uniforms u1
    (polar), u2 (azimuth) -> (x, y, z, pdf in 1/sr)."""
    c = hg_sample_cos(g, u1)
    s = math.sqrt(max(0.0, 1.0 - c * c))
    phi = 2.0 * math.pi * u2
    x, y, z = to_world(s * math.cos(phi), s * math.sin(phi), c, dx, dy, dz)
    return x, y, z, hg_eval(g, c)


@njit(cache=True, error_model="numpy")
def _vec_eval(g, c, out):
    for i in range(c.shape[0]):
        out[i] = hg_eval(g[i], c[i])


@njit(cache=True, error_model="numpy")
def _vec_sample(g, d, u1, u2, out, pdf):
    for i in range(d.shape[0]):
        out[i, 0], out[i, 1], out[i, 2], pdf[i] = hg_sample(g[i], d[i, 0], d[i, 1], d[i, 2],
                                                            u1[i], u2[i])


def _broadcast(a, n):
    return np.ascontiguousarray(np.broadcast_to(np.asarray(a, np.float64), (n,)))


def phase_values(g, cos_theta) -> np.ndarray:
    """hg_eval over arrays: (N,) float64, 1/sr; g scalar or (N,)."""
    c = np.ascontiguousarray(np.asarray(cos_theta, np.float64).reshape(-1))
    out = np.empty_like(c)
    _vec_eval(_broadcast(g, c.shape[0]), c, out)
    return out


def sample_directions(g, d, u1, u2) -> tuple[np.ndarray, np.ndarray]:
    """hg_sample over arrays: unit directions (N, 3) float64 and their pdf (N,), 1/sr, for
    unit propagation directions d (N, 3) and uniforms u1, u2 (N,)."""
    d = np.ascontiguousarray(d, np.float64).reshape(-1, 3)
    n = d.shape[0]
    out = np.empty_like(d)
    pdf = np.empty(n)
    _vec_sample(_broadcast(g, n), d, _broadcast(u1, n), _broadcast(u2, n), out, pdf)
    return out, pdf
