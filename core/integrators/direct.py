"""Direct illumination by shadow rays: the seed lecture's first term, L_direct, at surface
points, from every light, the emissive triangles and the world.

For each source and light sample, one numba kernel (``_shade_kernel``, which takes many
such pairs at once and builds each point's lobes once for them all) samples a point
on the source (core/lights/kernels.py), evaluates the reflection lobes there (diffuse and
rough glossy, core/materials/bsdf.py) and writes the unshadowed contribution f |cos| L / pdf with
the shadow ray that decides it; each pair's needed shadow rays are packed and sent to Embree in
one batch (``Accelerator.occluded``, or the cut-out transmittance of core/materials/textures.py);
the clear ones are added to the target. Light samples are stratified over a pixel's
samples x light samples (scrambled Sobol), keyed by (seed, pixel, sample).

Users: the camera pass (core/integrators/photon_mapping.py) at its first hits and behind
mirrors and glass, and SPPM (core/integrators/sppm.py) at its visible points, both through
``shade`` with the ``ShadingPoints`` they reached.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..materials import bsdf
from ..materials import closure
from ..scene import geometry
from ..lights import kernels as light_kernels
from ..lights import light_set as lights
from .. import sampling
from ..materials import textures
from ..media import regions
from ..scene.accel import Accelerator
from ..prepared import PreparedScene
from ..settings import RenderSettings

SOURCE_LIGHT, SOURCE_TRIANGLES, SOURCE_WORLD = 0, 1, 2
SHADE_SLOTS = 1 << 20
"""Most (point, light sample) slots of one ``_shade_kernel`` call (~53 bytes each: its
contribution and shadow ray): ``shade`` hands the kernel as many of its (source, light
sample) pairs as fit, at least one, so a point's lobes are built once for them all."""


@njit(cache=True, parallel=True, error_model="numpy")
def _shade_kernel(pair_source, pair_q, pair_dim, pair_pick_dim, pair_k, pair_diffuse,
                  pair_glossy, tris_cdf, tris_prob, tris_v0, tris_e1, tris_e2, tris_n,
                  tris_area, tris_rad, world, tab, pos, ngf, nsf, tan, d, front, mat, eps, thr,
                  texel, diffuse_on, mis, lam, pixel, sample, seed, k_count, bits, extent,
                  contrib, sh_o, sh_d, sh_t, need):
    """For each point i and each of P (source, light sample) pairs p: one light sample,
    its unshadowed contribution f |cos| L / pdf / k_count (contrib[p, i]) and the shadow
    ray that decides it (need[p, i]). Light samples are stratified over the pixel's
    samples x light samples (index sample * k_count + k).

    Pair p: its source (pair_source SOURCE_*, pair_q the light's parameter row), its
    random streams (pair_dim the light sample's, pair_pick_dim the triangle pick's), its
    light sample k (pair_k) and the light's diffuse / glossy visibility (pair_diffuse,
    pair_glossy, 0 or 1). The point's lobes (``closure.hit_lobes``: they do not depend on
    the light's direction) are built once for all its pairs, at the first whose light
    sample succeeds, into the block's ``closure.lobe_buffer``, and evaluated per sample
    (``closure.parts_at``), as ``closure.eval_parts`` would (issue 13: building them was
    half the kernel's time).
    The light's pdf is computed only where mis[i] reads it.

    f is the material's whole non-delta BSDF, split by ``closure.parts_at`` into the
    diffuse-like lobes' part (Lambert, Oren-Nayar, translucent, sheen: the part the photon
    maps continue; times diffuse_on[i]) and the glossy lobes' part, which camera paths also
    reach by sampling the BSDF where mis[i]: there the glossy part takes the power
    heuristic's weight of light sampling (k_count samples) against BSDF sampling, whose
    pdf is eval's pdf times ``continue_probability``. lam (N,) float64: the paths'
    wavelengths in nm (0: RGB), the IOR of dispersive transmission lobes
    (docs/dispersion.md), as the continuation samples them."""
    fmax = 3.0e38
    scale = 1.0 / k_count
    n_points = pos.shape[0]
    size = closure.LOBE_BLOCK
    for block in prange((n_points + size - 1) // size):
        lobes = closure.lobe_buffer(tab)  # the block's scratch: no allocation per point
        F = np.empty(12)
        for i in range(block * size, min(n_points, (block + 1) * size)):
            px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
            m = mat[i]
            wox, woy, woz = -d[i, 0], -d[i, 1], -d[i, 2]
            built = False
            for p in range(pair_source.shape[0]):
                need[p, i] = False
                contrib[p, i, 0] = 0.0
                contrib[p, i, 1] = 0.0
                contrib[p, i, 2] = 0.0
                source = pair_source[p]
                q = pair_q[p]
                u1, u2 = sampling.sobol2(sample[i] * k_count + pair_k[p], bits,
                                         sampling.pattern(seed, pixel[i], pair_dim[p]))
                pl = 0.0
                if source == SOURCE_LIGHT:
                    wx, wy, wz, dist, l0, l1, l2, cl, ok = light_kernels.sample_light(
                        q, px, py, pz, u1, u2)
                    if ok and mis[i]:
                        pl = light_kernels.light_pdf(q, px, py, pz, wx, wy, wz, dist)
                elif source == SOURCE_TRIANGLES:
                    u0 = sampling.hash_uniform(seed, pixel[i], sample[i], pair_pick_dim[p])
                    wx, wy, wz, dist, l0, l1, l2, cl, ok = light_kernels.sample_triangles(
                        tris_cdf, tris_prob, tris_v0, tris_e1, tris_e2, tris_n, tris_area,
                        tris_rad, px, py, pz, u0, u1, u2)
                    if ok and mis[i]:
                        j = sampling.pick(tris_cdf, u0)
                        pl = light_kernels.triangle_pdf(tris_prob, tris_area, j, wx, wy, wz,
                                                        tris_n[j, 0], tris_n[j, 1], tris_n[j, 2],
                                                        dist)
                else:
                    # the whole sphere where the surface transmits: the world behind it too
                    sphere = closure.transmits(tab, m)
                    wx, wy, wz, dist, l0, l1, l2, cl, ok = light_kernels.sample_world(
                        world[0], world[1], world[2], nsf[i, 0], nsf[i, 1], nsf[i, 2], u1, u2,
                        sphere)
                    if mis[i]:
                        pl = light_kernels.world_pdf(nsf[i, 0], nsf[i, 1], nsf[i, 2], wx, wy, wz,
                                                     sphere)
                if not ok:
                    continue
                if not built:
                    nl = closure.hit_lobes_into(lobes, F, tab, m, texel[i, 0], texel[i, 1],
                                                texel[i, 2], wox, woy, woz, nsf[i, 0], nsf[i, 1],
                                                nsf[i, 2], ngf[i, 0], ngf[i, 1], ngf[i, 2],
                                                tan[i, 0], tan[i, 1], tan[i, 2], front[i],
                                                lam[i])
                    L = lobes[:nl]
                    built = True
                d0, d1, d2, g0, g1, g2, pb = closure.parts_at(L, F, wx, wy, wz, ngf[i, 0],
                                                              ngf[i, 1], ngf[i, 2], False, True)
                f0, f1, f2 = d0 + g0, d1 + g1, d2 + g2
                if f0 <= 0.0 and f1 <= 0.0 and f2 <= 0.0:
                    continue
                wl = 1.0
                if mis[i] and pl > 0.0:
                    pc = pb * continue_probability(f0, f1, f2, g0, g1, g2)
                    wl = light_kernels.power_heuristic(k_count, pl, 1.0, pc)
                kd = pair_diffuse[p] * diffuse_on[i] * scale
                kg = pair_glossy[p] * wl * scale
                c0 = (d0 * kd + g0 * kg) * l0 * thr[i, 0]
                c1 = (d1 * kd + g1 * kg) * l1 * thr[i, 1]
                c2 = (d2 * kd + g2 * kg) * l2 * thr[i, 2]
                if c0 <= 0.0 and c1 <= 0.0 and c2 <= 0.0:
                    continue
                contrib[p, i, 0] = c0
                contrib[p, i, 1] = c1
                contrib[p, i, 2] = c2
                e = eps[i]
                if np.isinf(dist):
                    tf = fmax
                else:
                    qx, qy, qz = px + wx * dist, py + wy * dist, pz + wz * dist
                    tf = dist - e - geometry.offset_eps(qx, qy, qz, extent) / max(cl, 1e-3)
                    if tf <= 0.0:
                        continue  # the light touches the surface: nothing can come in between
                # The shadow ray leaves on the side of the light (transmission lobes: the far side).
                side = e if ngf[i, 0] * wx + ngf[i, 1] * wy + ngf[i, 2] * wz >= 0.0 else -e
                sh_o[p, i, 0] = px + side * ngf[i, 0]
                sh_o[p, i, 1] = py + side * ngf[i, 1]
                sh_o[p, i, 2] = pz + side * ngf[i, 2]
                sh_d[p, i, 0] = wx
                sh_d[p, i, 1] = wy
                sh_d[p, i, 2] = wz
                sh_t[p, i] = min(tf, fmax)
                need[p, i] = True


@njit(cache=True, parallel=True, error_model="numpy")
def _triangle_uniforms_kernel(pixel, sample, seed, dim, pick_dim, k, k_count, bits, u0, u1, u2):
    """The uniforms ``_shade_kernel`` picks an emissive triangle point with (the same
    streams), for the textured emitters' correction (``EmissiveTriangles.rescale``)."""
    for i in prange(pixel.shape[0]):
        u1[i], u2[i] = sampling.sobol2(sample[i] * k_count + k, bits,
                                       sampling.pattern(seed, pixel[i], dim))
        u0[i] = sampling.hash_uniform(seed, pixel[i], sample[i], pick_dim)


@njit(cache=True, error_model="numpy")
def continue_probability(f0, f1, f2, g0, g1, g2):
    """Probability that a camera path goes on along a BSDF-sampled direction: the glossy
    part's share max(g) / max(f) of the sampled f |cos| (1 for a pure glossy lobe, small
    where a diffuse lobe gave the direction: its light comes from the photon maps)."""
    fm = max(f0, max(f1, f2))
    if fm <= 0.0:
        return 0.0
    return min(1.0, max(g0, max(g1, g2)) / fm)


@njit(cache=True, error_model="numpy")
def _compact_kernel(need, sh_o, sh_d, sh_t, idx, o, d, t):
    """Pack the shadow rays that are needed (one sequential pass); returns their count."""
    c = 0
    for i in range(need.shape[0]):
        if need[i]:
            idx[c] = i
            for k in range(3):
                o[c, k] = sh_o[i, k]
                d[c, k] = sh_d[i, k]
            t[c] = sh_t[i]
            c += 1
    return c


@njit(cache=True, parallel=True, error_model="numpy")
def _gather_kernel(target, rows, contrib, need_idx, occluded):
    """target[rows] += contrib, except the points whose shadow ray was blocked."""
    for j in prange(need_idx.shape[0]):
        if occluded[j]:
            i = need_idx[j]
            contrib[i, 0] = 0.0
            contrib[i, 1] = 0.0
            contrib[i, 2] = 0.0
    for i in prange(rows.shape[0]):
        r = rows[i]
        target[r, 0] += contrib[i, 0]
        target[r, 1] += contrib[i, 1]
        target[r, 2] += contrib[i, 2]


def _textured_triangles(ctx, tris, hit, pixel, sample, dim, depth, k, contrib):
    """Emissive-triangle samples on textured emitters: contrib (N, 3), computed with the
    triangle's pick radiance, times (the program's emission at the sampled point) /
    (that radiance): the sample's pdf is unchanged (pick by the mean, uniform on the
    triangle), so the estimate stays unbiased and MIS with BSDF-sampled hits holds."""
    n = pixel.shape[0]
    u0, u1, u2 = np.empty(n), np.empty(n), np.empty(n)
    _triangle_uniforms_kernel(np.ascontiguousarray(pixel, np.int64),
                              np.ascontiguousarray(sample, np.int64), ctx.seed, dim,
                              sampling.stream(sampling.LIGHT_PICK, depth, k), k,
                              ctx.light_samples, ctx.sample_bits, u0, u1, u2)
    j, b1, b2 = tris.points(u0, u1, u2)
    point = tris.v0[j] + b1[:, None] * tris.e1[j] + b2[:, None] * tris.e2[j]
    w = point - hit.position
    w /= np.maximum(np.linalg.norm(w, axis=1), 1e-300)[:, None]
    tris.rescale(contrib, j, b1, b2, w, ctx.emission_points)


@dataclass
class DirectLighting:
    """What ``shade`` reads, built once per render (``prepare``)."""

    light_set: lights.LightSet
    emissive: lights.EmissiveTriangles
    closures: tuple               # the ClosureTable (PreparedScene.closures)
    world: np.ndarray             # (3,) background radiance
    extent: float                 # metres, the scene's size (ray offsets)
    accel: Accelerator            # shared with the caller, who closes it
    surfaces: textures.SurfaceTextures
    tri_vertices: np.ndarray      # (T, 3, 3) float32
    tri_normals: np.ndarray       # (T, 3, 3) float32 corner normals
    seed: int
    light_samples: int
    sample_bits: int              # bits of the (sample, light sample) index
    stats: dict = field(default_factory=lambda: {"rays_shadow": 0, "time_shading": 0.0,
                                                 "time_shadow": 0.0})
    no_light: np.ndarray = field(default_factory=lambda: np.zeros(light_kernels.P_COUNT))
    medium: regions.Medium | None = None  # the media shadow rays cross (core/media/regions.py)
    emission_points: object = None  # HitShader.emission_points: textured emitters' radiance


class ShadingPoints(NamedTuple):
    """N surface points reached by camera paths, where direct light is added.

    position (N, 3) metres; ng / ns (N, 3) unit geometric and shading normals on the
    viewer's side; direction (N, 3) unit, the direction the points were reached along;
    material (N,) int32; eps (N,) ray offsets (core/scene/geometry.py); throughput (N, 3)
    path weights; albedo (N, 3) the diffuse albedo there (textured); rows (N,) int64 the
    unique rows of the target they add to. texel (N, 3): the texel colour multiplying the
    closures' COLOR (None: albedo over the material's diffuse weight, 1 where it has
    none); diffuse_on (N,) float64, 1 where the diffuse part's direct light counts here
    (None: everywhere); mis (N,) bool, the path
    goes on by sampling the BSDF here, so the glossy part is weighted against it (None:
    nowhere); front (N,) bool, the point was reached from the front of the mesh's geometric
    normal (a dielectric's eta for the transmitted light; None: from the front);
    closures: the ClosureTable ``material`` indexes (``HitShader.closures_at``'s per-batch
    table, whose rows past the materials are programmed hits; None: the prepared one);
    wavelength (N,) float64 nm, the paths' wavelengths (0 or None: RGB; docs/dispersion.md);
    tangent (N, 3) float64: the BSDF frame's tangent (``HitShader.tangents``; None:
    ``closure.DEFAULT_TANGENT`` everywhere)."""

    position: np.ndarray
    ng: np.ndarray
    ns: np.ndarray
    direction: np.ndarray
    material: np.ndarray
    eps: np.ndarray
    throughput: np.ndarray
    albedo: np.ndarray
    rows: np.ndarray
    texel: np.ndarray | None = None
    diffuse_on: np.ndarray | None = None
    mis: np.ndarray | None = None
    front: np.ndarray | None = None
    closures: tuple | None = None
    wavelength: np.ndarray | None = None
    tangent: np.ndarray | None = None


def prepare(settings: RenderSettings, prepared: PreparedScene, samples: int,
            stats: dict | None = None,
            medium: regions.Medium | None = None) -> DirectLighting:
    """The direct lighting of a render over the prepared scene's tables and accelerator:
    settings' seed and light_samples; ``samples`` sizes the sample index (the camera
    pass's samples per pixel, SPPM's pass count). ``stats``: the caller's counters to add
    rays_shadow, time_shading and time_shadow to. ``medium``: the World's medium, whose
    transmittance multiplies every shadow ray's light (None: vacuum)."""
    dl = DirectLighting(
        light_set=prepared.light_set, emissive=prepared.emissive,
        closures=prepared.closures, world=prepared.world, extent=float(prepared.extent),
        accel=prepared.accel, surfaces=prepared.surfaces, tri_vertices=prepared.tri_vertices,
        tri_normals=prepared.tri_normals, seed=int(settings.seed),
        light_samples=int(settings.light_samples),
        sample_bits=sampling.index_bits(int(samples) * int(settings.light_samples)),
        medium=medium, emission_points=prepared.hit_shader.emission_points)
    if stats is not None:
        dl.stats = stats
    return dl


def shade(ctx: DirectLighting, hit: ShadingPoints, pixel, sample, depth, target):
    """Shadow-ray direct lighting at the points from every light, the emissive triangles
    and the world; adds throughput f |cos| L / pdf where the shadow ray is clear to
    target[hit.rows].

    pixel, sample (N,) int64 key the random numbers; depth: the bounce (another random
    stream per bounce); target (R, 3) float64."""
    ls, tris = ctx.light_set, ctx.emissive
    k_count = ctx.light_samples
    bits = ctx.sample_bits
    n = hit.position.shape[0]
    texel = hit.texel
    if texel is None:  # the texel behind the textured albedo: albedo / the lobe's weight
        lobe = ctx.surfaces.diffuse[hit.material]
        with np.errstate(divide="ignore", invalid="ignore"):
            texel = np.where(lobe > 0, hit.albedo / np.where(lobe > 0, lobe, 1.0), 1.0)
    diffuse_on = np.ones(n) if hit.diffuse_on is None else hit.diffuse_on
    mis = np.zeros(n, bool) if hit.mis is None else hit.mis
    front = np.ones(n, bool) if hit.front is None else hit.front
    lam = np.zeros(n) if hit.wavelength is None else hit.wavelength
    tangent = (closure.default_tangents(n) if hit.tangent is None
               else np.ascontiguousarray(hit.tangent, np.float64))
    sources = [(SOURCE_LIGHT, i) for i in range(ls.count) if ls.emits(i)]
    if tris.count:
        sources.append((SOURCE_TRIANGLES, ls.count))
    if np.any(ctx.world > 0):
        sources.append((SOURCE_WORLD, -1))
    # Every (source, light sample) pair, in the order their light is added to the target.
    pairs = [(source, i, k) for source, i in sources for k in range(k_count)]
    if not pairs:
        return
    per_call = max(1, min(len(pairs), SHADE_SLOTS // max(n, 1)))
    contrib = np.empty((per_call, n, 3))
    sh_o = np.empty((per_call, n, 3), np.float32)
    sh_d = np.empty((per_call, n, 3), np.float32)
    sh_t = np.empty((per_call, n), np.float32)
    need = np.empty((per_call, n), bool)
    idx = np.empty(n, np.int64)
    pk_o, pk_d = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32)
    pk_t = np.empty(n, np.float32)
    tab = ctx.closures if hit.closures is None else hit.closures
    for first in range(0, len(pairs), per_call):
        group = pairs[first:first + per_call]
        p_source = np.array([source for source, _, _ in group], np.int64)
        p_q = np.stack([ls.params[i] if source == SOURCE_LIGHT else ctx.no_light
                        for source, i, _ in group])
        p_dim = np.array([sampling.stream(sampling.LIGHT_SAMPLE, depth, i + 1)
                          for _, i, _ in group], np.int64)
        p_pick = np.array([sampling.stream(sampling.LIGHT_PICK, depth, k) for _, _, k in group],
                          np.int64)
        p_k = np.array([k for _, _, k in group], np.int64)
        p_diffuse = np.array([float(ls.visible_diffuse[i]) if source == SOURCE_LIGHT else 1.0
                              for source, i, _ in group])
        p_glossy = np.array([float(ls.visible_glossy[i]) if source == SOURCE_LIGHT else 1.0
                             for source, i, _ in group])
        t0 = time.perf_counter()
        _shade_kernel(p_source, p_q, p_dim, p_pick, p_k, p_diffuse, p_glossy, tris.cdf,
                      tris.probability, tris.v0, tris.e1, tris.e2, tris.normal, tris.area,
                      tris.radiance, ctx.world, tab, hit.position, hit.ng, hit.ns, tangent,
                      hit.direction, front, hit.material, hit.eps, hit.throughput, texel,
                      diffuse_on, mis, lam, pixel, sample, ctx.seed, k_count, bits, ctx.extent,
                      contrib, sh_o, sh_d, sh_t, need)
        ctx.stats["time_shading"] += time.perf_counter() - t0
        for p, (source, i, k) in enumerate(group):
            t0 = time.perf_counter()
            c_p, o_p, d_p, t_p, need_p = contrib[p], sh_o[p], sh_d[p], sh_t[p], need[p]
            if source == SOURCE_TRIANGLES and tris.textured is not None:
                _textured_triangles(ctx, tris, hit, pixel, sample, int(p_dim[p]), depth, k, c_p)
            if ctx.medium is not None:  # the shadow segment's transmittance
                ctx.medium.attenuate(c_p, need_p, o_p, d_p, t_p)
            t1 = time.perf_counter()
            shadows = bool(ls.cast_shadow[i]) if source == SOURCE_LIGHT else True
            c = _compact_kernel(need_p, o_p, d_p, t_p, idx, pk_o, pk_d, pk_t) if shadows else 0
            occ = np.zeros(0, bool)
            if c and ctx.surfaces.cutout:
                # Shadows through cut-outs: the light times the product of (1 - opacity).
                trans = ctx.surfaces.transmittance(ctx.accel, ctx.tri_vertices, ctx.tri_normals,
                                                   ctx.extent, pk_o[:c], pk_d[:c], pk_t[:c])
                c_p[idx[:c]] *= trans[:, None]
                occ = trans <= 0.0
                ctx.stats["rays_shadow"] += c
            elif c:
                occ = ctx.accel.occluded(pk_o[:c], pk_d[:c], pk_t[:c])
                ctx.stats["rays_shadow"] += c
            t2 = time.perf_counter()
            _gather_kernel(target, hit.rows, c_p, idx[:c], occ)
            ctx.stats["time_shading"] += t1 - t0 + time.perf_counter() - t2
            ctx.stats["time_shadow"] += t2 - t1
