"""Photons through the scene's media (core/media/regions.py): one free flight per photon
and bounce, before its surface hit is shaded (core/photons/tracing.py).

Per photon of a wavefront with its surface hit at t_hit (inf: it escapes), over the
homogeneous stretches of [0, t_hit] in order (``Medium.stretches``):
- a spectral free flight (``free_flight.sample_distance``) over each stretch: passing it,
  the flux takes its passing weight and the flight goes on in the next stretch (random
  numbers keyed by the stretch too); passing them all, the
  flux takes the passing weight T / P(pass) and the surface hit is shaded as without a
  medium; colliding at t < t_hit, the flux takes the collision weight sigma_s T / pdf
  (absorption stays in the weight) and the photon scatters there by Henyey-Greenstein
  (sampled exactly, so the phase adds no weight), counted as a diffuse-like bounce in
  ``n_diff`` (a later surface photon is indirect light, not a caustic), after Russian
  roulette on the weight (survive with p = min(1, max w), flux / p);
- where it collides, a volume photon is stored for the final-gather rays (every collision
  of the global emission within their bounce limit, photon_max_bounces - 1:
  core/photons/tracing.py, "Bounces") and, for the camera rays, by the rules below (its scattered flux, position and
  propagation direction), by the rules of the maps (core/photons/store.py's surface
  rules carried to media):
  - global emission (MODE_GLOBAL): after at least one diffuse or volume bounce; straight
    from the source only with ``store_direct`` (sources whose single scattering the camera
    pass does not take by shadow rays: emissive triangles, the world); after specular
    bounces only (light -> S+ -> V) only when the caustic volume map is not built
    (``caustic_apart`` False);
  - caustic emission (MODE_CAUSTIC): light -> S+ -> V only, and the photon ends there (its
    further light is the global emission's).
Units: metres, flux in watts, coefficients in 1/m.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from ..media.free_flight import sample_distance
from ..media.tracking import delta_tracking_batch
from ..media.phase import hg_sample
from .store import MODE_CAUSTIC

STRETCH_STEP = 1 << 20
"""The random step counter of a flight's k-th stretch is bounce + k STRETCH_STEP (bounces
stay far below it)."""


@njit(cache=True, parallel=True, error_model="numpy")
def fly_kernel(o, d, flux, pid, n_diff, n_spec, start, t0, t1, sigma_a, sigma_s, g, seed, dims,
               bounce, mode, caustic_apart, store_direct, last, pre, pre_t, pre_s, pre_w,
               near, collided, v_store, v_camera, v_pos, v_flux, v_dir, alive, o_new, d_new, f_new):
    """One free flight per photon (module doc).

    Inputs: o, d (N, 3) float32 origins and unit directions of travel; flux (N, 3)
    float64 W (updated in place for photons that pass: times the passing weight); pid (N,)
    int64 random counters; n_diff, n_spec (N,) int32 bounces so far (n_diff += 1 where a
    photon scatters in the medium); the homogeneous stretches of each photon's flight to
    its surface hit (regions.Stretches): start (N + 1,) int64, t0, t1 (S,) float64 metres,
    sigma_a, sigma_s (S, 3) 1/m, g (S,) the anisotropy; dims (4,) int64 random dimensions;
    bounce the wavefront's index; mode MODE_GLOBAL / MODE_CAUSTIC. Heterogeneous stretches
    come tracked already (``pre`` (S,) bool; their delta-tracking flight: pre_t (S,)
    metres from t0, pre_s (S,) bool scattered, pre_w (S, 3) weights; ``flight_through``).
    near: (N,) float64 metres, or (0,): a soft-falloff light's photons at their first
    flight (core/photons/emission.py, "Soft falloff"), whose collision closer than near[i]
    carries nothing (collided, neither stored nor going on).
    Outputs: collided (N,) bool; v_store (N,) bool, a volume photon is stored, v_camera
    (N,) bool, it belongs to the camera rays' map (the rules of the module doc; the
    global emission's map for final-gather rays takes every collision, as the global
    surface map of final gathering holds direct photons), with v_pos (N, 3) float32 metres,
    v_flux (N, 3) float32 W, v_dir (N, 3) float32 unit propagation direction; alive (N,)
    bool, a collided photon goes on from o_new along d_new (float32) with f_new (float64).
    Every output row is written: those of a photon not stored (v_pos, v_flux, v_dir) or
    not going on (o_new, d_new, f_new) are zeros, so callers may weigh or copy whole rows.
    """
    for i in prange(o.shape[0]):
        collided[i] = False
        v_store[i] = False
        v_camera[i] = mode == MODE_CAUSTIC
        alive[i] = False
        for c in range(3):
            v_pos[i, c] = 0.0
            v_flux[i, c] = 0.0
            v_dir[i, c] = 0.0
            o_new[i, c] = 0.0
            d_new[i, c] = 0.0
            f_new[i, c] = 0.0
        scattered = False
        t, w0, w1, w2, gs = 0.0, 1.0, 1.0, 1.0, 0.0
        for k in range(start[i], start[i + 1]):
            # The first stretch keeps the step counter of a flight in one medium.
            if pre[k]:
                ts, scattered, v0, v1, v2 = pre_t[k], pre_s[k], pre_w[k, 0], pre_w[k, 1], \
                    pre_w[k, 2]
            else:
                step = bounce + (k - start[i]) * STRETCH_STEP
                u_c = sampling.hash_uniform(seed, pid[i], step, dims[0])
                u_t = sampling.hash_uniform(seed, pid[i], step, dims[1])
                ts, scattered, v0, v1, v2 = sample_distance(
                    sigma_a[k, 0], sigma_a[k, 1], sigma_a[k, 2], sigma_s[k, 0], sigma_s[k, 1],
                    sigma_s[k, 2], t1[k] - t0[k], u_c, u_t)
            w0 *= v0
            w1 *= v1
            w2 *= v2
            if scattered:
                t = t0[k] + ts
                gs = g[k]
                break
        if not scattered:
            flux[i, 0] *= w0
            flux[i, 1] *= w1
            flux[i, 2] *= w2
            continue
        collided[i] = True
        if near.shape[0] and t < near[i]:
            continue
        dx, dy, dz = np.float64(d[i, 0]), np.float64(d[i, 1]), np.float64(d[i, 2])
        px = np.float64(o[i, 0]) + t * dx
        py = np.float64(o[i, 1]) + t * dy
        pz = np.float64(o[i, 2]) + t * dz
        f0, f1, f2 = flux[i, 0] * w0, flux[i, 1] * w1, flux[i, 2] * w2
        if not (f0 > 0.0 or f1 > 0.0 or f2 > 0.0):
            continue  # absorbed (a medium that does not scatter in this photon's light)
        nd, ns = n_diff[i], n_spec[i]
        caustic_path = nd == 0 and ns > 0
        if mode == MODE_CAUSTIC:
            keep = caustic_path
        else:
            keep = True  # the final-gather rays' map holds every collision
            v_camera[i] = nd > 0 or (nd == 0 and ns == 0 and store_direct) or (
                caustic_path and not caustic_apart)
        if keep:
            v_store[i] = True
            v_pos[i, 0], v_pos[i, 1], v_pos[i, 2] = px, py, pz
            v_flux[i, 0], v_flux[i, 1], v_flux[i, 2] = f0, f1, f2
            v_dir[i, 0], v_dir[i, 1], v_dir[i, 2] = dx, dy, dz
        if last or mode == MODE_CAUSTIC:
            continue
        p = min(1.0, max(w0, max(w1, w2)))
        if not sampling.hash_uniform(seed, pid[i], bounce, dims[2]) < p:
            continue
        u1 = sampling.hash_uniform(seed, pid[i], bounce, dims[3])
        u2 = sampling.hash_uniform(seed, pid[i], bounce, dims[3] + 1)
        nx, ny, nz, _ = hg_sample(gs, dx, dy, dz, u1, u2)
        n_diff[i] = nd + 1
        o_new[i, 0], o_new[i, 1], o_new[i, 2] = px, py, pz
        d_new[i, 0], d_new[i, 1], d_new[i, 2] = nx, ny, nz
        f_new[i, 0], f_new[i, 1], f_new[i, 2] = f0 / p, f1 / p, f2 / p
        alive[i] = True


def flight_through(medium, st, o, d, pid, seed: int, map_id: int, bounce: int):
    """The delta-tracking flights (core/media/tracking.py ``delta_tracking_batch``) of
    the heterogeneous stretches of ``st`` (regions.Stretches of photons o, d (N, 3) with
    counters pid (N,)): ``fly_kernel``'s pre, pre_t, pre_s, pre_w. Every heterogeneous
    stretch is tracked, also those behind an earlier collision (fly_kernel ignores them):
    one batch per wavefront, the density program evaluated over all active points per
    step. Random numbers: (seed, pid, tentative step, stream(MEDIUM_TRACKING, map, bounce,
    stretch k of the flight))."""
    s = st.t0.shape[0]
    pre = np.zeros(s, bool)
    pre_t = np.zeros(s)
    pre_s = np.zeros(s, bool)
    pre_w = np.ones((s, 3))
    if st.field is None:
        return pre, pre_t, pre_s, pre_w
    het = np.flatnonzero(st.field >= 0)
    if het.size == 0:
        return pre, pre_t, pre_s, pre_w
    ray = st.ray[het]
    kth = het - st.start[ray]
    for k in np.unique(kth):
        sel = het[kth == k]
        r = st.ray[sel]
        dim = sampling.stream(sampling.MEDIUM_TRACKING, map_id, min(bounce, 4095), int(k) % 4096)
        oo = np.asarray(o, np.float64)[r] + st.t0[sel, None] * np.asarray(d, np.float64)[r]
        t, sc, w = delta_tracking_batch(medium.fields.along(st.field[sel], st.majorant[sel]),
                                        oo, np.asarray(d, np.float64)[r], 0.0,
                                        st.t1[sel] - st.t0[sel], np.arange(sel.size),
                                        st.sigma_a[sel],
                                        st.sigma_s[sel], st.het_a[sel], st.het_s[sel],
                                        st.majorant[sel], seed, dim, index=pid[r])
        pre[sel], pre_t[sel], pre_s[sel], pre_w[sel] = True, t, sc, w
    return pre, pre_t, pre_s, pre_w


class VolumeStore:
    """Stored volume photons, appended per bounce: positions, flux (W), propagation
    directions, (n, 3) float32 each, whether the camera rays' map holds them (n,) bool,
    and whether the final-gather rays' map does (one flag per bounce: its photons are
    within the gather rays' bounce limit, core/photons/tracing.py), in emission order."""

    def __init__(self):
        self.pos, self.flux, self.dir, self.camera, self.gathered = [], [], [], [], []

    def add(self, flag, camera, pos, flux, direction, gathered=True):
        idx = np.flatnonzero(flag)
        if idx.size:
            self.pos.append(pos[idx])
            self.flux.append(flux[idx])
            self.dir.append(direction[idx])
            self.camera.append(camera[idx])
            self.gathered.append((idx.size, bool(gathered)))

    def take(self):
        """(positions, flux, directions (M, 3) float32, camera (M,) bool, gathered (M,)
        bool); the store is emptied."""
        out = tuple(np.concatenate(parts) if parts else np.zeros((0, 3), np.float32)
                    for parts in (self.pos, self.flux, self.dir))
        camera = np.concatenate(self.camera) if self.camera else np.zeros(0, bool)
        gathered = np.repeat([g for _, g in self.gathered],
                             [n for n, _ in self.gathered]).astype(bool)
        self.pos, self.flux, self.dir, self.camera, self.gathered = [], [], [], [], []
        return (*out, camera, gathered)
