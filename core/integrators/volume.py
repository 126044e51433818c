"""The camera pass's volume terms: what a camera segment through the scene's media
(core/media/regions.py: the World's and those inside closed meshes) adds, and how it
attenuates what lies behind it.

A segment from o along the unit d to t_hit (inf for a ray that escapes) is cut into its
homogeneous stretches (``Medium.stretches``: where it crosses a medium's boundary); each
stretch adds the terms below, weighted by the transmittance from o to its start:
- transmittance exp(-sigma_t t_hit) multiplies everything behind (the surface hit, the
  world background: 0 through fog on an escaping ray, as in Cycles, whose homogeneous World
  volume extinguishes the background and the sun);
- Volume Direct: single scattering of the lights, estimated per light and light sample by
  one equiangular distance towards the light's position, on the part of the stretch a
  spot's cone can light (``lights.kernels.spot_lit_interval``) (Kulla & Fajardo 2012;
  core/media/equiangular.py; area lights too, the pdf covers the whole segment) and a
  light sample from the scattering point (``lights.kernels.sample_light``) with its shadow
  ray: sigma_s p(cos) exp(-sigma_t t) T_shadow L / (pdf_t pdf_light), T_shadow the
  transmittance of the shadow segment through every medium it crosses. Sun lights add
  nothing in World fog (their light crosses infinite medium) but light a mesh medium;
  emissive triangles' single scattering comes from the volume photon map
  (core/photons/tracing.py stores their first collisions);
- Volume Indirect: the beam radiance estimate (core/photons/beam.py, Jarosz et al. 2008)
  of the volume photon map and of the volumetric caustic map along the segment, corrected
  where the segment meets a plane the scattering ends at (a medium's boundary with none
  beyond, the opaque surface the segment ends on: ``surface_bounds``);
- the medium's own emission, integral of exp(-sigma_t s) emission ds, to the Emission pass.
Radiance in W/(m^2 sr), segment lengths in metres.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from ..lights import kernels as light_kernels
from ..media import equiangular, regions, tracking
from ..media.phase import hg_eval
from ..photons.beam import VolumePhotonMap
from ..prepared import PreparedScene
from ..scene import geometry
from ..settings import RenderSettings

SEGMENT_FAR = 1e30
"""Length (metres) an escaping segment is given in the kernels (equiangular sampling and
the beam query take a finite end; the transmittance there is 0 in any fog)."""


@dataclass
class VolumeTerms:
    """What the volume terms of a render read (``prepare``)."""

    medium: regions.Medium
    prepared: PreparedScene
    seed: int
    light_samples: int
    """Single-scattering samples per light and camera sample (settings.volume_light_samples)."""
    sample_bits: int
    volume_map: VolumePhotonMap | None = None
    caustic_map: VolumePhotonMap | None = None
    single_scattering: bool = True
    """Volume Direct by shadow rays (False: the volume maps hold the lights' first
    collisions too, as standard SPPM's photon direct light, core/integrators/sppm.py)."""


AUTO_SAMPLES_HOMOGENEOUS = 16
"""Automatic volume light samples where every medium is homogeneous: measured best per
second on World fog and a fog cube (Volume Direct's noise 3-7x lower at 0-7 % more time,
docs/volumes.md "Volume light samples")."""
AUTO_SAMPLES_VARYING = 4
"""Automatic volume light samples where a density varies: each shadow ray is tracked
through the density, so 16 samples tripled the camera pass of a Noise-density cube for
1.3x less noise; 4 were level with 1 per second there."""


def volume_light_samples(settings: RenderSettings, medium: regions.Medium) -> int:
    """Single-scattering samples per light and camera sample: settings.volume_light_samples,
    or for 0 (automatic) AUTO_SAMPLES_HOMOGENEOUS / AUTO_SAMPLES_VARYING by whether any of
    the scene's media has a varying density."""
    k = int(settings.volume_light_samples)
    if k:
        return k
    return AUTO_SAMPLES_VARYING if medium.heterogeneous else AUTO_SAMPLES_HOMOGENEOUS


def prepare(settings: RenderSettings, prepared: PreparedScene, samples: int) -> VolumeTerms | None:
    """The volume terms of a render, or None when the scene has no medium to integrate
    (then every image is exactly as without media). Raises SceneError for a medium the
    renderer does not integrate yet (core/media/regions.py)."""
    medium = prepared.medium
    if medium is None:
        return None
    k = volume_light_samples(settings, medium)
    return VolumeTerms(medium=medium, prepared=prepared, seed=int(settings.seed),
                       light_samples=k, sample_bits=sampling.index_bits(int(samples) * k))


@njit(cache=True, parallel=True, error_model="numpy")
def _inscatter_kernel(q, origins, dirs, seg_t, thr, sigma_s, sigma_t, g, pixel, sample, seed,
                      dim_t, dim_l, k, k_count, bits, extent, far_ok, contrib, sh_o, sh_d,
                      sh_t, need):
    """One equiangular distance and one light sample per homogeneous stretch (sigma_s,
    sigma_t (N, 3), g (N,)): the single scattering thr sigma_s p T(t) L / (pdf_t pdf_light)
    / k_count (contrib (N, 3)) without the shadow segment's transmittance, and the shadow
    ray from the scattering point to the light (need[i]; 3e38 m towards a light at
    infinity, taken only where ``far_ok``: no World medium extinguishes every channel)."""
    px, py, pz = q[light_kernels.P_POS], q[light_kernels.P_POS + 1], q[light_kernels.P_POS + 2]
    scale = 1.0 / k_count
    for i in prange(origins.shape[0]):
        need[i] = False
        contrib[i, 0] = 0.0
        contrib[i, 1] = 0.0
        contrib[i, 2] = 0.0
        ox, oy, oz = origins[i, 0], origins[i, 1], origins[i, 2]
        dx, dy, dz = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        t_end = min(seg_t[i], SEGMENT_FAR)
        # Stratified over the pixel's samples x light samples, like the light sample.
        u_t, _ = sampling.sobol2(sample[i] * k_count + k, bits, sampling.pattern(seed, pixel[i], dim_t))
        # A spot lights only the part of the segment inside its cone: the distances are
        # drawn there (an integrand 0 elsewhere: unbiased, and beside a spot's apex most
        # of the equiangular samples used to fall outside it)
        lo, hi, lit = light_kernels.spot_lit_interval(q, ox, oy, oz, dx, dy, dz, 0.0, t_end)
        if not lit:
            continue
        delta, dist, ta, tb = equiangular.setup(ox, oy, oz, dx, dy, dz, px, py, pz, lo, hi)
        t, pdf_t = equiangular.sample(delta, dist, ta, tb, u_t)
        if not (pdf_t > 0.0) or t <= 0.0 or t >= t_end:
            continue
        xx, xy, xz = ox + t * dx, oy + t * dy, oz + t * dz
        u1, u2 = sampling.sobol2(sample[i] * k_count + k, bits,
                                 sampling.pattern(seed, pixel[i], dim_l))
        wx, wy, wz, r, l0, l1, l2, cl, ok = light_kernels.sample_light(q, xx, xy, xz, u1, u2)
        if not ok or not (r < SEGMENT_FAR or far_ok):
            continue
        # cos between the light's propagation (-w) and the scattered one towards the camera (-d)
        ph = hg_eval(g[i], wx * dx + wy * dy + wz * dz)
        f = ph * scale / pdf_t
        c0 = thr[i, 0] * sigma_s[i, 0] * np.exp(-sigma_t[i, 0] * t) * l0 * f
        c1 = thr[i, 1] * sigma_s[i, 1] * np.exp(-sigma_t[i, 1] * t) * l1 * f
        c2 = thr[i, 2] * sigma_s[i, 2] * np.exp(-sigma_t[i, 2] * t) * l2 * f
        if c0 <= 0.0 and c1 <= 0.0 and c2 <= 0.0:
            continue
        if r < SEGMENT_FAR:
            qx, qy, qz = xx + wx * r, xy + wy * r, xz + wz * r
            tf = r - geometry.offset_eps(qx, qy, qz, extent) / max(cl, 1e-3)
        else:
            tf = 3e38
        if tf <= 0.0:
            continue
        contrib[i, 0] = c0
        contrib[i, 1] = c1
        contrib[i, 2] = c2
        sh_o[i, 0] = xx
        sh_o[i, 1] = xy
        sh_o[i, 2] = xz
        sh_d[i, 0] = wx
        sh_d[i, 1] = wy
        sh_d[i, 2] = wz
        sh_t[i] = tf
        need[i] = True


def _single_scattering(vt: VolumeTerms, origins, dirs, seg_t, thr, sigma_s, sigma_t, g, pixel,
                       sample, depth, stats, sigma_s_at=None) -> np.ndarray:
    """Volume Direct of N homogeneous stretches (coefficients sigma_s, sigma_t (N, 3), g
    (N,)), (N, 3) float64 W/(m^2 sr), shadow rays and their transmittance included.
    sigma_s_at(idx (K,), points (K, 3) float64) -> (K, 3): a varying sigma_s at the
    scattering points of stretches idx, multiplied into the contributions (None: none)."""
    pr = vt.prepared
    ls = pr.light_set
    m = vt.medium
    far_ok = not bool(np.all(m.world_sigma_t > 0))
    n = origins.shape[0]
    out = np.zeros((n, 3))
    contrib = np.empty((n, 3))
    sh_o = np.zeros((n, 3), np.float32)
    sh_d = np.zeros((n, 3), np.float32)
    sh_t = np.zeros(n, np.float32)
    need = np.empty(n, bool)
    o64 = np.ascontiguousarray(origins, np.float64)
    d64 = np.ascontiguousarray(dirs, np.float64)
    for i in range(ls.count):
        if not ls.emits(i) or not ls.visible_diffuse[i]:
            continue
        for k in range(vt.light_samples):
            t0 = time.perf_counter()
            _inscatter_kernel(ls.params[i], o64, d64, seg_t, thr, sigma_s, sigma_t, g,
                              pixel, sample, vt.seed,
                              sampling.stream(sampling.VOLUME_DISTANCE, depth, i),
                              sampling.stream(sampling.VOLUME_LIGHT, depth, i), k,
                              vt.light_samples, vt.sample_bits, float(pr.extent), far_ok,
                              contrib, sh_o, sh_d, sh_t, need)
            if sigma_s_at is not None:
                idx = np.flatnonzero(need)
                contrib[idx] *= sigma_s_at(idx, sh_o[idx].astype(np.float64))
            m.attenuate(contrib, need, sh_o, sh_d, sh_t)
            t1 = time.perf_counter()
            idx = np.flatnonzero(need)
            if idx.size and ls.cast_shadow[i]:
                if pr.surfaces.cutout:
                    trans = pr.surfaces.transmittance(pr.accel, pr.tri_vertices, pr.tri_normals,
                                                      pr.extent, sh_o[idx], sh_d[idx], sh_t[idx])
                else:
                    trans = (~pr.accel.occluded(sh_o[idx], sh_d[idx], sh_t[idx])).astype(np.float64)
                out[idx] += contrib[idx] * trans[:, None]
                stats["rays_shadow"] += idx.size
            elif idx.size:
                out[idx] += contrib[idx]
            stats["time_volume_shadow"] = (stats.get("time_volume_shadow", 0.0)
                                           + time.perf_counter() - t1)
            stats["time_volume"] = stats.get("time_volume", 0.0) + t1 - t0
    return out


def surface_bounds(prepared: PreparedScene, prim, dirs) -> np.ndarray:
    """(N,) float64 |cos| between N rays (unit dirs (N, 3)) and the triangles prim (N,)
    (-1: missed) they end on, where the triangle's material transmits nothing (the medium
    ends there for the beam estimate, ``regions.Medium.stretches``' end_cos); NaN where a
    ray misses or its surface lets light through (glass, translucent: the medium may go on
    behind it)."""
    prim = np.asarray(prim)
    out = np.full(prim.shape[0], np.nan)
    hit = np.flatnonzero(prim >= 0)
    if hit.size == 0:
        return out
    keep = hit[prepared.opaque[prepared.tri_material[prim[hit]]]]
    v = prepared.tri_vertices[prim[keep]].astype(np.float64)
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    length = np.linalg.norm(n, axis=1)
    cos = np.abs(np.einsum("ij,ij->i", n, np.asarray(dirs, np.float64)[keep]))
    out[keep] = np.where(length > 0, np.minimum(cos / np.where(length > 0, length, 1.0), 1.0),
                         np.nan)
    return out


def add_segments(vt: VolumeTerms, origins, dirs, seg_t, thr, rows, pixel, sample, depth,
                 direct_target, indirect_target, emission_target, stats,
                 n_inside=None, end_cos=None) -> np.ndarray:
    """Add the volume terms of N camera segments (origins, unit dirs (N, 3), lengths
    seg_t (N,) metres, inf for escaping rays; path weights thr (N, 3)) to the targets' rows
    (N,) (per-sample accumulators (R, 3) float64), and return thr times the segments'
    transmittance, the weight of what lies behind them.

    n_inside (N,): the refractive index of the dielectric each segment lies in (None: 1).
    end_cos (N,): ``surface_bounds`` of the surfaces the segments end on (None: none bounds
    the medium; its boundaries still do).
    The camera paths' refractions do not scale radiance by eta^2 (Cycles' convention), but
    the beam estimate is the physical radiance there, n^2 times what the convention
    carries: it is divided by n^2 (a smoke-filled glass sphere).

    A stretch of varying density is cut at the tentative collisions of a ratio-tracking
    walk (``_split_heterogeneous``); each piece is integrated as a homogeneous stretch of
    the homogeneous part, weighted by the walk's running transmittance, and its Volume
    Direct takes sigma_s at the point it scatters.

    pixel, sample (R,) int64 key the random numbers (with depth, the bounce)."""
    m = vt.medium
    seg_t = np.ascontiguousarray(seg_t, np.float64)
    st = m.stretches(origins, dirs, seg_t, end_cos)
    ray = st.ray
    # Each stretch as a segment of its own: its start, its length, the weight reaching it
    s_o = np.ascontiguousarray(np.asarray(origins, np.float64)[ray]
                               + st.t0[:, None] * np.asarray(dirs, np.float64)[ray])
    s_d = np.ascontiguousarray(np.asarray(dirs, np.float64)[ray])
    s_len = np.ascontiguousarray(st.length)
    s_thr = np.ascontiguousarray(thr[ray] * st.before)
    s_ray = ray
    sig_s, sig_t, g, em = st.sigma_s, np.ascontiguousarray(st.sigma_t), st.g, st.emission
    s_bounds = stretch_bounds(st)
    fld = het_s = None
    if st.field is not None and np.any(st.field >= 0):
        (s_o, s_d, s_len, s_thr, s_ray, sig_s, sig_t, g, em, fld,
         het_s, s_bounds) = _split_heterogeneous(vt, st, s_o, s_d, s_len, s_thr, pixel[rows],
                                                 sample[rows], depth)
    s_rows = rows[s_ray]
    s_photon = s_thr
    if n_inside is not None and np.any(n_inside != 1.0):
        s_photon = s_thr / (np.asarray(n_inside, np.float64)[s_ray] ** 2)[:, None]
    scat = np.flatnonzero(np.any(sig_s > 0, axis=1) if fld is None else
                          np.any(sig_s > 0, axis=1) | np.any(het_s > 0, axis=1))
    if scat.size:
        sl = scat if scat.size < s_ray.size else slice(None)
        if vt.single_scattering and vt.prepared.light_set.count:
            direct_args = (s_o[sl], s_d[sl], s_len[sl], s_thr[sl])
            if fld is None:
                out = _single_scattering(vt, *direct_args, np.ascontiguousarray(sig_s[sl]),
                                         sig_t[sl], np.ascontiguousarray(g[sl]),
                                         pixel[s_rows[sl]], sample[s_rows[sl]], depth, stats)
            else:
                # sigma_s varies: the kernel takes 1 and the point's sigma_s multiplies after
                hs, hom, f = het_s[sl], sig_s[sl], fld[sl]

                def sigma_s_at(idx, points):
                    # rho (K, 1), or a varying colour's per-channel factor (K, 3)
                    return hom[idx] + m.fields.scattering(points, f[idx]) * hs[idx]
                out = _single_scattering(vt, *direct_args, np.ones((len(hs), 3)), sig_t[sl],
                                         np.ascontiguousarray(g[sl]), pixel[s_rows[sl]],
                                         sample[s_rows[sl]], depth, stats, sigma_s_at)
            np.add.at(direct_target, s_rows[sl], out)
        t0 = time.perf_counter()
        for vmap in (vt.volume_map, vt.caustic_map):
            if vmap is not None and len(vmap):
                est = beam_estimate(vmap, s_o[scat], s_d[scat], s_len[scat], sig_t[scat],
                                    g[scat], s_bounds[scat])
                np.add.at(indirect_target, s_rows[scat], s_photon[scat] * est)
        stats["time_volume_beam"] = stats.get("time_volume_beam", 0.0) + time.perf_counter() - t0
    if m.emits:
        np.add.at(emission_target, s_rows, s_thr * regions.emitted(em, sig_t, s_len))
    return thr * st.through


def _split_heterogeneous(vt: VolumeTerms, st, s_o, s_d, s_len, s_thr, pixel, sample, depth):
    """Cut the heterogeneous stretches of ``st`` at the tentative collisions of one
    ratio-tracking walk each (tracking.ratio_tracking_points; its running product is an
    unbiased estimate of the heterogeneous part's transmittance anywhere between two of
    them): the pieces replace the stretch, each with its start, length, weight times the
    running product, and the stretch's homogeneous part as coefficients. Returns the new
    (s_o, s_d, s_len, s_thr, ray, sigma_s, sigma_t, g, emission, field (P,) int64 (-1:
    homogeneous), het_s (P, 3), bounds (P, 4) (``stretch_bounds``, each piece's distances
    to its stretch's planes)): for a piece of a heterogeneous stretch sigma_s is the
    homogeneous part, to which rho(x) het_s adds where Volume Direct scatters. pixel,
    sample (N,) per segment key the walks."""
    m = vt.medium
    het = np.flatnonzero(st.field >= 0)
    seg = st.ray[het]
    index = pixel[seg] * np.int64(1 << 24) + sample[seg] * np.int64(64) + (het - st.start[seg])
    walk, t, T, _ = tracking.ratio_tracking_points(
        m.fields.along(st.field[het], st.majorant[het], st.het_a[het], st.het_s[het]),
        s_o[het], s_d[het], 0.0, s_len[het],
        np.arange(het.size), st.het_a[het]
        + st.het_s[het], st.majorant[het], vt.seed,
        sampling.stream(sampling.MEDIUM_TRACKING, 4095, min(depth, 4095)), index=index)
    # Pieces per heterogeneous stretch: 1 + its tentative collisions
    count = np.ones(st.t0.shape[0], np.int64)
    count[het] += np.bincount(walk, minlength=het.size)
    first = np.zeros(count.size + 1, np.int64)
    np.cumsum(count, out=first[1:])
    p = int(first[-1])
    src = np.repeat(np.arange(count.size), count)     # the stretch each piece cuts
    k = np.arange(p) - first[src]                      # the piece's rank in its stretch
    a = np.zeros(p)                                    # piece start, from the stretch's t0
    b = s_len[src].copy()                              # piece end
    w = np.ones((p, 3))
    # The j-th collision of walk h ends piece j and starts piece j + 1 of stretch het[h]
    rank = np.arange(walk.size) - np.searchsorted(walk, walk)
    at = first[het[walk]] + rank
    b[at] = t
    a[at + 1] = t
    w[at + 1] = T
    out_o = s_o[src] + a[:, None] * s_d[src]
    fld = st.field[src]
    bounds = stretch_bounds(st)[src]
    bounds[:, 1] = a
    short = b < s_len[src]  # an escaping stretch's last piece: inf - inf, left 0
    bounds[:, 3] = 0.0
    bounds[short, 3] = s_len[src][short] - b[short]
    return (np.ascontiguousarray(out_o), np.ascontiguousarray(s_d[src]), b - a,
            np.ascontiguousarray(s_thr[src] * w), st.ray[src], st.sigma_s[src],
            np.ascontiguousarray(st.sigma_t[src]), st.g[src], st.emission[src], fld,
            np.where((fld >= 0)[:, None], st.het_s[src], 0.0), bounds)


def stretch_bounds(st: regions.Stretches) -> np.ndarray:
    """(S, 4) float64 the beam estimate's planes of each stretch (``VolumePhotonMap.radiance``'s
    bounds): (bound0, 0, bound1, 0), the planes at the stretch's own ends."""
    out = np.zeros((st.t0.shape[0], 4))
    out[:, 0] = st.bound0
    out[:, 2] = st.bound1
    return out


def beam_estimate(vmap: VolumePhotonMap, origins, dirs, length, sigma_t, g,
                  bounds=None) -> np.ndarray:
    """The beam radiance estimate (N, 3) float64 W/(m^2 sr) of N homogeneous stretches
    (origins, unit dirs (N, 3), length (N,) metres, inf allowed; sigma_t (N, 3) 1/m, g
    (N,); bounds (N, 4) their planes, ``stretch_bounds``, or None): one query per distinct
    medium, since the map's query takes one."""
    out = np.zeros((origins.shape[0], 3))
    coef = np.concatenate([sigma_t, np.asarray(g, np.float64)[:, None]], axis=1)
    keys, inv = np.unique(coef, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    for j in range(keys.shape[0]):
        sel = np.flatnonzero(inv == j) if keys.shape[0] > 1 else slice(None)
        out[sel] = vmap.radiance(origins[sel], dirs[sel], np.minimum(length[sel], SEGMENT_FAR),
                                 keys[j, :3], float(keys[j, 3]),
                                 None if bounds is None else bounds[sel])
    return out
