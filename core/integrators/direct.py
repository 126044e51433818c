"""Direct illumination by shadow rays: the seed lecture's first term, L_direct, at surface
points, from every light, the emissive triangles and the world.

For each source and light sample, one numba kernel (``_shade_kernel``) samples a point
on the source (core/lights/kernels.py), evaluates the reflection lobes there (diffuse and
rough glossy, core/materials/bsdf.py) and writes the unshadowed contribution f |cos| L / pdf with
the shadow ray that decides it; the needed shadow rays are packed and sent to Embree in
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


@njit(cache=True, parallel=True, error_model="numpy")
def _shade_kernel(source, q, tris_cdf, tris_prob, tris_v0, tris_e1, tris_e2, tris_n, tris_area,
                  tris_rad, world, tab, pos, ngf, nsf, tan, d, front, mat, eps, thr, texel,
                  diffuse_on, mis, lam, pixel, sample, seed, dim, pick_dim, k, k_count, bits,
                  use_diffuse,
                  use_glossy, extent, contrib, sh_o, sh_d, sh_t, need):
    """One light sample per point: unshadowed contribution f |cos| L / pdf / k_count and
    the shadow ray that decides it (need[i]). Light samples are stratified over the
    pixel's samples x light samples (index sample * k_count + k).

    f is the material's whole non-delta BSDF, split by ``closure.eval_parts`` into the
    diffuse-like lobes' part (Lambert, Oren-Nayar, translucent, sheen: the part the photon
    maps continue; times diffuse_on[i]) and the glossy lobes' part, which camera paths also
    reach by sampling the BSDF where mis[i]: there the glossy part takes the power
    heuristic's weight of light sampling (k_count samples) against BSDF sampling, whose
    pdf is eval's pdf times ``continue_probability``. lam (N,) float64: the paths'
    wavelengths in nm (0: RGB), the IOR of dispersive transmission lobes
    (docs/dispersion.md), as the continuation samples them."""
    fmax = 3.0e38
    scale = 1.0 / k_count
    for i in prange(pos.shape[0]):
        need[i] = False
        contrib[i, 0] = 0.0
        contrib[i, 1] = 0.0
        contrib[i, 2] = 0.0
        u1, u2 = sampling.sobol2(sample[i] * k_count + k, bits,
                                 sampling.pattern(seed, pixel[i], dim))
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        pl = 0.0
        if source == SOURCE_LIGHT:
            wx, wy, wz, dist, l0, l1, l2, cl, ok = light_kernels.sample_light(q, px, py, pz, u1, u2)
            if ok:
                pl = light_kernels.light_pdf(q, px, py, pz, wx, wy, wz, dist)
        elif source == SOURCE_TRIANGLES:
            u0 = sampling.hash_uniform(seed, pixel[i], sample[i], pick_dim)
            wx, wy, wz, dist, l0, l1, l2, cl, ok = light_kernels.sample_triangles(
                tris_cdf, tris_prob, tris_v0, tris_e1, tris_e2, tris_n, tris_area, tris_rad,
                px, py, pz, u0, u1, u2)
            if ok:
                j = sampling.pick(tris_cdf, u0)
                pl = light_kernels.triangle_pdf(tris_prob, tris_area, j, wx, wy, wz,
                                                tris_n[j, 0], tris_n[j, 1], tris_n[j, 2], dist)
        else:
            # the whole sphere where the surface transmits: the world behind it too
            sphere = closure.transmits(tab, mat[i])
            wx, wy, wz, dist, l0, l1, l2, cl, ok = light_kernels.sample_world(
                world[0], world[1], world[2], nsf[i, 0], nsf[i, 1], nsf[i, 2], u1, u2, sphere)
            pl = light_kernels.world_pdf(nsf[i, 0], nsf[i, 1], nsf[i, 2], wx, wy, wz, sphere)
        if not ok:
            continue
        m = mat[i]
        wox, woy, woz = -d[i, 0], -d[i, 1], -d[i, 2]
        d0, d1, d2, g0, g1, g2, pb = closure.eval_parts(
            tab, m, texel[i, 0], texel[i, 1], texel[i, 2], wox, woy, woz, wx, wy, wz,
            nsf[i, 0], nsf[i, 1], nsf[i, 2], ngf[i, 0], ngf[i, 1], ngf[i, 2],
            tan[i, 0], tan[i, 1], tan[i, 2], front[i], False, lam[i])
        f0, f1, f2 = d0 + g0, d1 + g1, d2 + g2
        if f0 <= 0.0 and f1 <= 0.0 and f2 <= 0.0:
            continue
        wl = 1.0
        if mis[i] and pl > 0.0:
            pc = pb * continue_probability(f0, f1, f2, g0, g1, g2)
            wl = light_kernels.power_heuristic(k_count, pl, 1.0, pc)
        kd = use_diffuse * diffuse_on[i] * scale
        kg = use_glossy * wl * scale
        c0 = (d0 * kd + g0 * kg) * l0 * thr[i, 0]
        c1 = (d1 * kd + g1 * kg) * l1 * thr[i, 1]
        c2 = (d2 * kd + g2 * kg) * l2 * thr[i, 2]
        if c0 <= 0.0 and c1 <= 0.0 and c2 <= 0.0:
            continue
        contrib[i, 0] = c0
        contrib[i, 1] = c1
        contrib[i, 2] = c2
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
        sh_o[i, 0] = px + side * ngf[i, 0]
        sh_o[i, 1] = py + side * ngf[i, 1]
        sh_o[i, 2] = pz + side * ngf[i, 2]
        sh_d[i, 0] = wx
        sh_d[i, 1] = wy
        sh_d[i, 2] = wz
        sh_t[i] = min(tf, fmax)
        need[i] = True


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
    closures' COLOR (None: albedo over the material's diffuse weight, 1 where it has none); diffuse_on (N,) float64, 1 where the
    diffuse part's direct light counts here (None: everywhere); mis (N,) bool, the path
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
    contrib = np.empty((n, 3))
    sh_o = np.empty((n, 3), np.float32)
    sh_d = np.empty((n, 3), np.float32)
    sh_t = np.empty(n, np.float32)
    need = np.empty(n, bool)
    idx = np.empty(n, np.int64)
    pk_o, pk_d, pk_t = np.empty_like(sh_o), np.empty_like(sh_d), np.empty_like(sh_t)
    sources = [(SOURCE_LIGHT, i) for i in range(ls.count) if ls.emits(i)]
    if tris.count:
        sources.append((SOURCE_TRIANGLES, ls.count))
    if np.any(ctx.world > 0):
        sources.append((SOURCE_WORLD, -1))
    for source, i in sources:
        q = ls.params[i] if source == SOURCE_LIGHT else ctx.no_light
        use_d = float(ls.visible_diffuse[i]) if source == SOURCE_LIGHT else 1.0
        use_g = float(ls.visible_glossy[i]) if source == SOURCE_LIGHT else 1.0
        shadows = bool(ls.cast_shadow[i]) if source == SOURCE_LIGHT else True
        dim = sampling.stream(sampling.LIGHT_SAMPLE, depth, i + 1)
        for k in range(k_count):
            t0 = time.perf_counter()
            _shade_kernel(source, q, tris.cdf, tris.probability, tris.v0, tris.e1, tris.e2,
                          tris.normal, tris.area, tris.radiance, ctx.world,
                          ctx.closures if hit.closures is None else hit.closures,
                          hit.position, hit.ng, hit.ns, tangent, hit.direction, front,
                          hit.material,
                          hit.eps,
                          hit.throughput, texel, diffuse_on, mis, lam, pixel, sample,
                          ctx.seed, dim, sampling.stream(sampling.LIGHT_PICK, depth, k),
                          k, k_count, bits, use_d, use_g,
                          ctx.extent, contrib, sh_o, sh_d, sh_t, need)
            if source == SOURCE_TRIANGLES and tris.textured is not None:
                _textured_triangles(ctx, tris, hit, pixel, sample, dim, depth, k, contrib)
            if ctx.medium is not None:  # the shadow segment's transmittance
                ctx.medium.attenuate(contrib, need, sh_o, sh_d, sh_t)
            t1 = time.perf_counter()
            c = _compact_kernel(need, sh_o, sh_d, sh_t, idx, pk_o, pk_d, pk_t) if shadows else 0
            occ = np.zeros(0, bool)
            if c and ctx.surfaces.cutout:
                # Shadows through cut-outs: the light times the product of (1 - opacity).
                trans = ctx.surfaces.transmittance(ctx.accel, ctx.tri_vertices, ctx.tri_normals,
                                                   ctx.extent, pk_o[:c], pk_d[:c], pk_t[:c])
                contrib[idx[:c]] *= trans[:, None]
                occ = trans <= 0.0
                ctx.stats["rays_shadow"] += c
            elif c:
                occ = ctx.accel.occluded(pk_o[:c], pk_d[:c], pk_t[:c])
                ctx.stats["rays_shadow"] += c
            t2 = time.perf_counter()
            _gather_kernel(target, hit.rows, contrib, idx[:c], occ)
            ctx.stats["time_shading"] += t1 - t0 + time.perf_counter() - t2
            ctx.stats["time_shadow"] += t2 - t1
