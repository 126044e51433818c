"""Single scattering of a homogeneous medium under a point light, along camera rays.

    L(o, d) = integral over [0, t_max] of exp(-sigma_t t) sigma_s p(cos) I / r^2
              exp(-sigma_t r) dt,

r the distance from the point at t to the light, cos between the light's propagation
(from the light to the point) and the direction back to the camera (-d), p the
Henyey-Greenstein phase (phase.py), I the light's intensity (W/sr per RGB channel): the
radiance (W/(m^2 sr)) scattered once into the ray. Estimated with equiangular samples
(equiangular.py), stratified along the angle. No occlusion: the camera pass's Volume
Direct term adds the shadow rays through Embree; this kernel is its in-medium part and
the reference its tests use.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..sampling import hash_uniform
from . import equiangular
from .free_flight import transmittance
from .phase import hg_eval


@njit(cache=True, error_model="numpy")
def point_light_inscatter(ox, oy, oz, dx, dy, dz, t_max, px, py, pz, i0, i1, i2, a0, a1, a2,
                          c0, c1, c2, g, samples, seed, index):
    """The single-scattered radiance (L0, L1, L2) of one ray (module docstring) from
    ``samples`` stratified equiangular samples; stream (seed, index)."""
    s0 = a0 + c0
    s1 = a1 + c1
    s2 = a2 + c2
    delta, dist, ta, tb = equiangular.setup(ox, oy, oz, dx, dy, dz, px, py, pz, 0.0, t_max)
    L0 = 0.0
    L1 = 0.0
    L2 = 0.0
    for k in range(samples):
        u = (k + hash_uniform(seed, index, k, 0)) / samples
        t, density = equiangular.sample(delta, dist, ta, tb, u)
        if density <= 0.0:
            continue
        qx = ox + t * dx - px
        qy = oy + t * dy - py
        qz = oz + t * dz - pz
        r2 = qx * qx + qy * qy + qz * qz
        if r2 <= 0.0:
            continue  # the sample is the light itself (a light on the ray): no direction
        r = math.sqrt(r2)
        cos = -(qx * dx + qy * dy + qz * dz) / r
        f = hg_eval(g, cos) / (r2 * density)
        e0, e1, e2 = transmittance(s0, s1, s2, t + r)
        L0 += f * c0 * e0 * i0
        L1 += f * c1 * e1 * i1
        L2 += f * c2 * e2 * i2
    return L0 / samples, L1 / samples, L2 / samples


@njit(cache=True, parallel=True, error_model="numpy")
def inscatter_rays(origins, directions, t_max, light, intensity, sigma_a, sigma_s, g, samples,
                   seed, out):
    """point_light_inscatter for N rays: origins, directions (N, 3), t_max (N,) metres,
    light (3,), intensity (3,) W/sr, sigma_a, sigma_s (3,) 1/m -> out (N, 3) W/(m^2 sr)."""
    for i in prange(origins.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = point_light_inscatter(
            origins[i, 0], origins[i, 1], origins[i, 2], directions[i, 0], directions[i, 1],
            directions[i, 2], t_max[i], light[0], light[1], light[2], intensity[0],
            intensity[1], intensity[2], sigma_a[0], sigma_a[1], sigma_a[2], sigma_s[0],
            sigma_s[1], sigma_s[2], g, samples, seed, i)
