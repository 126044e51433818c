"""Surface points from ray hits, and the ray-offset rule that replaces a fixed epsilon.

Offset rule (scale-invariant): a new ray leaving a surface point p starts at

    p + side * eps(p) * n_g,   eps(p) = 2^-20 * (max(|p_x|, |p_y|, |p_z|) + extent)

where n_g is the unit geometric normal, side = +1 or -1 puts the origin on the side the
ray leaves towards, and ``extent`` is the largest side of the scene's bounding box.
float32 (what Embree sees) resolves 2^-24..2^-23 of a coordinate, so eps is 8-16 units
in the last place of the point's own coordinates (the rounding of the origin to float32
and Embree's plane test are a few of them) plus the same of the scene size (planes through
points near the world origin are computed from vertices as large as the scene). Scaling
the scene scales eps; translating it changes eps only as float32 resolution changes.
Shadow rays stop eps(q) / cos short of a light point q for the same reason.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .contract import SceneError

OFFSET_SCALE = 2.0 ** -20


class SurfacePoints(NamedTuple):
    """Shading data of N hits, float64.

    position: (N, 3) metres, from the barycentrics (exact on the float32 triangle).
    geometric_normal: (N, 3) unit, from the winding (v1 - v0) x (v2 - v0).
    shading_normal: (N, 3) unit, interpolated corner normals (geometric where degenerate).
    material: (N,) int32.
    eps: (N,) metres, the offset of the rule above.
    """

    position: np.ndarray
    geometric_normal: np.ndarray
    shading_normal: np.ndarray
    material: np.ndarray
    eps: np.ndarray


def scene_extent(lo: np.ndarray, hi: np.ndarray) -> float:
    """Largest side of the bounding box, metres (0 for a single point)."""
    return float(np.max(np.asarray(hi, np.float64) - np.asarray(lo, np.float64)))


@njit(cache=True, error_model="numpy")
def offset_eps(x, y, z, extent):
    return OFFSET_SCALE * (max(abs(x), abs(y), abs(z)) + extent)


@njit(cache=True, error_model="numpy")
def surface_point(tri_v, tri_n, t, b1, b2, dx, dy, dz):
    """Hit point, unit geometric normal (winding) and unit shading normal of triangle t
    at barycentrics (b1, b2), for a ray of direction d. Never NaN: a zero-area triangle
    gets -d as its normal, a zero shading normal falls back to the geometric one."""
    b0 = 1.0 - b1 - b2
    a0 = tri_v[t, 0]
    a1 = tri_v[t, 1]
    a2 = tri_v[t, 2]
    e1x = np.float64(a1[0]) - a0[0]
    e1y = np.float64(a1[1]) - a0[1]
    e1z = np.float64(a1[2]) - a0[2]
    e2x = np.float64(a2[0]) - a0[0]
    e2y = np.float64(a2[1]) - a0[1]
    e2z = np.float64(a2[2]) - a0[2]
    px = a0[0] + b1 * e1x + b2 * e2x
    py = a0[1] + b1 * e1y + b2 * e2y
    pz = a0[2] + b1 * e1z + b2 * e2z
    cx = e1y * e2z - e1z * e2y
    cy = e1z * e2x - e1x * e2z
    cz = e1x * e2y - e1y * e2x
    ln = np.sqrt(cx * cx + cy * cy + cz * cz)
    if ln > 0.0:
        cx /= ln
        cy /= ln
        cz /= ln
    else:
        cx, cy, cz = -dx, -dy, -dz
    sx = b0 * tri_n[t, 0, 0] + b1 * tri_n[t, 1, 0] + b2 * tri_n[t, 2, 0]
    sy = b0 * tri_n[t, 0, 1] + b1 * tri_n[t, 1, 1] + b2 * tri_n[t, 2, 1]
    sz = b0 * tri_n[t, 0, 2] + b1 * tri_n[t, 1, 2] + b2 * tri_n[t, 2, 2]
    ls = np.sqrt(sx * sx + sy * sy + sz * sz)
    if ls > 1e-12:
        sx /= ls
        sy /= ls
        sz /= ls
        # A shading normal on the far side of the plane (bad export) is replaced.
        if sx * cx + sy * cy + sz * cz <= 0.0:
            sx, sy, sz = cx, cy, cz
    else:
        sx, sy, sz = cx, cy, cz
    return px, py, pz, cx, cy, cz, sx, sy, sz


@njit(cache=True, parallel=True, error_model="numpy")
def _surface_kernel(tri_v, tri_n, tri_mat, prim, u, v, ray_d, extent,
                    pos, ng, ns, mat, eps):
    for i in prange(prim.shape[0]):
        t = prim[i]
        (pos[i, 0], pos[i, 1], pos[i, 2], ng[i, 0], ng[i, 1], ng[i, 2],
         ns[i, 0], ns[i, 1], ns[i, 2]) = surface_point(tri_v, tri_n, t, np.float64(u[i]),
                                                        np.float64(v[i]), ray_d[i, 0],
                                                        ray_d[i, 1], ray_d[i, 2])
        mat[i] = tri_mat[t]
        eps[i] = offset_eps(pos[i, 0], pos[i, 1], pos[i, 2], extent)


def surface_points(tri_vertices: np.ndarray, tri_normals: np.ndarray, tri_material: np.ndarray,
                   prim: np.ndarray, u: np.ndarray, v: np.ndarray, directions: np.ndarray,
                   extent: float) -> SurfacePoints:
    """Reconstruct N hits (prim >= 0 everywhere) from Embree's triangle index and barycentrics.

    tri_vertices (T, 3, 3) float32, tri_normals (T, 3, 3) float32, tri_material (T,) int32;
    prim (N,) int32, u, v (N,) float32; directions (N, 3) the rays' unit directions.
    """
    n = prim.shape[0]
    pos = np.empty((n, 3))
    ng = np.empty((n, 3))
    ns = np.empty((n, 3))
    mat = np.empty(n, np.int32)
    eps = np.empty(n)
    if n:
        _surface_kernel(tri_vertices, tri_normals, tri_material, np.ascontiguousarray(prim),
                        np.ascontiguousarray(u), np.ascontiguousarray(v),
                        np.ascontiguousarray(directions, np.float64), float(extent),
                        pos, ng, ns, mat, eps)
    return SurfacePoints(pos, ng, ns, mat, eps)


@njit(cache=True, parallel=True, error_model="numpy")
def _facing_kernel(tri_v, tri_n, tri_mat, prim, u, v, d, extent, pos, ngf, nsf, mat, eps, front):
    for i in prange(prim.shape[0]):
        t = prim[i]
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        px, py, pz, gx, gy, gz, sx, sy, sz = surface_point(
            tri_v, tri_n, t, np.float64(u[i]), np.float64(v[i]), dx, dy, dz)
        f = dx * gx + dy * gy + dz * gz < 0.0
        sgn = 1.0 if f else -1.0
        pos[i, 0], pos[i, 1], pos[i, 2] = px, py, pz
        ngf[i, 0], ngf[i, 1], ngf[i, 2] = sgn * gx, sgn * gy, sgn * gz
        nsf[i, 0], nsf[i, 1], nsf[i, 2] = sgn * sx, sgn * sy, sgn * sz
        mat[i] = tri_mat[t]
        eps[i] = offset_eps(px, py, pz, extent)
        front[i] = f


def facing_surface_points(tri_vertices, tri_normals, tri_material, prim, u, v, directions,
                          extent):
    """Like surface_points, with both normals flipped to face the incoming ray.

    Returns (pos, ngf, nsf (N, 3) float64, mat (N,) int32, eps (N,) float64, front (N,)
    bool: the ray hit the side the winding's normal points to). Camera paths and gather
    rays shade with these.
    """
    n = prim.shape[0]
    pos, ngf, nsf = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    mat, eps, front = np.empty(n, np.int32), np.empty(n), np.empty(n, bool)
    if n:
        _facing_kernel(tri_vertices, tri_normals, tri_material, prim, u, v, directions,
                       float(extent), pos, ngf, nsf, mat, eps, front)
    return pos, ngf, nsf, mat, eps, front


def offset_points(points: np.ndarray, geometric_normal: np.ndarray, eps: np.ndarray,
                  directions: np.ndarray) -> np.ndarray:
    """Origins (N, 3) float64 for rays leaving ``points`` along ``directions``.

    Moves each point eps along the geometric normal, to the side the direction points to.
    """
    side = np.where(np.einsum("ij,ij->i", geometric_normal, directions) >= 0.0, 1.0, -1.0)
    return points + (side * eps)[:, None] * geometric_normal


def point_eps(points: np.ndarray, extent: float) -> np.ndarray:
    """(N,) float64 offset of the rule above for arbitrary points (N, 3), metres."""
    return OFFSET_SCALE * (np.max(np.abs(points), axis=1) + extent)


MIN_FLOAT32_STEPS = 2 ** 13
"""Fewest float32 steps the scene's extent must span at its farthest coordinate: the ray
offsets are 8-16 steps (above), so at 2^13 steps they stay below 1/500 of the scene."""


def check_float32_precision(scene) -> None:
    """Raise SceneError when float32 (what Embree stores) cannot resolve the scene.

    At distance m from the origin float32 coordinates are spaced 2^(floor(log2 m) - 23)
    apart; when the scene's bounding box (geometry, positional lights, camera) spans fewer
    than MIN_FLOAT32_STEPS such steps, vertices snap and the ray offsets swallow gaps
    between objects (caustic photons are lost first), so the image would be silently wrong.
    """
    lo, hi = scene.bounds()
    far = float(max(np.max(np.abs(lo)), np.max(np.abs(hi))))
    extent = scene_extent(lo, hi)
    if far == 0.0 or extent == 0.0:
        return
    step = float(np.spacing(np.float32(far)))
    if extent < MIN_FLOAT32_STEPS * step:
        raise SceneError(
            f"float32 precision cannot hold the scene: it reaches {far:.4g} m from the render "
            f"origin (the camera, for scenes exported from Blender), where float32 resolves "
            f"{step * 1e3:.3g} mm, only 1/{extent / step:.0f} of its {extent:.4g} m size (at "
            f"least 1/{MIN_FLOAT32_STEPS} is needed); hide far objects from the render or "
            f"render the near part of the scene on its own")
