"""The second pass's photon terms: caustics, final gathering and the preview estimate.

At a diffuse hit x (a material with a diffuse lobe) seen with path throughput T:
- caustics:  T * rho_x / pi * E_c(x), E_c from the caustic map (k = caustic_k);
- indirect, final gather: T * rho_x * mean_j L(y_j), over ``gather_rays`` directions
  w_j cosine-distributed about the shading normal at x (pdf cos / pi cancels the
  cosine and the pi of rho / pi). y_j is the first diffuse hit along w_j, reached
  through mirrors and glass if need be (so L D S D paths are kept), and through rough
  glossy materials without a diffuse lobe (a rough metal: ``prepared.sampled_only``) by one
  BSDF sample each (``camera_paths.follow_bsdf``, weight f |cos| / pdf), and
  L(y_j) = rho_y / pi * E_g(y_j) from the global map built WITH direct photons. Light
  sources, emission and background seen by gather rays count nothing: the direct and
  caustics terms hold them; the media's emission along gather rays counts (no shadow ray
  samples an emissive medium);
- indirect, preview: T * rho_x / pi * E_g(x) from the global map built WITHOUT direct
  photons (the direct visualisation: fast, blotchy, labelled a preview).

Glossy (rough) lobes of the camera path's hits get direct light (and their own BSDF-sampled
continuation, core/integrators/photon_mapping.py). At a gather hit y_j whose material has a
rough glossy lobe besides its diffuse one (a Principled wall's specular layer and coat, a
Mix of Diffuse and Glossy: ``PreparedScene.glossy_on_diffuse``), the diffuse part is read as
above and the gather ray also goes on through one BSDF sample of the glossy part, as at a
rough metal (``camera_paths.follow_bsdf``: Russian roulette on the glossy share, so at a
default Principled wall about 1 ray in 20 goes on, with weight 1). The light the glossy
part reflects straight from the light sources is the caustic map's (light -> glossy ->
diffuse), as for a metal. Why not the diffuse-like shortcut (the global map's E / pi times
the glossy lobe's albedo toward x, exact only for uniform incident light): on
benchmarks/tradeoff.py's artist room it made the image 2.7 % too bright, 2.2 % of it from
the dark glossy floor (roughness 0.1) whose mirror-like reflection of the ceiling light it
spread over the walls (issue 13, docs/materials.md).
Photon terms at the camera's hits use the diffuse albedo, the textured one at each hit
(core/materials/textures.py). Gather rays pass cut-outs like camera rays.

Diffuse-like lobes that are not Lambert (``PhotonTerms.bsdf_materials``: Oren-Nayar,
sheen, translucent) are not rho / pi: there the terms evaluate the closure evaluator's
diffuse-like part f_d (``closure.parts_at``). Caustics and the preview estimate weight each
photon by f_d(wo, w_p), photons of both sides counting (``estimate.BsdfHits``); final
gathering weights each gather ray by f_d |cos| / pdf, the rays cosine-distributed on the
far side too with probability BACK_SHARE where a lobe transmits (Translucent); at gather
hits of such materials L(y_j) is the BSDF estimate toward x (the radiance cache, which
holds E / pi for Lambert lobes, is not read there).

Radiance estimates: core/photons/estimate.py's ``radiance_estimate`` (the k nearest
photons within the maximum radius, front-side only, the filter, Jensen's flattened disc),
and its automatic radius ``auto_radius``.

Random numbers: gather directions are a scrambled Sobol set over the pixel's
samples x gather rays (``sampling.stratified2``, index sample * gather_rays + j), the
lobe choices at specular surfaces hashes of (seed, pixel, that index, bounce).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numba
import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from ..prepared import PreparedScene
from ..scene import geometry
from ..shading import light_path
from ..passes import consecutive_mean
from ..settings import RenderSettings
from . import camera_paths, volume
from ..media import regions
from ..materials import closure
from ..photons.estimate import BsdfHits, radiance_estimate, radiance_estimate_sides
from ..photons import encoding, kdtree
from ..photons.photon_map import PhotonMap, squared_radius


CACHE_FRACTION = 0.25
"""Most radiance-cache points per stored global photon (Christensen's precomputation)."""
CACHE_POINTS_PER_DISC = 12.0
"""Radiance-cache points per gather disc (area pi r^2 of the global radius): about r/2
apart, one k-nearest radius (the automatic radius is twice it, photons.estimate.auto_radius).
The cached estimate is smooth at that scale and a gather hit reads its nearest point, whose
offset averages out over a pixel's gather rays: 50 points (r/4 apart) cost 4x the k-NN
searches (40 % of a Preview render) for the same error (docs/core_renderer.md, "The radiance
cache's density"). With the automatic radius this is 3 / k of the stored photons (6 % at
k = 50)."""
CACHE_NEIGHBOURS = 2
"""Cache points examined per gather hit, each with its two sides (the nearest side with a
compatible normal is used)."""
CACHE_MIN_COS = 0.5
"""A cache entry serves a gather hit when their normals agree this well (cos)."""


# --- the radiance cache (Christensen 1999) -----------------------------------------------------

@dataclass
class RadianceCache:
    """Outgoing diffuse radiance precomputed at points on the diffuse surfaces.

    tree (C, 3) float32 metres, axis (C,) uint8, depth: the points' left-balanced kd-tree
    (core/photons/kdtree.py), heap order; normals (C, 2, 3) float64: the unit surface
    normal of each point's two sides (front, back = -front); radiance (C, 2, 3) float64:
    E / pi (W/(m^2 sr) per unit albedo) on that side. Both go through the photon map's
    encoding (core/photons/encoding.py: one flux scale for both sides), as when the cache
    was a PhotonMap of 2 C entries. The lookup multiplies by the gather hit's own albedo.
    Final gathering reads the nearest side with a compatible normal among the
    CACHE_NEIGHBOURS nearest points (one k-nearest search per hit instead of a k =
    global_k estimate, several times faster); a hit with none within the radius gets the
    full estimate.
    """

    tree: np.ndarray
    axis: np.ndarray
    depth: int
    normals: np.ndarray
    radiance: np.ndarray
    radius: float

    def __len__(self):
        return self.tree.shape[0]


@njit(cache=True, parallel=True, error_model="numpy")
def _cache_points_kernel(tri_v, cdf, u0, u1, u2, pos, nrm, tri, bu, bv):
    """Points uniform over the area of the triangles (cdf over their areas); bu, bv: their
    barycentrics (Embree's u, v: weights of corners 1 and 2)."""
    for i in prange(u0.shape[0]):
        t = sampling.pick(cdf, u0[i] * cdf[-1])
        b0, b1 = sampling.uniform_triangle(u1[i], u2[i])
        bu[i] = b0
        bv[i] = b1
        for c in range(3):
            v0 = tri_v[t, 0, c]
            pos[i, c] = v0 + b0 * (tri_v[t, 1, c] - v0) + b1 * (tri_v[t, 2, c] - v0)
        ax = tri_v[t, 1, 0] - tri_v[t, 0, 0]
        ay = tri_v[t, 1, 1] - tri_v[t, 0, 1]
        az = tri_v[t, 1, 2] - tri_v[t, 0, 2]
        bx = tri_v[t, 2, 0] - tri_v[t, 0, 0]
        by = tri_v[t, 2, 1] - tri_v[t, 0, 1]
        bz = tri_v[t, 2, 2] - tri_v[t, 0, 2]
        nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
        ln = math.sqrt(nx * nx + ny * ny + nz * nz)
        nrm[i, 0], nrm[i, 1], nrm[i, 2] = nx / ln, ny / ln, nz / ln
        tri[i] = t


def cache_point_count(stored: int, diffuse_area: float, radius: float) -> int:
    """Surface points of the radiance cache (each holds both sides): CACHE_POINTS_PER_DISC
    per gather disc of ``radius`` (metres) over ``diffuse_area`` (m^2), at most
    CACHE_FRACTION x ``stored`` global photons, at least 1."""
    per_disc = CACHE_POINTS_PER_DISC * diffuse_area / (math.pi * radius * radius) \
        if radius > 0.0 else math.inf
    return max(1, int(min(CACHE_FRACTION * stored, per_disc)))


def build_radiance_cache(terms: "PhotonTerms", prepared: PreparedScene,
                         settings: RenderSettings, should_stop=None) -> RadianceCache | None:
    """Precompute the global map's radiance at ``cache_point_count`` points spread
    uniformly over the diffuse surfaces (both sides of each). Deterministic: the points
    are counter hashes of (seed, point index). should_stop() -> True (asked between
    chunks of points) abandons the cache: returns None."""
    diffuse_tri = np.flatnonzero(prepared.has_diffuse[prepared.tri_material])
    if terms.global_map is None or diffuse_tri.size == 0:
        return None
    t0 = time.perf_counter()
    v = prepared.tri_vertices[diffuse_tri].astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    keep = area > 0
    v, tri_ids, area = v[keep], diffuse_tri[keep], area[keep]
    if v.shape[0] == 0:
        return None
    m = cache_point_count(len(terms.global_map), float(area.sum()), terms.global_radius)
    seed = settings.seed
    ids = np.arange(m, dtype=np.int64)
    zero = np.zeros(m, np.int64)
    u0, u1, u2 = (sampling.uniform(seed, ids, zero, sampling.stream(sampling.CACHE_SAMPLE, c))
                  for c in range(3))
    pos, nrm, tri = np.empty((m, 3)), np.empty((m, 3)), np.empty(m, np.int64)
    bu, bv = np.empty(m), np.empty(m)
    _cache_points_kernel(np.ascontiguousarray(v), np.cumsum(area), u0, u1, u2, pos, nrm, tri,
                         bu, bv)
    # The cache holds E / pi (albedo 1): the lookup multiplies by the hit's own albedo
    # (a texel or a shader program's per-hit colour), so the cache neither blurs a texture
    # nor reads a material's constant colour where a program sets it per hit.
    albedo = np.ones((m, 3))
    # One neighbour search per point serves both of its sides.
    sides = radiance_estimate_sides(terms.global_map, pos, [nrm, -nrm], albedo,
                                    terms.global_k, terms.global_radius, terms.filter,
                                    should_stop=should_stop)
    if sides is None:
        return None
    front, back = sides
    # One tree over the m points (each side's entry shares its point's position): half
    # the points, half the neighbours searched per lookup.
    tree, source, axis = kdtree.balance(pos)
    scale = encoding.flux_scale(np.concatenate([front, back]))
    radiance = np.stack([encoding.decode_flux(encoding.encode_flux(f[source], scale), scale)
                         for f in (front, back)], axis=1).astype(np.float64)
    normals = np.stack([encoding.decode_direction(encoding.encode_direction(v[source]))
                        for v in (nrm, -nrm)], axis=1).astype(np.float64)
    cache = RadianceCache(tree, axis, kdtree.tree_depth(m), normals, radiance,
                          terms.global_radius)
    terms.stats["cache_points"] = 2 * m
    terms.stats["time_cache"] = time.perf_counter() - t0
    return cache


@njit(cache=True, parallel=True, error_model="numpy")
def _cached_times_albedo_kernel(entries, pick, albedo, out):
    """out[i] = entries[pick[i]] * albedo[i] (0 where pick[i] < 0): one pass instead of
    numpy's mask, gather and product temporaries."""
    for i in prange(pick.shape[0]):
        p = pick[i]
        for c in range(3):
            out[i, c] = entries[p, c] * albedo[i, c] if p >= 0 else 0.0


def cached_radiance(terms: "PhotonTerms", points, normals, albedo) -> np.ndarray:
    """(M, 3) float64 radiance albedo / pi * E (W/(m^2 sr)) at M Lambert hits: the cached
    E / pi times ``albedo`` (M, 3), the hits' own (textured, programmed) diffuse albedo;
    the full estimate where no cache entry with a compatible normal lies within the
    radius. points, normals (M, 3) metres / non-zero geometric normals facing the viewer."""
    cache = terms.cache
    m = points.shape[0]
    q = np.ascontiguousarray(points, np.float32)
    k = min(CACHE_NEIGHBOURS, len(cache))
    pick = np.empty(m, np.int64)
    # The order outside the chunk-size-1 block: its Morton kernel's prange would otherwise
    # be split into one task per query (measured 5x slower, ~15 % of a camera pass).
    order = kdtree.query_order(q)
    with numba.parallel_chunksize(1):
        kdtree.nearest_compatible_kernel(
            cache.tree, cache.axis, cache.depth, q, np.ascontiguousarray(normals, np.float64),
            order, k, squared_radius(cache.radius), kdtree.search_growth(k),
            cache.normals, CACHE_MIN_COS, pick)
    out = np.empty((m, 3))
    _cached_times_albedo_kernel(cache.radiance.reshape(-1, 3), pick,
                                np.ascontiguousarray(albedo, np.float64), out)
    missing = np.flatnonzero(pick < 0)
    if missing.size:
        out[missing] = radiance_estimate(terms.global_map, points[missing], normals[missing],
                                         albedo[missing], terms.global_k, terms.global_radius,
                                         terms.filter)
        terms.stats["cache_misses"] = terms.stats.get("cache_misses", 0) + int(missing.size)
    return out


# --- the terms at a set of diffuse hits ----------------------------------------------------

@dataclass
class PhotonTerms:
    """What the camera pass needs to add caustics and indirect light at diffuse hits.

    caustic_map / global_map: PhotonMap or None (term skipped); radii in metres (already
    resolved from 0 = automatic); mode: "final_gather", "preview" or "off";
    gather_rays: final-gather rays per camera sample. volume_map / volume_caustic_map:
    the volume photons (core/photons/beam.VolumePhotonMap) of a scene with a medium, read
    by core/integrators/volume.py; volume_gather_map (every collision) and medium (the
    core/media/regions.Medium), read by the final-gather rays; None without.
    """

    caustic_map: PhotonMap | None
    global_map: PhotonMap | None
    caustic_k: int
    global_k: int
    caustic_radius: float
    global_radius: float
    filter: str
    mode: str
    gather_rays: int
    cache: RadianceCache | None = None
    bsdf_materials: np.ndarray | None = None  # (M,) bool diffuse-like lobes not Lambert
    back_share: np.ndarray | None = None      # (M,) float64 gather rays on the far side
    volume_map: object = None
    volume_caustic_map: object = None
    volume_gather_map: object = None
    medium: object = None                     # core/media/regions.Medium or None
    stats: dict = field(default_factory=lambda: {"rays_gather": 0, "gather_queries": 0,
                                                 "caustic_queries": 0, "time_gather": 0.0,
                                                 "time_caustics": 0.0})

    @property
    def active(self) -> bool:
        return self.caustic_map is not None or (self.global_map is not None
                                                and self.mode != "off")


@njit(cache=True, inline="always")
def _gather_ray(o, d, r, pos, ngf, i, e, wx, wy, wz):
    """Gather ray r: from point i offset by e along its geometric normal, along w."""
    o[r, 0] = pos[i, 0] + e * ngf[i, 0]
    o[r, 1] = pos[i, 1] + e * ngf[i, 1]
    o[r, 2] = pos[i, 2] + e * ngf[i, 2]
    d[r, 0] = wx
    d[r, 1] = wy
    d[r, 2] = wz


@njit(cache=True, parallel=True, error_model="numpy")
def _gather_rays_kernel(pos, ngf, nsf, eps, owner, u1, u2, o, d, ok):
    """Cosine-distributed directions about the shading normal of point owner[r]; rays
    below the geometric surface are dropped (ok False)."""
    for r in prange(owner.shape[0]):
        i = owner[r]
        lx, ly, lz = sampling.cosine_hemisphere(u1[r], u2[r])
        wx, wy, wz = sampling.to_world(lx, ly, lz, nsf[i, 0], nsf[i, 1], nsf[i, 2])
        ok[r] = wx * ngf[i, 0] + wy * ngf[i, 1] + wz * ngf[i, 2] > 0.0
        _gather_ray(o, d, r, pos, ngf, i, eps[i], wx, wy, wz)


BACK_SHARE = 0.5
"""Share of a point's gather rays sent to the far side where a diffuse-like lobe transmits."""


def bsdf_terms(terms: PhotonTerms, closures, rows, mat, closure_rows, texel, d, nsf, front,
               tangent=None, lam=None):
    """Split the diffuse hits ``rows`` (indices into mat (N,) their materials, closure_rows
    (N,) int32 their rows of ``closures`` (``HitShader.closures_at``), texel (N, 3), d (N, 3)
    the arriving directions, nsf (N, 3), front (N,), tangent (N, 3) or None, as
    ``BsdfHits.tangent``, lam (N,) float64 the paths' wavelengths in nm or None, as
    ``BsdfHits.wavelength``) into those with Lambert diffuse lobes
    (the albedo path) and the others: (lambert rows, BSDF rows, BsdfHits of the BSDF rows
    or None when there are none)."""
    if terms.bsdf_materials is None:
        return rows, rows[:0], None
    b = terms.bsdf_materials[mat[rows]]
    if not b.any():
        return rows, rows[:0], None
    br = rows[b]
    hits = BsdfHits(closures, closure_rows[br].astype(np.int32), texel[br], -d[br], nsf[br],
                    front[br], terms.back_share[mat[br]],
                    None if tangent is None else tangent[br], None if lam is None else lam[br])
    return rows[~b], br, hits


def caustics(terms: PhotonTerms, pos, ngf, albedo, bsdf: BsdfHits | None = None) -> np.ndarray:
    """(N, 3) caustic radiance at diffuse hits (before the path throughput); with ``bsdf``
    the BSDF estimate (albedo not read)."""
    t0 = time.perf_counter()
    out = radiance_estimate(terms.caustic_map, pos, ngf, albedo, terms.caustic_k,
                            terms.caustic_radius, terms.filter, bsdf=bsdf)
    terms.stats["caustic_queries"] += pos.shape[0]
    terms.stats["time_caustics"] += time.perf_counter() - t0
    return out


def preview(terms: PhotonTerms, pos, ngf, albedo, bsdf: BsdfHits | None = None) -> np.ndarray:
    """(N, 3) indirect radiance seen directly in the global map (the preview mode); with
    ``bsdf`` the BSDF estimate (albedo not read)."""
    t0 = time.perf_counter()
    out = radiance_estimate(terms.global_map, pos, ngf, albedo, terms.global_k,
                            terms.global_radius, terms.filter, bsdf=bsdf)
    terms.stats["gather_queries"] += pos.shape[0]
    terms.stats["time_gather"] += time.perf_counter() - t0
    return out


@njit(cache=True, parallel=True, error_model="numpy")
def _bsdf_gather_rays_kernel(tab, mat, texel, wo, tan, front, lam, pos, ngf, nsf, eps, back, g,
                             u1, u2, o, d, weight, ok):
    """g gather rays per point i (rays i g .. i g + g - 1), cosine-distributed about the
    shading normal, about its opposite with probability back[i]; weight (RGB) f_d |cos| /
    pdf of the diffuse-like lobes (``closure.parts_at``, the closures built at wavelength
    lam[i] nm, 0: RGB); ok False where it is 0 or the ray's geometric side disagrees with
    its hemisphere."""
    for i in prange(pos.shape[0]):
        L, F = closure.hit_lobes(tab, mat[i], texel[i, 0], texel[i, 1], texel[i, 2],
                                 wo[i, 0], wo[i, 1], wo[i, 2], nsf[i, 0], nsf[i, 1], nsf[i, 2],
                                 ngf[i, 0], ngf[i, 1], ngf[i, 2], tan[i, 0], tan[i, 1],
                                 tan[i, 2], front[i], lam[i])
        pb = back[i]
        for j in range(g):
            r = i * g + j
            a = u1[r]
            side = 1.0
            if a < pb:
                side, a, share = -1.0, a / pb, pb
            else:
                a, share = (a - pb) / (1.0 - pb), 1.0 - pb
            lx, ly, lz = sampling.cosine_hemisphere(min(a, 1.0 - 1e-12), u2[r])
            wx, wy, wz = sampling.to_world(lx, ly, lz, side * nsf[i, 0], side * nsf[i, 1],
                                           side * nsf[i, 2])
            f0, f1, f2, _, _, _, _ = closure.parts_at(L, F, wx, wy, wz, ngf[i, 0], ngf[i, 1],
                                                      ngf[i, 2], True, True)
            pdf = share * lz / np.pi
            below = wx * ngf[i, 0] + wy * ngf[i, 1] + wz * ngf[i, 2] < 0.0
            ok[r] = below == (side < 0.0) and pdf > 0.0 and (f0 > 0.0 or f1 > 0.0 or f2 > 0.0)
            if ok[r]:
                weight[r, 0], weight[r, 1], weight[r, 2] = f0 / pdf, f1 / pdf, f2 / pdf
            else:
                weight[r, 0], weight[r, 1], weight[r, 2] = 0.0, 0.0, 0.0
            _gather_ray(o, d, r, pos, ngf, i, side * eps[i], wx, wy, wz)


GATHER_BATCH = 1 << 20
"""Gather rays traced together at most (bounds memory whatever the tile and ray counts)."""


def final_gather(terms: PhotonTerms, prepared: PreparedScene, settings: RenderSettings, pos,
                 ngf, nsf, eps, pixel, sample, depth, bsdf: BsdfHits | None = None,
                 lam=None) -> np.ndarray:
    """(N, 3) mean radiance L(y_j) over the gather rays of each diffuse hit (module doc).

    settings: seed, samples, max_specular_depth. pos, ngf, nsf (N, 3) float64, eps (N,),
    pixel and sample (N,) int64 of the
    camera sample, depth: the camera path's bounce (a random stream index).
    The caller multiplies by rho_x and the path throughput; with ``bsdf`` (the hits'
    BsdfHits) the mean is of f_d |cos| / pdf L(y_j) and the caller multiplies by the
    throughput only. lam (N,) float64: the camera paths' wavelengths in nm (0: RGB; None:
    all RGB), which their gather rays keep (docs/dispersion.md: a path stays at its
    wavelength once picked; a gather ray from an RGB path picks its own at its first
    dispersive surface). Points are gathered in batches of GATHER_BATCH rays; each
    point's value depends on its own rays only.
    """
    n = pos.shape[0]
    step = max(1, GATHER_BATCH // terms.gather_rays)
    if n <= step:
        return _final_gather_batch(terms, prepared, settings, pos, ngf, nsf, eps, pixel, sample,
                                   depth, bsdf, lam)
    out = np.empty((n, 3))
    for lo in range(0, n, step):
        sl = slice(lo, min(n, lo + step))
        out[sl] = _final_gather_batch(terms, prepared, settings, pos[sl], ngf[sl], nsf[sl],
                                      eps[sl], pixel[sl], sample[sl], depth,
                                      None if bsdf is None else bsdf.take(sl),
                                      None if lam is None else lam[sl])
    return out


def _through_medium(terms: PhotonTerms, prepared: PreparedScene, o, d, hits, thr, radiance,
                    rows) -> np.ndarray:
    """Final-gather segments through the scene's media: radiance[rows] += thr x the beam
    estimate of every volume photon along their homogeneous stretches (single scattering
    included, as the global map of final gathering holds direct photons) and the media's
    emission along them; returns thr x their transmittance. thr (M, 3) or None (all 1)."""
    seg = np.where(hits.prim >= 0, hits.t.astype(np.float64), np.inf)
    st = terms.medium.stretches(o, d, seg, volume.surface_bounds(prepared, hits.prim, d))
    vmap = terms.volume_gather_map
    scat = np.flatnonzero(np.any(st.sigma_s > 0, axis=1))
    if vmap is not None and len(vmap) and scat.size:
        ray = st.ray[scat]
        s_o = np.asarray(o, np.float64)[ray] + st.t0[scat, None] * np.asarray(d, np.float64)[ray]
        est = volume.beam_estimate(vmap, s_o, np.asarray(d, np.float64)[ray], st.length[scat],
                                   st.sigma_t[scat], st.g[scat], volume.stretch_bounds(st)[scat])
        np.add.at(radiance, rows[ray], _times(thr, ray, st.before[scat]) * est)
    if terms.medium.emits:
        # No shadow ray samples an emissive medium: its direct light at the gathering
        # point is what the gather rays see of it (the global map holds the rest).
        glow = np.flatnonzero(np.any(st.emission > 0, axis=1))
        ray = st.ray[glow]
        np.add.at(radiance, rows[ray], _times(thr, ray, st.before[glow]) * regions.emitted(
            st.emission[glow], st.sigma_t[glow], st.length[glow]))
    return _times(thr, None, st.through)


def _follow_rough(prepared, seed, depth, bounce, ray_pixel, index, rs, hits, hs, pos, ngf, nsf, d,
                  front, mat, eps, thr, lam, tab, crow):
    """Gather rays rs (K,) at hits hs (K,) of rough glossy materials (``prepared.sampled_only``,
    ``prepared.glossy_on_diffuse``): one lobe of the hit's shaded closures sampled each
    (``camera_paths.follow_bsdf``: the glossy part of f |cos| / pdf, the diffuse part being
    the estimate read there).
    Lights, emission and the world the rays then meet count nothing, as for gather rays
    after a mirror: the caustic map holds light reaching x through glossy lobes.
    Random numbers: dimensions 2 x and 2 x + 1 of x = (GATHER_LOBE, depth, bounce) for
    the lobe and the direction (as at mirrors), (GATHER_LOBE, depth, bounce, 1) and (.., 2)
    for the direction's second coordinate and the roulette.
    tab, crow (K,): the hits' shaded closures (``shade_hits``; nsf their shading normals
    as the programs bent them).
    Returns (rows (J,), origins (J, 3), directions (J, 3), throughput (J, 3), lam (J,))."""
    pix, idx = ray_pixel[rs], index[rs]
    dim = sampling.stream(sampling.GATHER_LOBE, depth, bounce)
    u_lobe = sampling.uniform(seed, pix, idx, 2 * dim)
    u1 = sampling.uniform(seed, pix, idx, 2 * dim + 1)
    u2 = sampling.uniform(seed, pix, idx, sampling.stream(sampling.GATHER_LOBE, depth, bounce, 1))
    u_rr = sampling.uniform(seed, pix, idx, sampling.stream(sampling.GATHER_LOBE, depth, bounce, 2))
    prim, u, v = hits.prim[hs], hits.u[hs], hits.v[hs]
    texel = prepared.texels.albedo(prim, u, v, mat)
    tangent = prepared.hit_shader.tangents(prim, pos, tab, crow)
    keep, o, d2, thr2, _, _, _, lam2 = camera_paths.follow_bsdf(
        prepared, np.ascontiguousarray(pos, np.float64), np.ascontiguousarray(ngf, np.float64),
        np.ascontiguousarray(nsf, np.float64), np.ascontiguousarray(d, np.float64),
        np.ascontiguousarray(front, np.bool_), np.ascontiguousarray(crow, np.int32),
        np.ascontiguousarray(eps, np.float64), np.ascontiguousarray(texel, np.float64),
        np.ascontiguousarray(thr, np.float64), np.ascontiguousarray(lam, np.float64),
        u_lobe, u1, u2, u_rr, closures=tab, tangent=tangent)
    return rs[keep], o, d2, thr2, lam2


def shade_hits(prepared, prim, u, v, d, mat, ns, path, need):
    """``HitShader.shade`` at the N hits (prim, u, v, d, mat, ns, path as it takes them)
    where ``need`` (N,) bool asks: (tab, rows (N,) int32, ns (N, 3)), rows the hits'
    rows of tab (their material where not needed or not programmed) and ns with the
    programs' normals in place. ``mat`` and ``ns`` themselves (the same objects, and the
    prepared table) when no needed hit is programmed: bit for bit as without programs."""
    shader = prepared.hit_shader
    sel = np.flatnonzero(need & shader.programmed[mat]) if shader.active else ()
    if len(sel) == 0:
        return prepared.closures, mat, ns
    given = ns[sel]
    tab, r, bent = shader.shade(prim[sel], u[sel], v[sel], d[sel], mat[sel], given,
                                None if path is None else path[sel])
    rows = np.array(mat, np.int32, copy=True)
    rows[sel] = r
    if bent is not given:
        ns = np.array(ns, copy=True)
        ns[sel] = bent
    return tab, rows, ns


def _take(a, idx):
    """a[idx] for selections that may be None, meaning "every row, in order": a itself when
    idx is None, idx when a is None (then the identity). Final gathering's batch is used
    as it is when every gather ray is kept, hits and is diffuse (the common case: a closed
    scene without specular surfaces), without index copies of the rays, hits and points
    (~5 % of the camera pass)."""
    if idx is None:
        return a
    return idx if a is None else a[idx]


def _times(thr, idx, x):
    """_take(thr, idx) * x, x itself when thr is None: final gathering's throughput (M, 3)
    while it is all 1 (1 * x is x bit for bit; no (M, 3) product on the common path)."""
    return x if thr is None else _take(thr, idx) * x


def _final_gather_batch(terms, prepared, settings, pos, ngf, nsf, eps, pixel, sample,
                        depth, bsdf=None, lam=None) -> np.ndarray:
    t_start = time.perf_counter()
    st = settings
    n = pos.shape[0]
    g = terms.gather_rays
    owner = np.repeat(np.arange(n, dtype=np.int64), g)
    index = np.repeat(sample.astype(np.int64) * g, g) + np.tile(np.arange(g, dtype=np.int64), n)
    ray_pixel = np.repeat(pixel.astype(np.int64), g)
    u1, u2 = sampling.stratified2(st.seed, ray_pixel, index, st.samples * g,
                                  sampling.stream(sampling.GATHER_DIRECTION, depth))
    index_of = index
    m = owner.shape[0]
    o, d, ok = np.empty((m, 3)), np.empty((m, 3)), np.empty(m, bool)
    if bsdf is None:
        _gather_rays_kernel(pos, ngf, nsf, eps, owner, u1, u2, o, d, ok)
    else:
        weight = np.empty((m, 3))
        back = bsdf.back_share
        _bsdf_gather_rays_kernel(bsdf.closures, bsdf.material, np.ascontiguousarray(bsdf.texel),
                                 np.ascontiguousarray(bsdf.outgoing), bsdf.tangents(),
                                 bsdf.front, bsdf.wavelengths(), pos, ngf, nsf,
                                 eps, back, g, u1, u2, o, d, weight, ok)
    radiance = np.zeros((m, 3))
    every_ray = np.arange(m)
    # rows: the batch's rays still traced (None: all, in order), hit: the rays of this
    # bounce that hit (None: all), diff: the hits with a diffuse lobe (None: all).
    rows = None if ok.all() else np.flatnonzero(ok)
    o, d = _take(o, rows), _take(d, rows)
    live = o.shape[0]
    thr = None if bsdf is None else _take(weight, rows)  # None: all 1 (_times)
    mats = prepared.materials
    # Each gather ray's wavelength (nm, 0 while RGB): its camera path's, else picked at its
    # first dispersive surface, as camera paths pick theirs (docs/dispersion.md).
    lam = np.zeros(live) if lam is None else np.asarray(lam, np.float64)[_take(owner, rows)]
    dispersive = bool(np.any(prepared.closures.abbe > 0))
    for bounce in range(st.max_specular_depth + 1):
        if o.shape[0] == 0:
            break
        ray_ids = _take(every_ray, rows)  # the traced rays' indices into the batch
        hits = camera_paths.intersect(
            prepared, st.seed, o, d, None, ray_ids, ray_pixel, index_of,
            lambda layer, bounce=bounce: sampling.stream(sampling.GATHER_CUTOUT, depth, bounce,
                                                         layer))
        terms.stats["rays_gather"] += o.shape[0]
        if terms.medium is not None:
            thr = _through_medium(terms, prepared, o, d, hits, thr, radiance, ray_ids)
        # Escaping rays and light sources count nothing (direct light holds them).
        hit = None if np.all(hits.prim >= 0) else np.flatnonzero(hits.prim >= 0)
        rows, d, lam = _take(rows, hit), _take(d, hit), _take(lam, hit)
        if thr is not None:
            thr = _take(thr, hit)
        prim, hu, hv = _take(hits.prim, hit), _take(hits.u, hit), _take(hits.v, hit)
        path = None
        if prepared.hit_shader.reads_light_path:  # a diffuse reflection from the camera
            # path's vertex at depth, then the delta bounces of this loop (follow_delta)
            path = light_path.after_bounce(
                _take(hits.t, hit), light_path.BOUNCE_DIFFUSE if bounce == 0 else
                light_path.BOUNCE_SINGULAR, False, depth + 1 + bounce, diffuse_depth=1,
                glossy_depth=depth + bounce)
        p2, n2, s2, mat, e2, front = geometry.facing_surface_points(
            prepared.tri_vertices, prepared.tri_normals, prepared.tri_material, prim,
            hu, hv, d, prepared.extent)
        if dispersive:  # before the hit's estimate, as camera_paths.pick_wavelengths says
            u_lam = sampling.uniform(st.seed, _take(ray_pixel, rows), _take(index, rows),
                                     sampling.stream(sampling.CAMERA_WAVELENGTH, depth, bounce,
                                                     sampling.GATHER_LOBE))
            thr = np.ones((mat.shape[0], 3)) if thr is None else np.array(thr)
            camera_paths.pick_wavelengths(prepared.closures, mat, u_lam, lam, thr)
        diffuse = prepared.has_diffuse[mat]
        diff = None if diffuse.all() else np.flatnonzero(diffuse)
        rough = prepared.sampled_only[mat] | prepared.glossy_on_diffuse[mat]
        # One shading per hit (issue 14: a Principled wall's hit was shaded for its
        # albedo, then again for its glossy continuation), read by the BSDF estimate,
        # the diffuse albedo and the rough continuation below.
        tab, crow, s2s = shade_hits(prepared, prim, hu, hv, d,
                                    mat, s2, path, prepared.has_diffuse[mat] | rough)
        md = _take(mat, diff)
        if terms.bsdf_materials is not None and md.size:
            b = terms.bsdf_materials[md]
            if b.any():  # L(y_j) toward x by the BSDF estimate (the cache holds Lambert's E / pi)
                which = _take(np.arange(mat.shape[0]), diff)
                bd, diff = which[b], which[~b]
                hd = _take(hit, bd)
                texel = prepared.texels.albedo(hits.prim[hd], hits.u[hd], hits.v[hd], mat[bd])
                tan = prepared.hit_shader.tangents(hits.prim[hd], p2[bd], tab, crow[bd])
                hb = BsdfHits(tab, crow[bd].astype(np.int32), texel, -d[bd], s2s[bd],
                              front[bd], tangent=tan, wavelength=lam[bd])
                est = radiance_estimate(terms.global_map, p2[bd], n2[bd], None, terms.global_k,
                                        terms.global_radius, terms.filter, bsdf=hb)
                radiance[_take(rows, bd)] += _times(thr, bd, est)
                terms.stats["gather_queries"] += bd.size
                md = _take(mat, diff)
        if md.size:
            hd = _take(hit, diff)
            if prepared.surfaces.textured:
                albedo = prepared.surfaces.albedo(_take(hits.prim, hd), _take(hits.u, hd),
                                                  _take(hits.v, hd), md)
            else:
                albedo = mats["diffuse"][md]
            if crow is not mat or prepared.hit_shader.layered[md].any():
                albedo = prepared.hit_shader.diffuse_albedo(
                    tab, _take(crow, diff), md,
                    prepared.texels.albedo(_take(hits.prim, hd), _take(hits.u, hd),
                                           _take(hits.v, hd), md),
                    _take(d, diff), _take(s2, diff), albedo)
            p2d, n2d = _take(p2, diff), _take(n2, diff)
            if terms.cache is not None:
                est = cached_radiance(terms, p2d, n2d, albedo)
            else:
                est = radiance_estimate(terms.global_map, p2d, n2d,
                                        albedo, terms.global_k,
                                        terms.global_radius, terms.filter)
            est = _times(thr, diff, est)
            target = _take(rows, diff)
            if target is None:
                radiance += est
            else:
                radiance[target] += est
            terms.stats["gather_queries"] += md.size
        if bounce == st.max_specular_depth:
            break
        # Mirrors and glass: one delta lobe (follow_delta). Rough glossy lobes (a rough
        # metal; a Principled wall's specular layer over its diffuse base, whose estimate
        # above is the diffuse part only): the ray goes on through one BSDF sample of the
        # glossy part (follow_bsdf, as camera paths do; Russian roulette on the glossy
        # share) to the next diffuse hit.
        sd = np.flatnonzero(prepared.has_delta[mat] & ~rough)
        sr = np.flatnonzero(rough)
        if sd.size == 0 and sr.size == 0:
            break
        if thr is None:
            thr = np.ones((mat.shape[0], 3))
        dim = sampling.stream(sampling.GATHER_LOBE, depth, bounce)
        go = []
        if sd.size:
            rs = _take(rows, sd)
            u_lobe = sampling.uniform(st.seed, ray_pixel[rs], index[rs], 2 * dim)
            u_pick = sampling.uniform(st.seed, ray_pixel[rs], index[rs], 2 * dim + 1)
            hs = _take(hit, sd)
            texel = prepared.texels.albedo(hits.prim[hs], hits.u[hs], hits.v[hs], mat[sd])
            tangent = prepared.hit_shader.tangents(hits.prim[hs], p2[sd], prepared.closures,
                                                   mat[sd])
            keep, o_s, d_s, thr_s, _, lam_s = camera_paths.follow_delta(
                prepared, p2[sd], n2[sd], s2[sd], d[sd], front[sd], mat[sd], e2[sd], texel,
                u_lobe, u_pick, thr[sd], lam[sd], tangent=tangent)
            go.append((rs[keep], o_s, d_s, thr_s, lam_s))
        if sr.size:
            go.append(_follow_rough(prepared, st.seed, depth, bounce, ray_pixel, index,
                                    _take(rows, sr), hits, _take(hit, sr), p2[sr], n2[sr],
                                    s2s[sr], d[sr], front[sr], mat[sr], e2[sr], thr[sr], lam[sr],
                                    tab, crow[sr]))
        if len(go) == 1:
            rows, o, d, thr, lam = go[0]
        else:
            rows, o, d, thr, lam = (np.concatenate(c) for c in zip(*go))
    terms.stats["time_gather"] += time.perf_counter() - t_start
    return consecutive_mean(radiance, g)
