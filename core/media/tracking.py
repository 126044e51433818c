"""Heterogeneous media: null-collision tracking through a density that varies in space.

The medium's coefficients are a base (sigma_a, sigma_s per RGB channel, 1/m) scaled by a
density rho(x, y, z) >= 0, given as a numba-compiled callback ``density(x, y, z) -> float``
(later: the shader program's texture, or a voxel grid). ``majorant`` bounds rho along the
segment; tentative collisions are drawn from the scalar extinction majorant
sigma_bar = majorant * max_c sigma_t,c, and each is real or null:

- ratio tracking (Novak et al. 2014) estimates the transmittance exp(-tau_c) per channel
  as the product of (1 - sigma_t,c(x) / sigma_bar) over tentative collisions, unbiased;
- spectral delta tracking (Kutz et al. 2017, without absorption events) samples a
  scattering distance: at each tentative collision it scatters with probability
  P_s = S / (S + N), S and N the channel means of sigma_s,c(x) and sigma_bar - sigma_t,c(x),
  and multiplies the weights by sigma_s,c / (sigma_bar P_s) on a scattering and by
  (sigma_bar - sigma_t,c) / (sigma_bar (1 - P_s)) on a null collision, so that per channel
  E[weight, passing] = exp(-tau_c(t_max)) and E[weight f(t), scattering] = integral of
  sigma_s,c(t) exp(-tau_c(t)) f(t) dt, the same contract as free_flight.sample_distance.

Random numbers come from sampling.hash_uniform(seed, index, step, dim): one stream per
(seed, index), one step per tentative collision, so a walk is reproducible and
independent of how many walks run in parallel. A density outside [0, majorant] (the
estimate would be biased and could turn negative) ends the walk with ok = False; the array
functions raise ValueError naming the ray.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..sampling import hash_uniform
from ..sampling import uniform as sampling_uniform

MAX_STEPS = 1 << 20
"""Tentative collisions per walk before giving up (an unreachable bound for a sane
majorant; a walk that hits it reports ok = False instead of looping forever)."""


@njit(cache=True, error_model="numpy")
def ratio_tracking(density, ox, oy, oz, dx, dy, dz, t_max, s0, s1, s2, majorant, seed,
                   index):
    """Transmittance estimate (T0, T1, T2, ok) along o + t d, t in [0, t_max] metres, for
    the extinction (s0, s1, s2) * rho(x), 1/m; majorant >= rho on the segment."""
    bar = majorant * max(s0, max(s1, s2))
    T0 = 1.0
    T1 = 1.0
    T2 = 1.0
    if bar <= 0.0:
        return T0, T1, T2, True
    t = 0.0
    for step in range(MAX_STEPS):
        t -= math.log1p(-hash_uniform(seed, index, step, 0)) / bar
        if t >= t_max:
            return T0, T1, T2, True
        rho = density(ox + t * dx, oy + t * dy, oz + t * dz)
        if not (0.0 <= rho <= majorant):
            return 0.0, 0.0, 0.0, False
        T0 *= 1.0 - rho * s0 / bar
        T1 *= 1.0 - rho * s1 / bar
        T2 *= 1.0 - rho * s2 / bar
    return 0.0, 0.0, 0.0, False


@njit(cache=True, error_model="numpy")
def delta_tracking(density, ox, oy, oz, dx, dy, dz, t_max, a0, a1, a2, c0, c1, c2, majorant,
                   seed, index):
    """One spectral delta-tracking flight through absorption (a0, a1, a2) and scattering
    (c0, c1, c2), 1/m, scaled by rho(x) <= majorant. Returns (t, scattered, w0, w1, w2, ok)
    (module docstring); t = t_max when the flight passes the segment."""
    s0 = a0 + c0
    s1 = a1 + c1
    s2 = a2 + c2
    bar = majorant * max(s0, max(s1, s2))
    w0 = 1.0
    w1 = 1.0
    w2 = 1.0
    if bar <= 0.0:
        return t_max, False, w0, w1, w2, True
    t = 0.0
    for step in range(MAX_STEPS):
        t -= math.log1p(-hash_uniform(seed, index, step, 0)) / bar
        if t >= t_max:
            return t_max, False, w0, w1, w2, True
        rho = density(ox + t * dx, oy + t * dy, oz + t * dz)
        if not (0.0 <= rho <= majorant):
            return t, False, 0.0, 0.0, 0.0, False
        # Collision coefficients here, throughput-weighted as Kutz et al.'s "average" rule.
        sc0 = rho * c0 * w0
        sc1 = rho * c1 * w1
        sc2 = rho * c2 * w2
        n0 = (bar - rho * s0) * w0
        n1 = (bar - rho * s1) * w1
        n2 = (bar - rho * s2) * w2
        scat = sc0 + sc1 + sc2
        null = n0 + n1 + n2
        if scat + null <= 0.0:
            return t, False, 0.0, 0.0, 0.0, True  # absorbed in every channel
        p_s = scat / (scat + null)
        if hash_uniform(seed, index, step, 1) < p_s:
            k = 1.0 / (bar * p_s)
            return t, True, rho * c0 * w0 * k, rho * c1 * w1 * k, rho * c2 * w2 * k, True
        k = 1.0 / (bar * (1.0 - p_s))
        w0 *= (bar - rho * s0) * k
        w1 *= (bar - rho * s1) * k
        w2 *= (bar - rho * s2) * k
    return t, False, 0.0, 0.0, 0.0, False


@njit(cache=True, parallel=True, error_model="numpy")
def _ratio_rays(density, origins, directions, t_max, sigma_t, majorant, seed, out, ok):
    for i in prange(origins.shape[0]):
        out[i, 0], out[i, 1], out[i, 2], ok[i] = ratio_tracking(
            density, origins[i, 0], origins[i, 1], origins[i, 2], directions[i, 0],
            directions[i, 1], directions[i, 2], t_max[i], sigma_t[0], sigma_t[1], sigma_t[2],
            majorant, seed, i)


@njit(cache=True, parallel=True, error_model="numpy")
def _delta_rays(density, origins, directions, t_max, sigma_a, sigma_s, majorant, seed, t_out,
                scattered, w_out, ok):
    for i in prange(origins.shape[0]):
        t_out[i], scattered[i], w_out[i, 0], w_out[i, 1], w_out[i, 2], ok[i] = delta_tracking(
            density, origins[i, 0], origins[i, 1], origins[i, 2], directions[i, 0],
            directions[i, 1], directions[i, 2], t_max[i], sigma_a[0], sigma_a[1], sigma_a[2],
            sigma_s[0], sigma_s[1], sigma_s[2], majorant, seed, i)


def _ray_arrays(origins, directions, t_max, majorant):
    o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
    d = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
    tm = np.ascontiguousarray(np.broadcast_to(np.asarray(t_max, np.float64), (o.shape[0],)))
    if not (np.isfinite(majorant) and majorant >= 0):
        raise ValueError(f"media: majorant must be finite and >= 0, got {majorant}")
    return o, d, tm


def _check_walks(ok, what, majorant):
    if not ok.all():
        i = int(np.flatnonzero(~ok)[0])
        raise ValueError(f"media: {what} of ray {i} met a density outside [0, majorant = "
                         f"{majorant}] (or ran past {MAX_STEPS} tentative collisions)")


def ratio_tracking_rays(density, origins, directions, t_max, sigma_t, majorant: float,
                        seed: int) -> np.ndarray:
    """ratio_tracking for N rays: origins, directions (N, 3), t_max (N,) or scalar metres,
    sigma_t (3,) 1/m -> (N, 3) float64 transmittance estimates; walk i uses stream index i."""
    o, d, tm = _ray_arrays(origins, directions, t_max, majorant)
    out = np.empty((o.shape[0], 3))
    ok = np.empty(o.shape[0], bool)
    _ratio_rays(density, o, d, tm, np.asarray(sigma_t, np.float64), float(majorant), seed,
                out, ok)
    _check_walks(ok, "ratio tracking", majorant)
    return out


def delta_tracking_rays(density, origins, directions, t_max, sigma_a, sigma_s,
                        majorant: float, seed: int):
    """delta_tracking for N rays (arguments as ratio_tracking_rays) -> t (N,) metres,
    scattered (N,) bool, weights (N, 3) float64."""
    o, d, tm = _ray_arrays(origins, directions, t_max, majorant)
    n = o.shape[0]
    t = np.empty(n)
    scattered = np.empty(n, bool)
    w = np.empty((n, 3))
    ok = np.empty(n, bool)
    _delta_rays(density, o, d, tm, np.asarray(sigma_a, np.float64),
                np.asarray(sigma_s, np.float64), float(majorant), seed, t, scattered, w, ok)
    _check_walks(ok, "delta tracking", majorant)
    return t, scattered, w


# --- batched tracking through a density given as a batch function -------------------------
# A shader program's density (core/prepared.py binds core/shading/interpreter.py to a
# medium) is evaluated best over many points at once, so these walk all rays together:
# one Python iteration per tentative-collision *step*, numpy over the rays still walking,
# one density call per step over every active point. Walk i draws its numbers from
# sampling.uniform(seed, index[i], step, dim): reproducible, independent of the batch.

class MajorantExceeded(ValueError):
    """A density above the majorant it was tracked with (the estimate would be biased)."""


def _walk_arrays(origins, directions, t0, t1, index):
    o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
    d = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
    n = o.shape[0]
    a = np.broadcast_to(np.asarray(t0, np.float64), (n,)).copy()
    b = np.broadcast_to(np.asarray(t1, np.float64), (n,)).copy()
    idx = np.arange(n, dtype=np.int64) if index is None else \
        np.ascontiguousarray(np.broadcast_to(np.asarray(index, np.int64), (n,)))
    return o, d, a, b, idx


def _checked_density(density, points, field, majorant, what):
    """rho (K,) or, for a medium whose colour varies, per-channel factors (K, 3) (of the
    extinction) or (K, 6) (absorption's, scattering's): each in [0, majorant] (else
    MajorantExceeded)."""
    rho = np.asarray(density(points, field), np.float64)
    bound = majorant if rho.ndim == 1 else np.asarray(majorant)[:, None]
    bad = ~((rho >= 0.0) & (rho <= bound))
    if bad.ndim == 2:
        bad = bad.any(axis=1)
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        raise MajorantExceeded(
            f"media: {what} met a density {rho[j].tolist()!r} outside [0, majorant = "
            f"{majorant[j]!r}] "
            f"at {points[j].tolist()} (field {int(field[j])}): the majorant underestimates "
            f"the density there")
    return rho


def _per_channel(rho: np.ndarray) -> np.ndarray:
    """rho (K,) as (K, 1), per-channel factors (K, 3) as they are."""
    return rho[:, None] if rho.ndim == 1 else rho


def ratio_tracking_batch(density, origins, directions, t0, t1, field, sigma_t, majorant,
                         seed: int, dim: int, index=None, step0: int = 0) -> np.ndarray:
    """Ratio-tracking transmittance estimates (N, 3) float64 of N segments o + t d, t in
    [t0, t1] metres (t1 finite), through the extinction rho(x) sigma_t (sigma_t (N, 3) 1/m
    per segment). density(points (K, 3) float64, field (K,) int64) -> (K,) float64 is rho,
    field (N,) int64 which density each segment reads, majorant (N,) >= rho on the segment.
    Unbiased: E = exp(-integral of rho sigma_t) per channel. Raises MajorantExceeded for a
    density outside [0, majorant] (module doc). A medium whose colour varies (Principled
    Volume Color / Absorption Color fed by nodes) has a per-channel extinction: density
    then returns (K, 3) factors r_c(x) with sigma_t,c(x) = r_c(x) sigma_t,c, each in
    [0, majorant] (the majorant stays one scalar on the extinction: the tentative
    collisions are drawn from majorant x max_c sigma_t,c as for a scalar rho)."""
    o, d, t, b, idx = _walk_arrays(origins, directions, t0, t1, index)
    st = np.ascontiguousarray(np.broadcast_to(np.asarray(sigma_t, np.float64), o.shape))
    maj = np.broadcast_to(np.asarray(majorant, np.float64), t.shape)
    fld = np.broadcast_to(np.asarray(field, np.int64), t.shape)
    bar = maj * st.max(axis=1)
    T = np.ones((o.shape[0], 3))
    active = np.flatnonzero((bar > 0.0) & (b > t))
    step = 0
    while active.size:
        if step >= MAX_STEPS:
            raise ValueError(f"media: ratio tracking ran past {MAX_STEPS} tentative collisions")
        u = sampling_uniform(seed, idx[active], np.full(active.size, step0 + step), dim)
        t[active] -= np.log1p(-u) / bar[active]
        active = active[t[active] < b[active]]
        if not active.size:
            break
        p = o[active] + t[active, None] * d[active]
        rho = _checked_density(density, p, fld[active], maj[active], "ratio tracking")
        T[active] *= 1.0 - _per_channel(rho) * st[active] / bar[active, None]
        step += 1
    return T


def delta_tracking_batch(density, origins, directions, t0, t1, field, base_a, base_s, rho_a,
                         rho_s, majorant, seed: int, dim: int, index=None, step0: int = 0):
    """Spectral delta tracking (``delta_tracking``'s weights) of N flights o + t d from t0
    to t1 metres (inf allowed where base_a + base_s > 0 in some channel) through the
    absorption base_a + rho(x) rho_a and scattering base_s + rho(x) rho_s ((N, 3) 1/m
    each: a homogeneous part plus the density's), rho as ``ratio_tracking_batch``.
    Returns t (N,) metres (t1 where the flight passes), scattered (N,) bool, weights (N, 3)
    float64: E[w, passing] = T(t1), E[w f(t), scattering] = integral of sigma_s T f.
    A medium whose colour varies: density returns (K, 6) factors, the absorption's per
    channel then the scattering's (sigma_a,c = base_a,c + f_c rho_a,c, sigma_s,c = base_s,c
    + f_{3+c} rho_s,c), each in [0, majorant]."""
    o, d, t, b, idx = _walk_arrays(origins, directions, t0, t1, index)
    n = o.shape[0]

    def full(a):
        return np.ascontiguousarray(np.broadcast_to(np.asarray(a, np.float64), (n, 3)))
    ba, bs, ra, rs = full(base_a), full(base_s), full(rho_a), full(rho_s)
    maj = np.broadcast_to(np.asarray(majorant, np.float64), (n,))
    fld = np.broadcast_to(np.asarray(field, np.int64), (n,))
    bar = (ba + bs + maj[:, None] * (ra + rs)).max(axis=1)
    w = np.ones((n, 3))
    scattered = np.zeros(n, bool)
    active = np.flatnonzero((bar > 0.0) & (b > t))
    t[bar <= 0.0] = b[bar <= 0.0]
    step = 0
    while active.size:
        if step >= MAX_STEPS:
            raise ValueError(f"media: delta tracking ran past {MAX_STEPS} tentative collisions")
        s = np.full(active.size, step0 + step)
        u = sampling_uniform(seed, idx[active], s, dim)
        t[active] -= np.log1p(-u) / bar[active]
        out = t[active] >= b[active]
        t[active[out]] = b[active[out]]
        active = active[~out]
        if not active.size:
            break
        p = o[active] + t[active, None] * d[active]
        rho = _checked_density(density, p, fld[active], maj[active], "delta tracking")
        if rho.ndim == 1:
            rho_a = rho_sc = rho[:, None]
        else:  # a varying colour: (K, 6) per-channel factors of rho_a, then of rho_s
            rho_a, rho_sc = rho[:, :3], rho[:, 3:]
        sig_s = bs[active] + rho_sc * rs[active]
        sig_t = ba[active] + rho_a * ra[active] + sig_s
        wa = w[active]
        bb = bar[active, None]
        # Kutz et al.'s throughput-weighted channel means decide scattering vs null
        scat = (sig_s * wa).sum(axis=1)
        null = ((bb - sig_t) * wa).sum(axis=1)
        dead = scat + null <= 0.0
        p_s = np.where(dead, 0.0, scat / np.where(dead, 1.0, scat + null))
        hit = sampling_uniform(seed, idx[active], s, dim + 1) < p_s
        hit_rows = active[hit]
        w[hit_rows] = wa[hit] * sig_s[hit] / (bb[hit] * p_s[hit, None])
        scattered[hit_rows] = True
        go = ~hit & ~dead
        w[active[go]] = wa[go] * (bb[go] - sig_t[go]) / (bb[go] * (1.0 - p_s[go, None]))
        w[active[dead]] = 0.0
        active = active[go]
        step += 1
    return t, scattered, w


def ratio_tracking_points(density, origins, directions, t0, t1, field, sigma_t, majorant,
                          seed: int, dim: int, index=None):
    """``ratio_tracking_batch`` that also returns its tentative collisions: (walk (P,)
    int64, t (P,) metres, T (P, 3) the running transmittance estimate just after each),
    sorted by walk then t. Between consecutive tentative collisions the running product is
    an unbiased estimate of exp(-tau(t)) at every t there (it only changes at them), which
    is how a camera segment integrates terms along a heterogeneous stretch
    (core/integrators/volume.py)."""
    o, d, t, b, idx = _walk_arrays(origins, directions, t0, t1, index)
    st = np.ascontiguousarray(np.broadcast_to(np.asarray(sigma_t, np.float64), o.shape))
    maj = np.broadcast_to(np.asarray(majorant, np.float64), t.shape)
    fld = np.broadcast_to(np.asarray(field, np.int64), t.shape)
    bar = maj * st.max(axis=1)
    T = np.ones((o.shape[0], 3))
    walks, ts, Ts = [], [], []
    active = np.flatnonzero((bar > 0.0) & (b > t))
    step = 0
    while active.size:
        if step >= MAX_STEPS:
            raise ValueError(f"media: ratio tracking ran past {MAX_STEPS} tentative collisions")
        u = sampling_uniform(seed, idx[active], np.full(active.size, step), dim)
        t[active] -= np.log1p(-u) / bar[active]
        active = active[t[active] < b[active]]
        if not active.size:
            break
        p = o[active] + t[active, None] * d[active]
        rho = _checked_density(density, p, fld[active], maj[active], "ratio tracking")
        T[active] *= 1.0 - _per_channel(rho) * st[active] / bar[active, None]
        walks.append(active.copy())
        ts.append(t[active].copy())
        Ts.append(T[active].copy())
        step += 1
    if not walks:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 3)), T
    w, tt, TT = np.concatenate(walks), np.concatenate(ts), np.concatenate(Ts)
    order = np.lexsort((tt, w))
    return w[order], tt[order], TT[order], T
