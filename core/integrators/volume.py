"""The camera pass's volume terms: what a camera segment through the World's medium
(core/media/world.py) adds, and how it attenuates what lies behind it.

For a segment from o along the unit d to t_hit (inf for a ray that escapes):
- transmittance exp(-sigma_t t_hit) multiplies everything behind (the surface hit, the
  world background: 0 through fog on an escaping ray, as in Cycles, whose homogeneous World
  volume extinguishes the background and the sun);
- Volume Direct: single scattering of the lights, estimated per light and light sample by
  one equiangular distance towards the light's position (Kulla & Fajardo 2012;
  core/media/equiangular.py; area lights too, the pdf covers the whole segment) and a
  light sample from the scattering point (``lights.kernels.sample_light``) with its shadow
  ray: sigma_s p(cos) exp(-sigma_t t) exp(-sigma_t r) L / (pdf_t pdf_light). Sun lights
  and the world background add nothing in World fog (their light crosses infinite
  medium); emissive triangles' single scattering comes from the volume photon map
  (core/photons/tracing.py stores their first collisions);
- Volume Indirect: the beam radiance estimate (core/photons/beam.py, Jarosz et al. 2008)
  of the volume photon map and of the volumetric caustic map along the segment;
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
from ..media import equiangular, world
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

    medium: world.WorldMedium
    prepared: PreparedScene
    seed: int
    light_samples: int
    sample_bits: int
    volume_map: VolumePhotonMap | None = None
    caustic_map: VolumePhotonMap | None = None


def prepare(settings: RenderSettings, prepared: PreparedScene, samples: int) -> VolumeTerms | None:
    """The volume terms of a render, or None when the scene has no medium to integrate
    (then every image is exactly as without media). Raises SceneError for a medium the
    renderer does not integrate yet (core/media/world.py)."""
    medium = world.renderable(prepared.scene.media)
    if medium is None:
        return None
    return VolumeTerms(medium=medium, prepared=prepared, seed=int(settings.seed),
                       light_samples=int(settings.light_samples),
                       sample_bits=sampling.index_bits(int(samples) * int(settings.light_samples)))


@njit(cache=True, parallel=True, error_model="numpy")
def _inscatter_kernel(q, origins, dirs, seg_t, thr, sigma_s, sigma_t, g, pixel, sample, seed,
                      dim_t, dim_l, k, k_count, bits, extent, contrib, sh_o, sh_d, sh_t, need):
    """One equiangular distance and one light sample per segment: the unshadowed single
    scattering thr sigma_s p T(t) T(r) L / (pdf_t pdf_light) / k_count (contrib (N, 3))
    and the shadow ray from the scattering point to the light (need[i])."""
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
        delta, dist, ta, tb = equiangular.setup(ox, oy, oz, dx, dy, dz, px, py, pz, 0.0, t_end)
        t, pdf_t = equiangular.sample(delta, dist, ta, tb, u_t)
        if not (pdf_t > 0.0) or t <= 0.0 or t >= t_end:
            continue
        xx, xy, xz = ox + t * dx, oy + t * dy, oz + t * dz
        u1, u2 = sampling.sobol2(sample[i] * k_count + k, bits,
                                 sampling.pattern(seed, pixel[i], dim_l))
        wx, wy, wz, r, l0, l1, l2, cl, ok = light_kernels.sample_light(q, xx, xy, xz, u1, u2)
        if not ok or not (r < SEGMENT_FAR):
            continue
        # cos between the light's propagation (-w) and the scattered one towards the camera (-d)
        ph = hg_eval(g, wx * dx + wy * dy + wz * dz)
        f = ph * scale / pdf_t
        a = t + r
        c0 = thr[i, 0] * sigma_s[0] * np.exp(-sigma_t[0] * a) * l0 * f
        c1 = thr[i, 1] * sigma_s[1] * np.exp(-sigma_t[1] * a) * l1 * f
        c2 = thr[i, 2] * sigma_s[2] * np.exp(-sigma_t[2] * a) * l2 * f
        if c0 <= 0.0 and c1 <= 0.0 and c2 <= 0.0:
            continue
        qx, qy, qz = xx + wx * r, xy + wy * r, xz + wz * r
        tf = r - geometry.offset_eps(qx, qy, qz, extent) / max(cl, 1e-3)
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


def _single_scattering(vt: VolumeTerms, origins, dirs, seg_t, thr, pixel, sample, depth,
                       stats) -> np.ndarray:
    """Volume Direct of N segments, (N, 3) float64 W/(m^2 sr), shadow rays included."""
    pr = vt.prepared
    ls = pr.light_set
    m = vt.medium
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
            _inscatter_kernel(ls.params[i], o64, d64, seg_t, thr, m.sigma_s, m.sigma_t, m.g,
                              pixel, sample, vt.seed,
                              sampling.stream(sampling.VOLUME_DISTANCE, depth, i),
                              sampling.stream(sampling.VOLUME_LIGHT, depth, i), k,
                              vt.light_samples, vt.sample_bits, float(pr.extent), contrib,
                              sh_o, sh_d, sh_t, need)
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


def add_segments(vt: VolumeTerms, origins, dirs, seg_t, thr, rows, pixel, sample, depth,
                 direct_target, indirect_target, emission_target, stats) -> np.ndarray:
    """Add the volume terms of N camera segments (origins, unit dirs (N, 3), lengths
    seg_t (N,) metres, inf for escaping rays; path weights thr (N, 3)) to the targets' rows
    (N,) (per-sample accumulators (R, 3) float64), and return thr times the segments'
    transmittance, the weight of what lies behind them.

    pixel, sample (R,) int64 key the random numbers (with depth, the bounce)."""
    m = vt.medium
    seg_t = np.ascontiguousarray(seg_t, np.float64)
    px, sm = pixel[rows], sample[rows]
    if m.scatters:
        if vt.prepared.light_set.count:
            direct_target[rows] += _single_scattering(vt, origins, dirs, seg_t, thr, px, sm,
                                                      depth, stats)
        t0 = time.perf_counter()
        for vmap in (vt.volume_map, vt.caustic_map):
            if vmap is not None and len(vmap):
                est = vmap.radiance(origins, dirs, np.minimum(seg_t, SEGMENT_FAR), m.sigma_t, m.g)
                indirect_target[rows] += thr * est
        stats["time_volume_beam"] = stats.get("time_volume_beam", 0.0) + time.perf_counter() - t0
    if np.any(m.emission > 0):
        emission_target[rows] += thr * world.emitted(m, seg_t)
    return thr * world.transmittance(m, seg_t)
