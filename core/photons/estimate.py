"""Density estimation: irradiance and reflected radiance from the nearest photons.

At a surface point x with unit normal n, gather the k nearest photons within
``max_radius`` and divide their flux by the area of the disc they cover:

    E(x)      ~ sum_p w_p Phi_p / (pi r^2)                          W/m^2
    L_r(x, o) ~ sum_p f_r(x, w_p, o) w_p Phi_p / (pi r^2)           W/(m^2 sr)

Conventions (decided here, used by every caller):
- r is the distance to the k-th nearest photon; when fewer than k photons lie within
  ``max_radius`` the search covered the whole disc of radius ``max_radius``, so r is
  ``max_radius`` (with max_radius = inf and fewer than k photons the estimate is 0).
  Jensen's estimate: the k-th photon itself is counted.
- Only photons arriving from the front contribute: dot(direction_p, n) > 0, where a
  photon's direction points toward where it came from.
- Filters weight photons by their distance d to x; each is divided by its mean over the
  disc, so a uniform photon field gives the same answer with every filter:
    "none":     w = 1
    "cone":     w = (1 - d / (k_cone r)) / (1 - 2 / (3 k_cone)),  k_cone >= 1 (Jensen)
    "gaussian": w = a (1 - (1 - exp(-b d^2 / (2 r^2))) / (1 - exp(-b))) / mean, with
                Jensen's a = 0.918, b = 1.953. His a alone does not normalise the
                filter for a division by pi r^2 (the bracket's mean over the disc times a
                is 0.531), so the closed-form mean is divided out.
- ``max_plane_distance`` (Jensen's fix for light leaking through corners and thin
  walls): photons farther than max_plane_distance * r from the tangent plane at x are
  left out of the sum. The search itself stays spherical, so r and the area are
  unchanged.

One kernel estimates (``_estimate_kernel``): the renderer's caustics, final gathering,
radiance cache and preview call ``radiance_estimate`` / ``radiance_estimate_sides``, and
``irradiance`` is the same kernel with albedo pi. It searches each query's k nearest
(``kdtree.knn_search_coherent``, as ``PhotonMap.nearest`` does), sorts them by (distance,
index) and sums them in that order, so a query's value does not depend on the other queries
of its batch. No (M, k) neighbour arrays are written: memory stays O(k) per thread
whatever k (the settings allow k up to 10,000, where 65,536 queries' arrays took 7.9 GB),
at the same speed (the artist room's caustic estimate at k = 100: 1.95 s before, 1.94 s
fused). The BSDF estimate below gathers the same way. A BRDF callback (``radiance(brdf=...)``)
needs the gathered photons as arrays, so that path materialises (M, k) arrays.

The BSDF estimate (``radiance_estimate(..., bsdf=BsdfHits)``, ``_bsdf_estimate_kernel``):
where a material's diffuse-like lobes are not Lambert (Oren-Nayar, sheen, translucent;
``closure.lobe_masks``' ``non_lambert``) the reflected light is sum_p f_d(wo, w_p) w_p Phi_p
/ (pi r^2), f_d the diffuse-like lobes of the closure evaluator (``closure.parts_at``,
without the cosine, which the photon flux already holds) at each photon's direction, and
photons from BOTH sides count: f_d is 0 on the far side unless a lobe transmits
(Translucent). The Lambert case f_d = albedo / pi is the fused albedo path above.

Automatic radius (``auto_radius``, setting 0): the radius of a disc that holds k photons
on average when the stored photons cover the diffuse surfaces uniformly, times
RADIUS_FACTOR: r = RADIUS_FACTOR * sqrt(A_diffuse * k / (pi * N_stored)). It scales with
the scene (A ~ s^2, r ~ s), so a scene in millimetres or kilometres gives the same image.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..materials import closure
from . import encoding, kdtree
from .photon_map import PhotonMap, check_k, check_points, squared_radius

PLANE_FRACTION = 0.25
"""Flattened-disc gather: photons farther than this fraction of r from the tangent plane
at the query are left out (Jensen's fix for leaks through corners and thin walls)."""
RADIUS_FACTOR = 2.0
"""Automatic radius = this x the radius that holds k photons on average."""
CONE_K = 1.1
"""Jensen's cone filter constant k >= 1 (1.1 in his book)."""
QUERY_CHUNK = 1 << 16
"""Queries per kernel call of ``radiance_estimate_sides`` (should_stop is asked between)."""

FILTERS = {"none": 0, "cone": 1, "gaussian": 2}
GAUSS_ALPHA = 0.918
GAUSS_BETA = 1.953
_GAUSS_EDGE = 1.0 - math.exp(-GAUSS_BETA)
# Mean of Jensen's Gaussian over the unit disc: 2 * integral_0^1 w(s) s ds.
_GAUSS_MEAN = GAUSS_ALPHA * (
    1.0 - (1.0 - (2.0 / GAUSS_BETA) * (1.0 - math.exp(-GAUSS_BETA / 2.0))) / _GAUSS_EDGE)


@njit(cache=True, nogil=True, inline="always")
def photon_weight(direction_codes, tree, j, d2, r2, px, py, pz, nx, ny, nz,
                  kind, k_cone, plane_fraction):
    """Weight of photon j in the estimate at (p, n): filter / (pi r^2), or 0.

    d2, r2: squared distance of the photon and squared disc radius (m^2, float64); n unit.
    plane_fraction < 0 disables the tangent-plane test. Returns 1/m^2.
    """
    wx, wy, wz = encoding.oct_decode(direction_codes[j, 0], direction_codes[j, 1])
    if wx * nx + wy * ny + wz * nz <= 0.0:
        return 0.0
    if plane_fraction >= 0.0:
        h = (tree[j, 0] - px) * nx + (tree[j, 1] - py) * ny + (tree[j, 2] - pz) * nz
        if h * h > plane_fraction * plane_fraction * r2:
            return 0.0
    if kind == 0:
        w = 1.0
    elif kind == 1:
        w = (1.0 - math.sqrt(d2 / r2) / k_cone) / (1.0 - 2.0 / (3.0 * k_cone))
    else:
        w = GAUSS_ALPHA * (1.0 - (1.0 - math.exp(-GAUSS_BETA * d2 / (2.0 * r2)))
                           / _GAUSS_EDGE) / _GAUSS_MEAN
    return w / (math.pi * r2)


@njit(cache=True, nogil=True, inline="always")
def disc_radius2(count, k, farthest_d2, max_r2):
    """Squared disc radius: the k-th photon's when k were found, else max_radius^2."""
    return np.float64(farthest_d2) if count == k else np.float64(max_r2)


@njit(cache=True, nogil=True, inline="always")
def gathered_disc(idx, dist2, i, k, max_r2):
    """(count, r2) of query i's gathered photons (rows of PhotonMap.nearest's idx / dist2,
    -1 after the last): how many were found and the squared disc radius (0 for k photons
    exactly on the point; -1 when none were found)."""
    c = 0
    while c < k and idx[i, c] >= 0:
        c += 1
    if c == 0:
        return 0, -1.0
    return c, disc_radius2(c, k, dist2[i, c - 1], max_r2)


@njit(parallel=True, cache=True, nogil=True)
def _weights_kernel(tree, direction_codes, idx, dist2, points, normals, k, max_r2, kind,
                    k_cone, plane_fraction, out):
    """out[i, s] = weight (1/m^2) of gathered photon idx[i, s], 0 where idx is -1.
    Returns the number of zero-area discs holding photons."""
    degenerate = 0
    for i in prange(idx.shape[0]):
        c, r2 = gathered_disc(idx, dist2, i, k, max_r2)
        for s in range(k):
            out[i, s] = 0.0
        if c == 0:
            continue
        if r2 == 0.0:
            degenerate += 1
            continue
        n0 = np.float64(normals[i, 0])
        n1 = np.float64(normals[i, 1])
        n2 = np.float64(normals[i, 2])
        inv = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        for s in range(c):
            out[i, s] = photon_weight(direction_codes, tree, idx[i, s],
                                      np.float64(dist2[i, s]), r2, points[i, 0],
                                      points[i, 1], points[i, 2], n0 * inv, n1 * inv,
                                      n2 * inv, kind, k_cone, plane_fraction)
    return degenerate


def _check_options(photon_map, points, normals, k, max_radius, filter, k_cone,
                   max_plane_distance):
    if not isinstance(photon_map, PhotonMap):
        raise TypeError(f"photon_map must be a PhotonMap, got {type(photon_map).__name__}")
    points = check_points(points, "points")
    normals = check_points(normals, "normals")
    if normals.shape != points.shape:
        raise ValueError(f"normals must have the shape of points {points.shape}, "
                         f"got {normals.shape}")
    if normals.size and not (np.einsum("ij,ij->i", normals, normals) > 0).all():
        raise ValueError("normals must be non-zero vectors")
    k = check_k(k)
    if not float(max_radius) > 0.0:
        raise ValueError(f"max_radius must be > 0 metres (or inf), got {max_radius!r}")
    r2 = squared_radius(max_radius)
    if filter not in FILTERS:
        raise ValueError(f"filter must be one of {sorted(FILTERS)}, got {filter!r}")
    if not float(k_cone) >= 1.0 or not math.isfinite(float(k_cone)):
        raise ValueError(f"k_cone must be a finite number >= 1, got {k_cone!r}")
    if max_plane_distance is None:
        plane = -1.0
    else:
        plane = float(max_plane_distance)
        if not (plane >= 0.0 and math.isfinite(plane)):
            raise ValueError("max_plane_distance must be None or a finite fraction of the "
                             f"radius >= 0, got {max_plane_distance!r}")
    return points, normals, k, r2, FILTERS[filter], float(k_cone), plane


def _raise_degenerate(count):
    if count:
        raise ValueError(
            f"{count} points have k photons exactly on them (zero-area disc, infinite "
            "density): use a larger k")


def irradiance(photon_map: PhotonMap, points, normals, k: int, max_radius, *,
               filter: str = "none", k_cone: float = 1.0,
               max_plane_distance=None) -> np.ndarray:
    """Irradiance at surface points from the k nearest front-side photons.

    photon_map: PhotonMap. points (M, 3) float32 metres; normals (M, 3) non-zero (unit
    after normalisation); k >= 1; max_radius > 0 metres (inf allowed); filter "none",
    "cone" or "gaussian"; k_cone >= 1 (cone filter only); max_plane_distance: None or a
    fraction of r (see the module docstring).
    Returns (M, 3) float32, W/m^2: the renderer's own estimate (``_estimate_kernel``,
    which returns albedo / pi * E) with albedo pi.
    """
    points, normals, k, r2, kind, k_cone, plane = _check_options(
        photon_map, points, normals, k, max_radius, filter, k_cone, max_plane_distance)
    m = points.shape[0]
    out = np.zeros((m, 3), np.float64)
    if m == 0 or len(photon_map) == 0:
        return out.astype(np.float32)
    normals = np.ascontiguousarray(normals, np.float64)
    albedo = np.full((m, 3), math.pi)
    _raise_degenerate(_estimate(photon_map, points, normals[None], albedo, k, max_radius, kind,
                                k_cone, plane, out[None]))
    return out.astype(np.float32)


def radiance(photon_map: PhotonMap, points, normals, k: int, max_radius, *, albedo=None,
             brdf=None, outgoing=None, filter: str = "none", k_cone: float = 1.0,
             max_plane_distance=None) -> np.ndarray:
    """Reflected radiance at surface points from the k nearest front-side photons.

    Give exactly one of:
      albedo: (M, 3) diffuse albedo in [0, 1]: L = albedo / pi * E (the fused fast path);
      brdf: a callable ``brdf(incoming, outgoing) -> f_r`` with incoming (M, k, 3)
        float32 unit directions toward where the gathered photons came from (zero rows
        where fewer than k were found), outgoing (M, 3) float32 (the ``outgoing``
        argument, toward the viewer), returning f_r in 1/sr broadcastable to (M, k, 3),
        finite and >= 0.
    Other arguments as ``irradiance``. Returns (M, 3) float32, W/(m^2 sr).
    """
    if (albedo is None) == (brdf is None):
        raise ValueError("radiance needs exactly one of albedo= or brdf=")
    if albedo is not None:
        e = irradiance(photon_map, points, normals, k, max_radius, filter=filter,
                       k_cone=k_cone, max_plane_distance=max_plane_distance)
        albedo = np.asarray(albedo, dtype=np.float32)
        if albedo.shape != e.shape:
            raise ValueError(f"albedo must have shape {e.shape}, got {albedo.shape}")
        if not np.isfinite(albedo).all() or (albedo < 0).any():
            raise ValueError("albedo must be finite and >= 0")
        return (albedo * np.float32(1.0 / math.pi)) * e

    points, normals, k, r2, kind, k_cone, plane = _check_options(
        photon_map, points, normals, k, max_radius, filter, k_cone, max_plane_distance)
    outgoing = check_points(outgoing if outgoing is not None else np.zeros((0, 3)),
                             "outgoing")
    if outgoing.shape != points.shape:
        raise ValueError(f"outgoing must have the shape of points {points.shape} when "
                         f"brdf is given, got {outgoing.shape}")
    tree, _, _, flux_codes, scale, direction_codes = photon_map.kernel_arrays()
    idx, dist2 = photon_map.nearest(points, k, max_radius)
    weights = np.empty(idx.shape, np.float64)
    bad = _weights_kernel(tree, direction_codes, idx, dist2, points, normals, k, r2, kind,
                          k_cone, plane, weights)
    _raise_degenerate(bad)
    safe = np.where(idx >= 0, idx, 0)
    incoming = encoding.decode_direction(direction_codes[safe.ravel()]).reshape(idx.shape + (3,))
    incoming[idx < 0] = 0.0
    flux = encoding.decode_flux(flux_codes[safe.ravel()], scale).reshape(idx.shape + (3,))
    f_r = np.asarray(brdf(incoming, outgoing), dtype=np.float64)
    try:
        f_r = np.broadcast_to(f_r, idx.shape + (3,))
    except ValueError:
        raise ValueError(f"brdf must return values broadcastable to {idx.shape + (3,)}, "
                         f"got shape {f_r.shape}") from None
    if not np.isfinite(f_r).all() or (f_r < 0).any():
        raise ValueError("brdf must return finite values >= 0 (1/sr)")
    return np.einsum("mk,mkc->mc", weights, f_r * flux).astype(np.float32)


# --- the radius and the radiance estimate the renderer uses ------------------------------

def auto_radius(area: float, k: int, stored: int) -> float:
    """Maximum gather radius (metres) for ``stored`` photons spread over ``area`` m^2."""
    if stored <= 0 or area <= 0:
        return math.inf
    return RADIUS_FACTOR * math.sqrt(area * k / (math.pi * stored))


@njit(cache=True, nogil=True, inline="always")
def unit_row(v, i):
    """Row i of v (N, 3) normalised (float64); it must be non-zero."""
    n0, n1, n2 = v[i, 0], v[i, 1], v[i, 2]
    inv = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    return n0 * inv, n1 * inv, n2 * inv


@njit(cache=True, nogil=True, inline="always")
def _lambert_sum(tree, flux_codes, direction_codes, heap, c, r2, fbuf, ubuf, px, py, pz,
                 n0, n1, n2, kind, k_cone, plane_fraction):
    """(sum_p w_p Phi_p) in flux codes' units over the c sorted neighbours of heap (the
    gathered disc of squared radius r2 about p, unit normal n), summed in their order."""
    ex = 0.0
    ey = 0.0
    ez = 0.0
    for s in range(c):
        j, d2 = kdtree.heap_entry(heap, s, fbuf, ubuf)
        w = photon_weight(direction_codes, tree, j, np.float64(d2), r2, px, py, pz,
                          n0, n1, n2, kind, k_cone, plane_fraction)
        if w != 0.0:
            ex += w * encoding.half_to_float(flux_codes[j, 0])
            ey += w * encoding.half_to_float(flux_codes[j, 1])
            ez += w * encoding.half_to_float(flux_codes[j, 2])
    return ex, ey, ez


@njit(cache=True, nogil=True, inline="always")
def _gather_disc(tree, axis, depth, px, py, pz, k, max_r2, growth, heap, fbuf, ubuf, stack_i,
                 stack_f, prev):
    """The k nearest photons of p within max_r2 (``kdtree.knn_search_coherent``), sorted by
    (distance, index) in heap: (count, squared disc radius ``disc_radius2``; -1 when none
    were found, 0 for k photons exactly on p)."""
    c = kdtree.knn_search_coherent(tree, axis, depth, px, py, pz, k, max_r2, growth, heap,
                                   fbuf, ubuf, stack_i, stack_f, prev)
    if c == 0:
        return 0, -1.0
    kdtree.sort_heap(heap, c)
    _, far = kdtree.heap_entry(heap, c - 1, fbuf, ubuf)
    return c, disc_radius2(c, k, far, max_r2)


@njit(cache=True, parallel=True, error_model="numpy")
def _estimate_kernel(tree, axis, depth, flux_codes, inv_scale, direction_codes, points, order,
                     k, max_r2, growth, normals, albedo, kind, k_cone, plane_fraction, out):
    """out[s, i] = albedo[i] / pi * E(points[i]) on the side of normals[s, i]: the k
    nearest photons within max_r2 (``kdtree.knn_search_coherent``, queries visited in
    ``order``), sorted by (distance, index) and summed in that order, without (M, k)
    neighbour arrays. normals (S, M, 3) float64 non-zero; out (S, M, 3) float64.
    Returns the number of zero-area discs holding photons."""
    m = order.shape[0]
    blocks = (m + kdtree.QUERY_BLOCK - 1) // kdtree.QUERY_BLOCK
    degenerate = np.zeros(blocks, np.int64)  # per block: a scalar reduction trips numba
    for b in prange(blocks):
        heap, fbuf, ubuf, stack_i, stack_f, prev = kdtree.knn_scratch(k)
        bad = 0
        for t in range(b * kdtree.QUERY_BLOCK, min(m, (b + 1) * kdtree.QUERY_BLOCK)):
            i = order[t]
            px, py, pz = points[i, 0], points[i, 1], points[i, 2]
            c, r2 = _gather_disc(tree, axis, depth, px, py, pz, k, max_r2, growth, heap, fbuf,
                                 ubuf, stack_i, stack_f, prev)
            out[:, i, :] = 0.0
            if c == 0:
                continue
            if r2 == 0.0:
                bad += 1
                continue
            for side in range(normals.shape[0]):
                n0, n1, n2 = unit_row(normals[side], i)
                ex, ey, ez = _lambert_sum(tree, flux_codes, direction_codes, heap, c, r2,
                                          fbuf, ubuf, px, py, pz, n0, n1, n2, kind, k_cone,
                                          plane_fraction)
                s_ = inv_scale / math.pi
                out[side, i, 0] = albedo[i, 0] * ex * s_
                out[side, i, 1] = albedo[i, 1] * ey * s_
                out[side, i, 2] = albedo[i, 2] * ez * s_
        degenerate[b] = bad
    return degenerate.sum()


def _estimate(photon_map: PhotonMap, points, normals, albedo, k, max_radius, kind, k_cone,
              plane_fraction, out) -> int:
    """``_estimate_kernel`` over points (M, 3) float32, normals (S, M, 3) float64, albedo
    (M, 3) float64 into out (S, M, 3) float64; returns its count of zero-area discs."""
    tree, axis, depth, flux_codes, scale, direction_codes = photon_map.kernel_arrays()
    order = kdtree.query_order(points)
    with numba.parallel_chunksize(1):
        return _estimate_kernel(tree, axis, depth, flux_codes, 1.0 / scale, direction_codes,
                                points, order, k, squared_radius(max_radius),
                                kdtree.search_growth(k), normals, albedo, kind, k_cone,
                                plane_fraction, out)


class BsdfHits(NamedTuple):
    """The BSDF at the query points of a ``radiance_estimate(..., bsdf=)``.

    closures: the ClosureTable (core/materials/closure.py); material (M,) int32; texel
    (M, 3) float64 the texel colour multiplying the closures' COLOR (1 untextured);
    outgoing (M, 3) float64 unit, toward the viewer; shading_normal (M, 3) float64 unit;
    front (M,) bool, the viewer is on the front of the mesh's geometric normal.
    material is the row of ``closures`` (a shader program's hits have rows of their own past
    the materials', ``HitShader.closures_at``). back_share (M,) float64: the share of final
    gathering's rays sent to the far side (None where no final gathering starts there).
    tangent (M, 3) float64: the BSDF frame's tangent (``HitShader.tangents``; None:
    ``closure.DEFAULT_TANGENT``). wavelength (M,) float64: the camera paths' wavelengths in
    nm, 0 for an RGB path (docs/dispersion.md; None: all RGB), at which the closures'
    dispersive transmission lobes are built (``closure.hit_lobes``).
    """

    closures: closure.ClosureTable
    material: np.ndarray
    texel: np.ndarray
    outgoing: np.ndarray
    shading_normal: np.ndarray
    front: np.ndarray
    back_share: np.ndarray | None = None
    tangent: np.ndarray | None = None
    wavelength: np.ndarray | None = None

    def tangents(self) -> np.ndarray:
        """(M, 3) float64 C-contiguous: ``tangent``, or the default tangent where None."""
        if self.tangent is None:
            return closure.default_tangents(self.material.shape[0])
        return np.ascontiguousarray(self.tangent, np.float64)

    def wavelengths(self) -> np.ndarray:
        """(M,) float64 C-contiguous nm: ``wavelength``, or 0 (RGB) where None."""
        if self.wavelength is None:
            return np.zeros(self.material.shape[0])
        return np.ascontiguousarray(self.wavelength, np.float64)

    def take(self, rows) -> "BsdfHits":
        """The hits ``rows`` (an index array or slice)."""
        return BsdfHits(self.closures, self.material[rows], self.texel[rows],
                        self.outgoing[rows], self.shading_normal[rows], self.front[rows],
                        None if self.back_share is None else self.back_share[rows],
                        None if self.tangent is None else self.tangent[rows],
                        None if self.wavelength is None else self.wavelength[rows])


@njit(cache=True, parallel=True, error_model="numpy")
def _bsdf_estimate_kernel(tree, axis, depth, flux_codes, inv_scale, direction_codes, points,
                          order, k, max_r2, growth, normals, tab, mat, texel, wo, ns, tan,
                          front, lam, kind, k_cone, plane_fraction, out):
    """out[i] = sum_p f_d(wo_i, w_p) w_p Phi_p (W/(m^2 sr)) over the gathered photons of
    both sides of normals[i] (the geometric normal facing the viewer), gathered and summed
    as ``_estimate_kernel`` does, the closures built at wavelength lam[i] nm (0: RGB);
    returns the number of zero-area discs holding photons."""
    m = order.shape[0]
    blocks = (m + kdtree.QUERY_BLOCK - 1) // kdtree.QUERY_BLOCK
    degenerate = np.zeros(blocks, np.int64)
    for b in prange(blocks):
        heap, fbuf, ubuf, stack_i, stack_f, prev = kdtree.knn_scratch(k)
        bad = 0
        for t in range(b * kdtree.QUERY_BLOCK, min(m, (b + 1) * kdtree.QUERY_BLOCK)):
            i = order[t]
            px, py, pz = points[i, 0], points[i, 1], points[i, 2]
            c, r2 = _gather_disc(tree, axis, depth, px, py, pz, k, max_r2, growth, heap, fbuf,
                                 ubuf, stack_i, stack_f, prev)
            out[i, 0] = 0.0
            out[i, 1] = 0.0
            out[i, 2] = 0.0
            if c == 0:
                continue
            if r2 == 0.0:
                bad += 1
                continue
            n0, n1, n2 = unit_row(normals, i)
            L, F = closure.hit_lobes(tab, mat[i], texel[i, 0], texel[i, 1], texel[i, 2],
                                     wo[i, 0], wo[i, 1], wo[i, 2], ns[i, 0], ns[i, 1], ns[i, 2],
                                     n0, n1, n2, tan[i, 0], tan[i, 1], tan[i, 2], front[i],
                                     lam[i])
            if L.shape[0] == 0:
                continue
            ex = 0.0
            ey = 0.0
            ez = 0.0
            for s in range(c):
                j, d2 = kdtree.heap_entry(heap, s, fbuf, ubuf)
                wx, wy, wz = encoding.oct_decode(direction_codes[j, 0], direction_codes[j, 1])
                # photon_weight keeps the photons of its normal's side: give it the side the
                # photon came from (the BSDF decides whether that side's light is seen).
                sg = 1.0 if wx * n0 + wy * n1 + wz * n2 > 0.0 else -1.0
                w = photon_weight(direction_codes, tree, j, np.float64(d2), r2, px, py, pz,
                                  sg * n0, sg * n1, sg * n2, kind, k_cone, plane_fraction)
                if w == 0.0:
                    continue
                f0, f1, f2, _, _, _, _ = closure.parts_at(L, F, wx, wy, wz, n0, n1, n2, True,
                                                          False)
                ex += w * f0 * encoding.half_to_float(flux_codes[j, 0])
                ey += w * f1 * encoding.half_to_float(flux_codes[j, 1])
                ez += w * f2 * encoding.half_to_float(flux_codes[j, 2])
            out[i, 0] = ex * inv_scale
            out[i, 1] = ey * inv_scale
            out[i, 2] = ez * inv_scale
        degenerate[b] = bad
    return degenerate.sum()


def radiance_estimate(photon_map: PhotonMap, points: np.ndarray, normals: np.ndarray,
                      albedo: np.ndarray, k: int, max_radius: float, filter: str = "cone",
                      plane_fraction: float = PLANE_FRACTION,
                      bsdf: BsdfHits | None = None) -> np.ndarray:
    """Diffuse reflected radiance albedo / pi * E (W/(m^2 sr)) at surface points.

    points (M, 3) metres; normals (M, 3) non-zero geometric normals, facing the viewer
    (only photons arriving on that side count); albedo (M, 3) >= 0; k >= 1; max_radius > 0
    metres (inf allowed). With ``bsdf`` (a BsdfHits of the M points) albedo is not read:
    the radiance is the BSDF estimate of the module docstring (photons of both sides,
    each weighted by the diffuse-like lobes' f at its direction). Returns (M, 3) float64.
    Raises ValueError when k photons sit exactly on a query point (zero-area disc).
    """
    if bsdf is None:
        return radiance_estimate_sides(photon_map, points, [normals], albedo, k, max_radius,
                                       filter, plane_fraction)[0]
    m = points.shape[0]
    out = np.zeros((m, 3))
    if m == 0 or len(photon_map) == 0:
        return out
    tree, axis, depth, flux_codes, scale, direction_codes = photon_map.kernel_arrays()
    k = min(int(k), len(photon_map))
    r2 = squared_radius(max_radius)
    points32 = check_points(points, "points")
    normals, texel, wo, ns = (np.ascontiguousarray(a, np.float64) for a in
                              (normals, bsdf.texel, bsdf.outgoing, bsdf.shading_normal))
    mat = np.ascontiguousarray(bsdf.material, np.int32)
    front = np.ascontiguousarray(bsdf.front, np.bool_)
    order = kdtree.query_order(points32)
    with numba.parallel_chunksize(1):
        bad = _bsdf_estimate_kernel(tree, axis, depth, flux_codes, 1.0 / scale, direction_codes,
                                    points32, order, k, r2, kdtree.search_growth(k), normals,
                                    bsdf.closures, mat, texel, wo, ns, bsdf.tangents(), front,
                                    bsdf.wavelengths(), FILTERS[filter], CONE_K,
                                    float(plane_fraction), out)
    _raise_degenerate(bad)
    return out


def radiance_estimate_sides(photon_map: PhotonMap, points, normals_list, albedo, k,
                            max_radius, filter="cone", plane_fraction=PLANE_FRACTION,
                            should_stop=None):
    """``radiance_estimate`` for several normals per point (e.g. both sides of a
    surface) from one neighbour search; returns a list of (M, 3) float64, or None when
    should_stop() (asked between chunks of QUERY_CHUNK points) answers True."""
    m = points.shape[0]
    out = np.zeros((len(normals_list), m, 3))
    if m == 0 or len(photon_map) == 0:
        return list(out)
    points32 = check_points(points, "points")
    normals = np.stack([np.asarray(n, np.float64) for n in normals_list])
    albedo = np.ascontiguousarray(albedo, np.float64)
    k = min(int(k), len(photon_map))
    bad = 0
    for lo in range(0, m, QUERY_CHUNK):
        if lo and should_stop is not None and should_stop():
            return None
        hi = min(m, lo + QUERY_CHUNK)
        bad += _estimate(photon_map, points32[lo:hi], normals[:, lo:hi], albedo[lo:hi], k,
                         max_radius, FILTERS[filter], CONE_K, float(plane_fraction),
                         out[:, lo:hi])
    _raise_degenerate(bad)
    return list(out)
