"""Oren-Nayar diffuse (Diffuse BSDF roughness > 0, Principled's Diffuse Roughness), as Cycles
4.3+ defines it: Fujii's improved Oren-Nayar ("EON", energy-preserving), sigma = roughness
in [0, 1], with the multiple-scattering term that restores the energy the single-scattering
model loses, coloured by the albedo (bsdf_oren_nayar.h). Local frame, wo.z > 0; f in 1/sr
without the cosine, RGB; cosine-weighted sampling (the lobe's own is Lambert's)."""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from . import lambert


@njit(cache=True, error_model="numpy")
def g(cos_t):
    """The directional-albedo integral of Fujii's model: E(mu) = pi A + B g(mu)."""
    if cos_t < 1e-6:
        return (0.5 * np.pi - 2.0 / 3.0) - cos_t
    s = np.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    th = np.arccos(min(cos_t, 1.0))
    return s * (th - 2.0 / 3.0 - s * cos_t) + 2.0 / 3.0 * (s / cos_t) * (1.0 - s * s * s)


@njit(cache=True, error_model="numpy")
def coefficients(sigma):
    """(A, B, E_avg) of roughness sigma in [0, 1]."""
    s = min(max(sigma, 0.0), 1.0)
    a = 1.0 / (np.pi + s * (0.5 * np.pi - 2.0 / 3.0))
    b = s * a
    e_avg = a * np.pi + ((2.0 * np.pi - 5.6) / 3.0) * b
    return a, b, e_avg


@njit(cache=True, error_model="numpy")
def eval(sigma, r0, r1, r2, wox, woy, woz, wix, wiy, wiz):
    """f (RGB, 1/sr) for albedo r (clamped to [0, 1]; it colours the multiple scattering)."""
    if wiz <= 0.0 or woz <= 0.0:
        return 0.0, 0.0, 0.0
    a, b, e_avg = coefficients(sigma)
    t = wox * wix + woy * wiy + woz * wiz - wiz * woz
    if t > 0.0:
        t /= max(wiz, woz) + 1e-38
    single = a + b * t
    el = a * np.pi + b * g(wiz)
    ev = a * np.pi + b * g(woz)
    k = (1.0 - el) * (1.0 - ev) / np.pi * e_avg / (1.0 - e_avg)
    out0 = single + k * _ms(r0, e_avg)
    out1 = single + k * _ms(r1, e_avg)
    out2 = single + k * _ms(r2, e_avg)
    return out0, out1, out2


@njit(cache=True, error_model="numpy")
def _ms(r, e_avg):
    r = min(max(r, 0.0), 1.0)
    return r * r / (1.0 - r * (1.0 - e_avg))


@njit(cache=True, error_model="numpy")
def pdf(wiz):
    """Cosine-weighted, as Lambert."""
    return lambert.pdf(wiz)


@njit(cache=True, error_model="numpy")
def sample(sigma, r0, r1, r2, wox, woy, woz, u1, u2):
    """(wix, wiy, wiz, w0, w1, w2, pdf), w = f cos / pdf = pi f."""
    x, y, z, _, p = lambert.sample(u1, u2)
    f0, f1, f2 = eval(sigma, r0, r1, r2, wox, woy, woz, x, y, z)
    return x, y, z, np.pi * f0, np.pi * f1, np.pi * f2, p
