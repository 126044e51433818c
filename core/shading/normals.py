"""Shading-normal nodes with Cycles' definitions (docs/shading.md, "Normals"): the Normal
Map node (``normal_map``, Cycles' svm_node_normal_map) and the Bump node (``bump``,
svm_node_set_bump) as our own numba code, and ``valid_specular_reflection`` (Cycles'
ensure_valid_specular_reflection) that ``HitShader.shade`` applies to a programmed normal.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401

_JIT = dict(cache=True, error_model="numpy")


@njit(inline="always", **_JIT)
def _safe_normalize(x, y, z):
    length = math.sqrt(x * x + y * y + z * z)
    if length > 0.0:
        return x / length, y / length, z / length, True
    return x, y, z, False


@njit(**_JIT)
def normal_map(space, invert_green, cx, cy, cz, strength, tx, ty, tz, sign, nx, ny, nz, back,
               m00, m01, m02, m10, m11, m12, m20, m21, m22):
    """The Normal Map node's normal (3 floats, unit, world space) as Cycles'
    svm_node_normal_map.

    space: 0 tangent, 1 object, 2 world, 3 Blender object, 4 Blender world
    (``program.NORMAL_MAP_SPACES``); invert_green 1 for Blender 5's DirectX convention
    (the green axis points the other way: Cycles' invert_green); (cx, cy, cz) the colour; strength; (tx, ty, tz) the
    interpolated MikkTSpace tangent A t_o (A the object's linear transform, not
    normalised) and sign its bitangent sign (world space, flipped by a mirroring
    transform; sign 0: no tangent, the normal is returned unchanged as Cycles does without
    the attribute);
    (nx, ny, nz) the shading normal facing the viewer (Cycles' sd->N) and back 1 when the
    hit is on the back face; m the object's normal transform inv(A)^T, rows.

    Tangent space: the colour 2 (c - 0.5) scaled by the strength in the tangent plane
    (z mixed towards 1 for strength < 1), on the object-space frame (T, sign N x T, N)
    with N the smooth normal on the face's own side (sd->N unflipped), taken to the world
    by the normal transform m (as Cycles: so a non-uniformly scaled object's bumps flatten
    along its stretch), then flipped back for a back face. Object / world space: the colour as a normal (object: through the normal
    transform); Blender's conventions negate y and z; strength interpolates linearly
    from sd->N. A zero or non-finite result gives sd->N.
    """
    cx, cy, cz = 2.0 * (cx - 0.5), 2.0 * (cy - 0.5), 2.0 * (cz - 0.5)
    if invert_green:
        cy = -cy
    flip = -1.0 if back > 0.5 else 1.0
    linear = True
    if space == 0:
        if sign == 0.0:
            return nx, ny, nz
        # Cycles mixes in object space, then applies the normal transform M = inv(A)^T:
        # under a non-uniform scale that differs from mixing in the world. The tangent
        # here is A t_o (not normalised), so t_o = M^T t; the normal (before its
        # back-face flip, as Cycles builds the frame) goes back by M^-1 = A^T, whose
        # columns are the cross products of M's rows over det M; a mirroring transform
        # (det < 0) flipped the exported bitangent sign, which object space undoes.
        bx, by, bz = flip * nx, flip * ny, flip * nz
        det = (m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20)
               + m02 * (m10 * m21 - m11 * m20))
        if det == 0.0 or not math.isfinite(det):
            return nx, ny, nz
        ux = m00 * tx + m10 * ty + m20 * tz
        uy = m01 * tx + m11 * ty + m21 * tz
        uz = m02 * tx + m12 * ty + m22 * tz
        wx = ((m11 * m22 - m12 * m21) * bx + (m21 * m02 - m22 * m01) * by
              + (m01 * m12 - m02 * m11) * bz)
        wy = ((m12 * m20 - m10 * m22) * bx + (m22 * m00 - m20 * m02) * by
              + (m02 * m10 - m00 * m12) * bz)
        wz = ((m10 * m21 - m11 * m20) * bx + (m20 * m01 - m21 * m00) * by
              + (m00 * m11 - m01 * m10) * bz)
        if det < 0.0:  # adj(M) / det: only the direction matters, not the length
            wx, wy, wz, sign = -wx, -wy, -wz, -sign
        wx, wy, wz, ok = _safe_normalize(wx, wy, wz)
        if not ok:
            return nx, ny, nz
        cx *= strength
        cy *= strength
        s = min(max(strength, 0.0), 1.0)
        cz = 1.0 + (cz - 1.0) * s
        # B = sign * cross(normal, tangent), object space
        qx = sign * (wy * uz - wz * uy)
        qy = sign * (wz * ux - wx * uz)
        qz = sign * (wx * uy - wy * ux)
        px = cx * ux + cy * qx + cz * wx
        py = cx * uy + cy * qy + cz * wy
        pz = cx * uz + cy * qz + cz * wz
        ox = m00 * px + m01 * py + m02 * pz
        oy = m10 * px + m11 * py + m12 * pz
        oz = m20 * px + m21 * py + m22 * pz
        ox, oy, oz, ok = _safe_normalize(ox, oy, oz)
        ox, oy, oz = flip * ox, flip * oy, flip * oz
        linear = False
    else:
        if space == 3 or space == 4:
            cy, cz = -cy, -cz
        if space == 1 or space == 3:
            ox = m00 * cx + m01 * cy + m02 * cz
            oy = m10 * cx + m11 * cy + m12 * cz
            oz = m20 * cx + m21 * cy + m22 * cz
        else:
            ox, oy, oz = cx, cy, cz
        ox, oy, oz, ok = _safe_normalize(ox, oy, oz)
        ox, oy, oz = flip * ox, flip * oy, flip * oz
    if linear and strength != 1.0:
        s = max(strength, 0.0)
        ox, oy, oz, ok = _safe_normalize(nx + (ox - nx) * s, ny + (oy - ny) * s,
                                         nz + (oz - nz) * s)
    if not ok or not (math.isfinite(ox) and math.isfinite(oy) and math.isfinite(oz)):
        return nx, ny, nz
    return ox, oy, oz


@njit(**_JIT)
def bump(invert, strength, distance, width, h_c, h_x, h_y, nx, ny, nz,
         dxx, dxy, dxz, dyx, dyy, dyz):
    """The Bump node's normal (3 floats, unit) as Cycles' svm_node_set_bump: the heights
    h_c at the point, h_x at P + width dPdx, h_y at P + width dPdy (width the Filter Width),
    the footprint vectors dPdx = (dxx, dxy, dxz), dPdy (metres, in the tangent plane),
    the input normal n; Distance scales the height (negated by Invert), Strength mixes
    the result with n. N' = normalize(width |det| n - distance sign(det) surfgrad) with
    Rx = dPdy x n, Ry = n x dPdx, det = dPdx . Rx, surfgrad = (h_x - h_c) Rx + (h_y - h_c)
    Ry: to first order normalize(n - distance grad h), whatever the footprint's size."""
    rxx, rxy, rxz = dyy * nz - dyz * ny, dyz * nx - dyx * nz, dyx * ny - dyy * nx
    ryx, ryy, ryz = ny * dxz - nz * dxy, nz * dxx - nx * dxz, nx * dxy - ny * dxx
    det = dxx * rxx + dxy * rxy + dxz * rxz
    gx = (h_x - h_c) * rxx + (h_y - h_c) * ryx
    gy = (h_x - h_c) * rxy + (h_y - h_c) * ryy
    gz = (h_x - h_c) * rxz + (h_y - h_c) * ryz
    scale = -distance if invert else distance
    strength = max(strength, 0.0)
    sgn = 1.0 if det > 0.0 else (-1.0 if det < 0.0 else 0.0)
    a = width * abs(det)
    ox, oy, oz, ok = _safe_normalize(a * nx - scale * sgn * gx, a * ny - scale * sgn * gy,
                                     a * nz - scale * sgn * gz)
    if not ok:
        return nx, ny, nz
    ox, oy, oz, ok = _safe_normalize(strength * ox + (1.0 - strength) * nx,
                                     strength * oy + (1.0 - strength) * ny,
                                     strength * oz + (1.0 - strength) * nz)
    if not ok or not (math.isfinite(ox) and math.isfinite(oy) and math.isfinite(oz)):
        return nx, ny, nz
    return ox, oy, oz


def valid_specular_reflection(ng, incoming, n) -> np.ndarray:
    """(N, 3) float64 unit: shading normals n (N, 3, unit) tilted towards the true normal
    ng (N, 3, unit, on the viewer's side) just enough that the mirror reflection of
    ``incoming`` (N, 3, unit, towards the viewer) leaves at least min(0.9 I.Ng, 0.01)
    above the true surface, as Cycles' ensure_valid_specular_reflection (what its BSDFs
    apply to a bumped or normal-mapped normal): a strong bump cannot reflect a ray into
    the surface it came from. Normals already valid are returned unchanged."""
    ng = np.asarray(ng, np.float64)
    i = np.asarray(incoming, np.float64)
    n = np.asarray(n, np.float64)
    out = n.copy()
    dot = np.einsum
    ni = dot("ij,ij->i", n, i)
    iz = dot("ij,ij->i", i, ng)
    threshold = np.minimum(0.9 * iz, 0.01)
    r_z = 2.0 * ni * dot("ij,ij->i", n, ng) - iz  # Ng . R, R = 2 (N.I) N - I
    bad = np.flatnonzero(r_z < threshold)
    if bad.size == 0:
        return out
    ng, i, n, iz, t = ng[bad], i[bad], n[bad], iz[bad], threshold[bad]
    # Frame: Ng the z axis, x along N's component orthogonal to Ng (N itself if none).
    x = n - dot("ij,ij->i", n, ng)[:, None] * ng
    length = np.linalg.norm(x, axis=1)
    x = np.where(length[:, None] > 0, x / np.where(length > 0, length, 1.0)[:, None], n)
    ix = dot("ij,ij->i", i, x)
    # N'.z solves 4 a z^4 - 2 b z^2 + c = 0 with the root whose reflection is the one
    # asked for (Cycles' derivation, kernel/geom/shader_data or util/math)
    a = ix * ix + iz * iz
    b = 2.0 * (a + iz * t)
    c = (t + iz) ** 2
    root = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
    a_safe = np.where(a > 0, a, 1.0)
    nz2 = np.where(ix < 0, 0.25 * (b + root) / a_safe, 0.25 * (b - root) / a_safe)
    nx = np.sqrt(np.maximum(1.0 - nz2, 0.0))
    nz = np.sqrt(np.maximum(nz2, 0.0))
    fixed = nx[:, None] * x + nz[:, None] * ng
    fixed /= np.maximum(np.linalg.norm(fixed, axis=1), 1e-300)[:, None]
    out[bad] = np.where((a > 0)[:, None], fixed, ng)
    return out


@njit(**_JIT)
def tangent(mode, vx, vy, vz, m00, m01, m02, m10, m11, m12, m20, m21, m22, nx, ny, nz):
    """The Tangent node's tangent (3 floats, unit, world space) as Cycles'
    svm_node_tangent (and Geometry Tangent, primitive_tangent: radial about Z).

    mode: ``program.TANGENT_MODES`` (0-2 radial about the object's X / Y / Z axis, 3 UV
    map); v: Generated (radial), or the UV map's interpolated world-space tangent (UV
    map: 0 where the mesh has none, and the result is then 0, as Cycles without the
    attribute); m: the rows of the object's normal transform inv(A)^T, applied to the
    radial tangent (Cycles' object_normal_transform; the UV map's tangent is already in
    world space); n: the shading normal. Result cross(N, normalize(cross(T, N))): T made
    orthogonal to N; 0 where T is parallel to N or 0 (the radial tangent on its axis,
    where Cycles' normalize divides by 0)."""
    if mode == 0:
        tx, ty, tz = 0.0, -(vz - 0.5), vy - 0.5
    elif mode == 1:
        tx, ty, tz = -(vz - 0.5), 0.0, vx - 0.5
    elif mode == 2:
        tx, ty, tz = -(vy - 0.5), vx - 0.5, 0.0
    else:
        tx, ty, tz = vx, vy, vz
    if mode != 3:
        tx, ty, tz = (m00 * tx + m01 * ty + m02 * tz, m10 * tx + m11 * ty + m12 * tz,
                      m20 * tx + m21 * ty + m22 * tz)
    cx, cy, cz = ty * nz - tz * ny, tz * nx - tx * nz, tx * ny - ty * nx
    cx, cy, cz, ok = _safe_normalize(cx, cy, cz)
    if not ok:
        return 0.0, 0.0, 0.0
    return ny * cz - nz * cy, nz * cx - nx * cz, nx * cy - ny * cx
