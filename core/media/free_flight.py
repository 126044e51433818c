"""Homogeneous media: transmittance and free-flight distance sampling, per RGB channel.

Transmittance over a distance d is exp(-sigma_t d) per channel. Free flight is spectral
(pbrt-v4's and Cycles' chromatic media): a channel c is picked uniformly, the distance is
drawn from sigma_c exp(-sigma_c t), and the pdf used for the weights is the mean over the
three channels (one-sample MIS over the channel choice), so a medium whose channels differ
gives bounded weights in every channel.

    collision at t < t_max:  pdf = mean_c sigma_c exp(-sigma_c t),
                             weight = sigma_s * exp(-sigma_t t) / pdf   (scattered flux)
    passing t_max:           P = mean_c exp(-sigma_c t_max),
                             weight = exp(-sigma_t t_max) / P

so E[weight of passing] = exp(-sigma_t t_max) and E[weight at a collision, f(t)] =
integral of sigma_s exp(-sigma_t t) f(t) dt over [0, t_max], per channel: absorption is in
the weight, the walk never terminates inside the medium on its own (Russian roulette on
the throughput does that). Distances in metres, coefficients in 1/m.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)


@njit(cache=True, error_model="numpy")
def transmittance(s0, s1, s2, d):
    """exp(-sigma_t d) per channel for extinction (s0, s1, s2) 1/m over d metres."""
    return math.exp(-s0 * d), math.exp(-s1 * d), math.exp(-s2 * d)


@njit(cache=True, error_model="numpy")
def distance_pdf(s0, s1, s2, t):
    """Density (1/m) of a collision at t: the mean over channels of sigma_c exp(-sigma_c t)."""
    return (s0 * math.exp(-s0 * t) + s1 * math.exp(-s1 * t) + s2 * math.exp(-s2 * t)) / 3.0


@njit(cache=True, error_model="numpy")
def pass_probability(s0, s1, s2, t_max):
    """Probability of flying past t_max: the mean over channels of exp(-sigma_c t_max)."""
    return (math.exp(-s0 * t_max) + math.exp(-s1 * t_max) + math.exp(-s2 * t_max)) / 3.0


@njit(cache=True, error_model="numpy")
def sample_distance(a0, a1, a2, c0, c1, c2, t_max, u_channel, u):
    """One free flight through a homogeneous medium of absorption (a0, a1, a2) and
    scattering (c0, c1, c2), 1/m, along a segment of t_max metres (inf allowed).

    Returns (t, scattered, w0, w1, w2): the collision distance (t_max when the flight
    passes the segment), whether it scatters there, and the throughput weight per channel
    (module docstring). A channel with sigma_t = 0 is never picked by its own flight.
    """
    s0 = a0 + c0
    s1 = a1 + c1
    s2 = a2 + c2
    pick = min(int(u_channel * 3.0), 2)
    sc = s0 if pick == 0 else (s1 if pick == 1 else s2)
    t = -math.log1p(-u) / sc if sc > 0.0 else math.inf
    if t < t_max:
        t0, t1, t2 = transmittance(s0, s1, s2, t)
        pdf = distance_pdf(s0, s1, s2, t)
        return t, True, c0 * t0 / pdf, c1 * t1 / pdf, c2 * t2 / pdf
    if t_max == math.inf:
        # Every channel with sigma_t > 0 would have collided; only empty channels pass.
        return t_max, False, 1.0 if s0 == 0.0 else 0.0, 1.0 if s1 == 0.0 else 0.0, \
            1.0 if s2 == 0.0 else 0.0
    t0, t1, t2 = transmittance(s0, s1, s2, t_max)
    p = pass_probability(s0, s1, s2, t_max)
    return t_max, False, t0 / p, t1 / p, t2 / p


@njit(cache=True, error_model="numpy")
def _vec_sample(sigma_a, sigma_s, t_max, u_channel, u, t, scattered, w):
    for i in range(u.shape[0]):
        t[i], scattered[i], w[i, 0], w[i, 1], w[i, 2] = sample_distance(
            sigma_a[0], sigma_a[1], sigma_a[2], sigma_s[0], sigma_s[1], sigma_s[2],
            t_max[i], u_channel[i], u[i])


def sample_distances(sigma_a, sigma_s, t_max, u_channel, u):
    """sample_distance over arrays for one medium: sigma_a, sigma_s (3,) 1/m; t_max, u_channel,
    u (N,) (t_max may be a scalar). Returns t (N,) float64 metres, scattered (N,) bool,
    weights (N, 3) float64."""
    u = np.ascontiguousarray(np.asarray(u, np.float64).reshape(-1))
    n = u.shape[0]
    tm = np.ascontiguousarray(np.broadcast_to(np.asarray(t_max, np.float64), (n,)))
    t = np.empty(n)
    scattered = np.empty(n, bool)
    w = np.empty((n, 3))
    _vec_sample(np.asarray(sigma_a, np.float64), np.asarray(sigma_s, np.float64), tm,
                np.ascontiguousarray(np.asarray(u_channel, np.float64).reshape(-1)), u, t,
                scattered, w)
    return t, scattered, w
