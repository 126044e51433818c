"""Equiangular sampling of a point on a ray segment towards a point light (Kulla & Fajardo
2012, "Importance sampling techniques for path tracing in participating media").

For the ray o + t d (unit d), t in [t0, t1] metres, and a light at p: delta = (p - o) . d
is where the ray passes closest to the light, D its distance there. The angle seen from
the light, theta = atan((t - delta) / D), is sampled uniformly, which cancels the 1/r^2 of
the light's falloff:

    t = delta + D tan(theta_a + u (theta_b - theta_a)),
    pdf(t) = D / ((theta_b - theta_a) (D^2 + (t - delta)^2))   (1/m).

A light on the ray's line (D = 0) has no such density; D is floored to MIN_DISTANCE, which
keeps the pdf finite (the integrand is not integrable there either).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)

MIN_DISTANCE = 1e-9
"""Floor of the light's distance to the ray's line, metres."""


@njit(cache=True, error_model="numpy")
def setup(ox, oy, oz, dx, dy, dz, px, py, pz, t0, t1):
    """(delta, D, theta_a, theta_b) of a segment [t0, t1] and a light at p."""
    vx = px - ox
    vy = py - oy
    vz = pz - oz
    delta = vx * dx + vy * dy + vz * dz
    cx = vx - delta * dx
    cy = vy - delta * dy
    cz = vz - delta * dz
    dist = max(math.sqrt(cx * cx + cy * cy + cz * cz), MIN_DISTANCE)
    return delta, dist, math.atan2(t0 - delta, dist), math.atan2(t1 - delta, dist)


@njit(cache=True, error_model="numpy")
def sample(delta, dist, theta_a, theta_b, u):
    """(t, pdf) for a uniform u in [0, 1): t metres along the ray, pdf in 1/m."""
    theta = theta_a + u * (theta_b - theta_a)
    t = delta + dist * math.tan(theta)
    return t, pdf(delta, dist, theta_a, theta_b, t)


@njit(cache=True, error_model="numpy")
def pdf(delta, dist, theta_a, theta_b, t):
    """Density (1/m) of sampling t on the segment (zero span: 0)."""
    span = theta_b - theta_a
    if span <= 0.0:
        return 0.0
    h = t - delta
    return dist / (span * (dist * dist + h * h))


@njit(cache=True, error_model="numpy")
def _vec_sample(o, d, p, t0, t1, u, t, density):
    for i in range(u.shape[0]):
        delta, dist, ta, tb = setup(o[0], o[1], o[2], d[0], d[1], d[2], p[0], p[1], p[2],
                                    t0, t1)
        t[i], density[i] = sample(delta, dist, ta, tb, u[i])


@njit(cache=True, error_model="numpy")
def _vec_pdf(o, d, p, t0, t1, t, density):
    for i in range(t.shape[0]):
        delta, dist, ta, tb = setup(o[0], o[1], o[2], d[0], d[1], d[2], p[0], p[1], p[2],
                                    t0, t1)
        density[i] = pdf(delta, dist, ta, tb, t[i])


def sample_segment(origin, direction, light, t0: float, t1: float, u):
    """Equiangular distances (N,) float64 metres and their pdf (N,) 1/m for one ray
    (origin, unit direction (3,)), a light position (3,) and uniforms u (N,)."""
    u = np.ascontiguousarray(np.asarray(u, np.float64).reshape(-1))
    t = np.empty_like(u)
    density = np.empty_like(u)
    _vec_sample(np.asarray(origin, np.float64), np.asarray(direction, np.float64),
                np.asarray(light, np.float64), float(t0), float(t1), u, t, density)
    return t, density


def segment_pdf(origin, direction, light, t0: float, t1: float, t) -> np.ndarray:
    """The pdf (N,) 1/m of equiangular sampling at distances t (N,) metres."""
    t = np.ascontiguousarray(np.asarray(t, np.float64).reshape(-1))
    density = np.empty_like(t)
    _vec_pdf(np.asarray(origin, np.float64), np.asarray(direction, np.float64),
             np.asarray(light, np.float64), float(t0), float(t1), t, density)
    return density
