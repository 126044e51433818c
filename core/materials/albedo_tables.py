"""Directional-albedo tables of the microfacet lobes and multiscatter GGX energy compensation.

The tables (``albedo_tables.npz`` beside this file, float64) are Monte Carlo estimates made by
``tools/albedo_tables.py`` with this package's own samplers (microfacet.py), on Cycles' grids
(scene/shader.tables, app/cycles_precompute.cpp) so that they mean the same thing:

- ``ggx_E`` (32 mu, 32 roughness): single-scattering GGX reflection albedo E(mu, r), no
  Fresnel, r = sqrt(alpha) (Blender's Roughness), mu = cos theta_o;
- ``ggx_Eavg`` (32 roughness): 2 int E(mu) mu dmu;
- ``glass_E`` (2, 16 z, 16 mu, 16 roughness) and ``glass_Eavg`` (2, 16 z, 16 roughness): the
  rough dielectric's reflection + transmission albedo with exact Fresnel, [0] for IOR > 1,
  [1] for 1 / IOR, z = sqrt(|(ior - 1) / (ior + 1)|) (F0 = z^4);
- ``schlick_s`` (16 z, 16 mu, 16 roughness): the mean interpolation factor s of the
  "real curve" generalized Schlick (F = mix(F0, 1, s)) over the visible normals;
- ``schlick5_s`` (16 mu, 16 roughness): the same for (1 - cos)^5 (F82's albedo estimate);
- ``sheen`` (3, 32 roughness, 32 mu): Cycles' fitted LTC (a, b, albedo) of the Microfiber
  sheen (copied from Cycles' scene/shader.tables: the fit cannot be re-derived here).

The kernels read them as module constants (``GGX_E`` ... ``SHEEN``, loaded at import):
numba freezes a global array into the compiled code, so they cost no reference counting
per call, where the same arrays carried in ``closure.ClosureTable`` were increfed and
decrefed at every lobe-building call (issue 13: a third of building a hit's lobes). The
numba cache's digest covers this file's data (core/_numba_cache.py).

Every axis is sampled at i / (n - 1) and read with linear interpolation, clamped, as
Cycles' lookup_table_read does.

Energy compensation (Cycles' microfacet_ggx_preserve_energy, after Kulla and Conty 2017):
a lobe of albedo E at wo is scaled by 1 + Fms (1 - E) / E, Fms = Fss E_avg / (1 - Fss (1 -
E_avg)), Fss the lobe's average Fresnel (1 without one): a white rough metal reflects 1.
"""

from __future__ import annotations

import os

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)

PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "albedo_tables.npz")
NAMES = ("ggx_E", "ggx_Eavg", "glass_E", "glass_Eavg", "schlick_s", "schlick5_s", "sheen")


def load(path: str = PATH) -> dict[str, np.ndarray]:
    """The tables as contiguous float64 arrays (shapes in the module docstring). A missing
    file raises FileNotFoundError naming it and the script that makes it."""
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path} is missing: run tools/albedo_tables.py")
    with np.load(path) as z:
        return {k: np.ascontiguousarray(z[k], np.float64) for k in NAMES}


GGX_E, GGX_EAVG, GLASS_E, GLASS_EAVG, SCHLICK_S, SCHLICK5_S, SHEEN = (
    load()[k] for k in NAMES)
"""The tables, frozen into the kernels that read them (module docstring)."""


@njit(cache=True, error_model="numpy")
def _coord(x, n):
    x = min(max(x, 0.0), 1.0) * (n - 1)
    i = min(int(x), n - 1)
    j = min(i + 1, n - 1)
    return i, j, x - i


@njit(cache=True, error_model="numpy")
def read_1d(t, x):
    """Linear interpolation of t (n,) at x in [0, 1]."""
    i, j, f = _coord(x, t.shape[0])
    return (1.0 - f) * t[i] + f * t[j]


@njit(cache=True, error_model="numpy")
def read_2d(t, x, y):
    """Bilinear interpolation of t (ny, nx) at (x, y) in [0, 1]^2 (x the last axis)."""
    i0, i1, fx = _coord(x, t.shape[1])
    j0, j1, fy = _coord(y, t.shape[0])
    a = (1.0 - fx) * t[j0, i0] + fx * t[j0, i1]
    b = (1.0 - fx) * t[j1, i0] + fx * t[j1, i1]
    return (1.0 - fy) * a + fy * b


@njit(cache=True, error_model="numpy")
def read_3d(t, x, y, z):
    """Trilinear interpolation of t (nz, ny, nx) at (x, y, z) in [0, 1]^3."""
    k0, k1, fz = _coord(z, t.shape[0])
    return (1.0 - fz) * read_2d(t[k0], x, y) + fz * read_2d(t[k1], x, y)


@njit(cache=True, error_model="numpy")
def ior_z(eta):
    """The IOR axis of the glass and Schlick tables: z = sqrt(|(eta - 1) / (eta + 1)|), with
    eta >= 1 (pass 1 / eta below 1)."""
    return np.sqrt(abs((eta - 1.0) / (eta + 1.0)))


@njit(cache=True, error_model="numpy")
def reflect_e(ggx_e, ggx_eavg, rough, mu):
    """(E(mu), E_avg) of single-scattering GGX reflection at Roughness ``rough``."""
    return read_2d(ggx_e, rough, mu), read_1d(ggx_eavg, rough)


@njit(cache=True, error_model="numpy")
def glass_e(glass_e_t, glass_eavg_t, rough, mu, eta):
    """(E(mu), E_avg) of the rough dielectric (reflection + transmission) of relative IOR eta."""
    side = 0
    if eta < 1.0:
        eta = 1.0 / eta
        side = 1
    z = ior_z(eta)
    return read_3d(glass_e_t[side], rough, mu, z), read_2d(glass_eavg_t[side], rough, z)


@njit(cache=True, error_model="numpy")
def compensation(e, e_avg, fss):
    """Multiscatter factor 1 + Fms (1 - E) / E of one channel (Fss = 1: 1 / E)."""
    e = max(e, 1e-4)
    missing = (1.0 - e) / e
    den = 1.0 - fss * (1.0 - e_avg)
    fms = fss * e_avg / den if den > 0.0 else 1.0
    return 1.0 + fms * missing
