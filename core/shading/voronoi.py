"""Cycles' Voronoi Texture (kernel/svm/voronoi.h) in 1, 2, 3 and 4 D: F1, F2, smooth F1,
distance to edge and n-sphere radius, with the Euclidean, Manhattan, Chebychev and Minkowski metrics and the
fractal octaves (detail, roughness, lacunarity, normalize) of Blender 4.0+. Feature
points come from the PCG integer hashes (Blender 5.0+), or with ``legacy`` from lookup3
on the cell's float coordinates (Blender 4.x, before Cycles commit c24e0712c of June 2025).
1D hashes the cell's float coordinate with lookup3 in both, and measures |distance| whatever
the metric (Cycles); 4D uses PCG 4D (5.0+) or lookup3 on the four floats (4.x).

A 2-D point is (x, y, 0) with a one-cell-thick search in z; the metrics then see a zero
third component, which leaves every metric unchanged.
"""

from __future__ import annotations

import math

from numba import njit

from .. import _numba_cache  # noqa: F401
from .hash import hash_int2_to_float2, hash_int3_to_float3, hash_int4_to_float4, \
    hash_float_to_float, hash_float2_to_float, hash_float3_to_float, hash_float4_to_float

_JIT = dict(cache=True, error_model="numpy")

F1 = 0
F2 = 1
SMOOTH_F1 = 2
DISTANCE_TO_EDGE = 3
N_SPHERE_RADIUS = 4
FEATURES = {"F1": F1, "F2": F2, "SMOOTH_F1": SMOOTH_F1, "DISTANCE_TO_EDGE": DISTANCE_TO_EDGE,
            "N_SPHERE_RADIUS": N_SPHERE_RADIUS}
EUCLIDEAN = 0
MANHATTAN = 1
CHEBYCHEV = 2
MINKOWSKI = 3
METRICS = {"EUCLIDEAN": EUCLIDEAN, "MANHATTAN": MANHATTAN, "CHEBYCHEV": CHEBYCHEV,
           "MINKOWSKI": MINKOWSKI}
"""Blender's ``feature`` / ``distance`` enums -> the codes of the program."""


@njit(inline="always", **_JIT)
def _distance(dx, dy, dz, metric, exponent):
    dx, dy, dz = abs(dx), abs(dy), abs(dz)
    if metric == EUCLIDEAN:
        return math.sqrt(dx * dx + dy * dy + dz * dz)
    if metric == MANHATTAN:
        return dx + dy + dz
    if metric == CHEBYCHEV:
        return max(dx, max(dy, dz))
    return (dx ** exponent + dy ** exponent + dz ** exponent) ** (1.0 / exponent)


@njit(inline="always", **_JIT)
def _bound(dx, dy, dz, metric, exponent):
    """Cycles' voronoi_distance_bound: monotone in the distance (no root)."""
    if metric == EUCLIDEAN:
        return dx * dx + dy * dy + dz * dz
    if metric == MINKOWSKI:
        return abs(dx) ** exponent + abs(dy) ** exponent + abs(dz) ** exponent
    return _distance(dx, dy, dz, metric, exponent)


# Not inlined: inlining these hashes at every call site multiplied the compile time
# (voronoi_texture alone, cold cache: 33.3 -> 7.8 CPU s).
@njit(**_JIT)
def _cell_point(cx, cy, cz, dims, legacy):
    """The feature point's offset in [0, 1)^dims of integer cell (cx, cy, cz)."""
    if legacy:
        x, y, z = float(cx), float(cy), float(cz)
        if dims == 2:
            return hash_float2_to_float(x, y), hash_float3_to_float(x, y, 1.0), 0.0
        return (hash_float3_to_float(x, y, z), hash_float4_to_float(x, y, z, 1.0),
                hash_float4_to_float(x, y, z, 2.0))
    if dims == 2:
        a, b = hash_int2_to_float2(cx, cy)
        return a, b, 0.0
    return hash_int3_to_float3(cx, cy, cz)


@njit(**_JIT)  # not inlined, as _cell_point
def _cell_color(cx, cy, cz, dims, legacy):
    if legacy:
        x, y, z = float(cx), float(cy), float(cz)
        if dims == 2:
            return (hash_float2_to_float(x, y), hash_float3_to_float(x, y, 1.0),
                    hash_float3_to_float(x, y, 2.0))
        return (hash_float3_to_float(x, y, z), hash_float4_to_float(x, y, z, 1.0),
                hash_float4_to_float(x, y, z, 2.0))
    return hash_int3_to_float3(cx, cy, 0 if dims == 2 else cz)


@njit(inline="always", **_JIT)
def _smoothstep01(x):
    if x < 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return (3.0 - 2.0 * x) * (x * x)


@njit(**_JIT)
def octave(x, y, z, dims, feature, metric, exponent, randomness, smoothness, legacy):
    """One octave of F1 / F2 / smooth F1 at (x, y, z): (distance, r, g, b, px, py, pz)."""
    fx, fy, fz = math.floor(x), math.floor(y), math.floor(z) if dims == 3 else 0.0
    lx, ly, lz = x - fx, y - fy, (z - fz) if dims == 3 else 0.0
    cx, cy, cz = int(fx), int(fy), int(fz)
    kr = 1 if dims == 3 else 0
    if feature == SMOOTH_F1 and smoothness != 0.0:
        sd = 0.0
        sr = sg = sb = 0.0
        spx = spy = spz = 0.0
        h = -1.0
        for k in range(-2 * kr, 2 * kr + 1):
            for j in range(-2, 3):
                for i in range(-2, 3):
                    ox, oy, oz = _cell_point(cx + i, cy + j, cz + k, dims, legacy)
                    px = i + ox * randomness
                    py = j + oy * randomness
                    pz = k + oz * randomness
                    d = _distance(px - lx, py - ly, pz - lz, metric, exponent)
                    h = 1.0 if h == -1.0 else _smoothstep01(0.5 + 0.5 * (sd - d) / smoothness)
                    corr = smoothness * h * (1.0 - h)
                    sd = (1.0 - h) * sd + h * d - corr
                    corr /= 1.0 + 3.0 * smoothness
                    r, g, b = _cell_color(cx + i, cy + j, cz + k, dims, legacy)
                    sr = (1.0 - h) * sr + h * r - corr
                    sg = (1.0 - h) * sg + h * g - corr
                    sb = (1.0 - h) * sb + h * b - corr
                    spx = (1.0 - h) * spx + h * px - corr
                    spy = (1.0 - h) * spy + h * py - corr
                    spz = (1.0 - h) * spz + h * pz - corr
        return sd, sr, sg, sb, fx + spx, fy + spy, (fz + spz) if dims == 3 else 0.0
    d1 = d2 = 3.4028234663852886e38
    o1x = o1y = o1z = o2x = o2y = o2z = 0
    p1x = p1y = p1z = p2x = p2y = p2z = 0.0
    for k in range(-kr, kr + 1):
        for j in range(-1, 2):
            for i in range(-1, 2):
                ox, oy, oz = _cell_point(cx + i, cy + j, cz + k, dims, legacy)
                px = i + ox * randomness
                py = j + oy * randomness
                pz = k + oz * randomness
                if feature == F2:
                    d = _distance(px - lx, py - ly, pz - lz, metric, exponent)
                    if d < d1:
                        d2, o2x, o2y, o2z, p2x, p2y, p2z = d1, o1x, o1y, o1z, p1x, p1y, p1z
                        d1, o1x, o1y, o1z, p1x, p1y, p1z = d, i, j, k, px, py, pz
                    elif d < d2:
                        d2, o2x, o2y, o2z, p2x, p2y, p2z = d, i, j, k, px, py, pz
                else:
                    d = _bound(px - lx, py - ly, pz - lz, metric, exponent)
                    if d < d1:
                        d1, o1x, o1y, o1z, p1x, p1y, p1z = d, i, j, k, px, py, pz
    if feature == F2:
        r, g, b = _cell_color(cx + o2x, cy + o2y, cz + o2z, dims, legacy)
        return d2, r, g, b, p2x + fx, p2y + fy, (p2z + fz) if dims == 3 else 0.0
    d = _distance(p1x - lx, p1y - ly, p1z - lz, metric, exponent)
    r, g, b = _cell_color(cx + o1x, cy + o1y, cz + o1z, dims, legacy)
    return d, r, g, b, p1x + fx, p1y + fy, (p1z + fz) if dims == 3 else 0.0


@njit(**_JIT)
def distance_to_edge(x, y, z, dims, randomness, legacy):
    """Cycles' voronoi_distance_to_edge (Euclidean, whatever the metric)."""
    fx, fy, fz = math.floor(x), math.floor(y), math.floor(z) if dims == 3 else 0.0
    lx, ly, lz = x - fx, y - fy, (z - fz) if dims == 3 else 0.0
    cx, cy, cz = int(fx), int(fy), int(fz)
    kr = 1 if dims == 3 else 0
    vx = vy = vz = 0.0
    best = 3.4028234663852886e38
    for k in range(-kr, kr + 1):
        for j in range(-1, 2):
            for i in range(-1, 2):
                ox, oy, oz = _cell_point(cx + i, cy + j, cz + k, dims, legacy)
                tx = i + ox * randomness - lx
                ty = j + oy * randomness - ly
                tz = (k + oz * randomness - lz) if dims == 3 else 0.0
                d = tx * tx + ty * ty + tz * tz
                if d < best:
                    best, vx, vy, vz = d, tx, ty, tz
    best = 3.4028234663852886e38
    for k in range(-kr, kr + 1):
        for j in range(-1, 2):
            for i in range(-1, 2):
                ox, oy, oz = _cell_point(cx + i, cy + j, cz + k, dims, legacy)
                tx = i + ox * randomness - lx
                ty = j + oy * randomness - ly
                tz = (k + oz * randomness - lz) if dims == 3 else 0.0
                ex, ey, ez = tx - vx, ty - vy, tz - vz
                e2 = ex * ex + ey * ey + ez * ez
                if e2 > 0.0001:
                    inv = 1.0 / math.sqrt(e2)
                    d = ((vx + tx) * 0.5 * ex + (vy + ty) * 0.5 * ey + (vz + tz) * 0.5 * ez) * inv
                    best = min(best, d)
    return best


@njit(**_JIT)
def n_sphere_radius(x, y, z, dims, randomness, legacy):
    """Cycles' voronoi_n_sphere_radius: half the (Euclidean) distance from the nearest
    feature point to its own nearest one (searched among the cells around its cell)."""
    fx, fy, fz = math.floor(x), math.floor(y), math.floor(z) if dims == 3 else 0.0
    lx, ly, lz = x - fx, y - fy, (z - fz) if dims == 3 else 0.0
    cx, cy, cz = int(fx), int(fy), int(fz)
    kr = 1 if dims == 3 else 0
    best = 3.4028234663852886e38
    qx = qy = qz = 0.0
    oi = oj = ok = 0
    for k in range(-kr, kr + 1):
        for j in range(-1, 2):
            for i in range(-1, 2):
                ox, oy, oz = _cell_point(cx + i, cy + j, cz + k, dims, legacy)
                px, py, pz = i + ox * randomness, j + oy * randomness, k + oz * randomness
                d = _distance(px - lx, py - ly, pz - lz, EUCLIDEAN, 1.0)
                if d < best:
                    best, qx, qy, qz, oi, oj, ok = d, px, py, pz, i, j, k
    best = 3.4028234663852886e38
    rx = ry = rz = 0.0
    for k in range(-kr, kr + 1):
        for j in range(-1, 2):
            for i in range(-1, 2):
                if i == 0 and j == 0 and k == 0:
                    continue
                ii, jj, kk = i + oi, j + oj, k + ok
                ox, oy, oz = _cell_point(cx + ii, cy + jj, cz + kk, dims, legacy)
                px, py, pz = ii + ox * randomness, jj + oy * randomness, kk + oz * randomness
                d = _distance(qx - px, qy - py, qz - pz, EUCLIDEAN, 1.0)
                if d < best:
                    best, rx, ry, rz = d, px, py, pz
    return _distance(rx - qx, ry - qy, rz - qz, EUCLIDEAN, 1.0) / 2.0


# --- 1D (W only): lookup3 on the cell's float coordinate in Blender 4.x and 5.x alike ----

@njit(**_JIT)
def _cell_color1(c):
    """Cycles' hash_float_to_float3 of cell coordinate c (float)."""
    return hash_float_to_float(c), hash_float2_to_float(c, 1.0), hash_float2_to_float(c, 2.0)


@njit(**_JIT)
def octave1(w, feature, randomness, smoothness):
    """One 1-D octave of F1 / F2 / smooth F1 at w: (distance, r, g, b, position w); the
    distance is |dw| whatever the metric (Cycles' 1-D voronoi_distance)."""
    cell = math.floor(w)
    local = w - cell
    if feature == SMOOTH_F1 and smoothness != 0.0:
        sd = sr = sg = sb = sp = 0.0
        h = -1.0
        for i in range(-2, 3):
            p = i + hash_float_to_float(cell + i) * randomness
            d = abs(p - local)
            h = 1.0 if h == -1.0 else _smoothstep01(0.5 + 0.5 * (sd - d) / smoothness)
            corr = smoothness * h * (1.0 - h)
            sd = (1.0 - h) * sd + h * d - corr
            corr /= 1.0 + 3.0 * smoothness
            r, g, b = _cell_color1(cell + i)
            sr = (1.0 - h) * sr + h * r - corr
            sg = (1.0 - h) * sg + h * g - corr
            sb = (1.0 - h) * sb + h * b - corr
            sp = (1.0 - h) * sp + h * p - corr
        return sd, sr, sg, sb, cell + sp
    d1 = d2 = 3.4028234663852886e38
    o1 = o2 = 0
    p1 = p2 = 0.0
    for i in range(-1, 2):
        p = i + hash_float_to_float(cell + i) * randomness
        d = abs(p - local)
        if d < d1:
            d2, o2, p2 = d1, o1, p1
            d1, o1, p1 = d, i, p
        elif d < d2:
            d2, o2, p2 = d, i, p
    if feature == F2:
        r, g, b = _cell_color1(cell + o2)
        return d2, r, g, b, p2 + cell
    r, g, b = _cell_color1(cell + o1)
    return d1, r, g, b, p1 + cell


@njit(**_JIT)
def distance_to_edge1(w, randomness):
    """Cycles' 1-D voronoi_distance_to_edge: to the nearer midpoint with a neighbour."""
    cell = math.floor(w)
    local = w - cell
    mid = hash_float_to_float(cell) * randomness
    left = -1.0 + hash_float_to_float(cell - 1.0) * randomness
    right = 1.0 + hash_float_to_float(cell + 1.0) * randomness
    return min(abs((mid + left) / 2.0 - local), abs((mid + right) / 2.0 - local))


@njit(**_JIT)
def n_sphere_radius1(w, randomness):
    """Cycles' 1-D voronoi_n_sphere_radius."""
    cell = math.floor(w)
    local = w - cell
    best = 3.4028234663852886e38
    q = 0.0
    qo = 0
    for i in range(-1, 2):
        p = i + hash_float_to_float(cell + i) * randomness
        d = abs(p - local)
        if d < best:
            best, q, qo = d, p, i
    best = 3.4028234663852886e38
    rr = 0.0
    for i in (-1, 1):
        o = i + qo
        p = o + hash_float_to_float(cell + o) * randomness
        d = abs(q - p)
        if d < best:
            best, rr = d, p
    return abs(rr - q) / 2.0


# --- 4D (Vector + W) -----------------------------------------------------------------------

@njit(inline="always", **_JIT)
def _distance4(dx, dy, dz, dw, metric, exponent):
    dx, dy, dz, dw = abs(dx), abs(dy), abs(dz), abs(dw)
    if metric == EUCLIDEAN:
        return math.sqrt(dx * dx + dy * dy + dz * dz + dw * dw)
    if metric == MANHATTAN:
        return dx + dy + dz + dw
    if metric == CHEBYCHEV:
        return max(max(dx, dy), max(dz, dw))
    return (dx ** exponent + dy ** exponent + dz ** exponent + dw ** exponent) ** (
        1.0 / exponent)


@njit(inline="always", **_JIT)
def _bound4(dx, dy, dz, dw, metric, exponent):
    """As _bound, in 4-D."""
    if metric == EUCLIDEAN:
        return dx * dx + dy * dy + dz * dz + dw * dw
    if metric == MINKOWSKI:
        return abs(dx) ** exponent + abs(dy) ** exponent + abs(dz) ** exponent + \
            abs(dw) ** exponent
    return _distance4(dx, dy, dz, dw, metric, exponent)


@njit(**_JIT)  # not inlined, as _cell_point
def _cell_point4(cx, cy, cz, cw, legacy):
    """The feature point's offset in [0, 1)^4 of integer cell (cx, cy, cz, cw): Cycles'
    hash_int4_to_float4 (PCG, 5.0+) or with ``legacy`` hash_float4_to_float4 (4.x)."""
    if legacy:
        x, y, z, w = float(cx), float(cy), float(cz), float(cw)
        return (hash_float4_to_float(x, y, z, w), hash_float4_to_float(w, x, y, z),
                hash_float4_to_float(z, w, x, y), hash_float4_to_float(y, z, w, x))
    return hash_int4_to_float4(cx, cy, cz, cw)


@njit(**_JIT)  # not inlined, as _cell_point
def _cell_color4(cx, cy, cz, cw, legacy):
    """Cycles' hash_int4_to_float3 (5.0+) or hash_float4_to_float3 (4.x) of the cell."""
    if legacy:
        x, y, z, w = float(cx), float(cy), float(cz), float(cw)
        return (hash_float4_to_float(x, y, z, w), hash_float4_to_float(z, x, w, y),
                hash_float4_to_float(w, z, y, x))
    a, b, c, _ = hash_int4_to_float4(cx, cy, cz, cw)
    return a, b, c


@njit(**_JIT)
def octave4(x, y, z, w, feature, metric, exponent, randomness, smoothness, legacy):
    """One 4-D octave of F1 / F2 / smooth F1: (distance, r, g, b, px, py, pz, pw)."""
    fx, fy, fz, fw = math.floor(x), math.floor(y), math.floor(z), math.floor(w)
    lx, ly, lz, lw = x - fx, y - fy, z - fz, w - fw
    cx, cy, cz, cw = int(fx), int(fy), int(fz), int(fw)
    if feature == SMOOTH_F1 and smoothness != 0.0:
        sd = sr = sg = sb = 0.0
        spx = spy = spz = spw = 0.0
        h = -1.0
        for u in range(-2, 3):
            for k in range(-2, 3):
                for j in range(-2, 3):
                    for i in range(-2, 3):
                        ox, oy, oz, ow = _cell_point4(cx + i, cy + j, cz + k, cw + u, legacy)
                        px = i + ox * randomness
                        py = j + oy * randomness
                        pz = k + oz * randomness
                        pw = u + ow * randomness
                        d = _distance4(px - lx, py - ly, pz - lz, pw - lw, metric, exponent)
                        h = 1.0 if h == -1.0 else _smoothstep01(
                            0.5 + 0.5 * (sd - d) / smoothness)
                        corr = smoothness * h * (1.0 - h)
                        sd = (1.0 - h) * sd + h * d - corr
                        corr /= 1.0 + 3.0 * smoothness
                        r, g, b = _cell_color4(cx + i, cy + j, cz + k, cw + u, legacy)
                        sr = (1.0 - h) * sr + h * r - corr
                        sg = (1.0 - h) * sg + h * g - corr
                        sb = (1.0 - h) * sb + h * b - corr
                        spx = (1.0 - h) * spx + h * px - corr
                        spy = (1.0 - h) * spy + h * py - corr
                        spz = (1.0 - h) * spz + h * pz - corr
                        spw = (1.0 - h) * spw + h * pw - corr
        return sd, sr, sg, sb, fx + spx, fy + spy, fz + spz, fw + spw
    d1 = d2 = 3.4028234663852886e38
    o1x = o1y = o1z = o1w = o2x = o2y = o2z = o2w = 0
    p1x = p1y = p1z = p1w = p2x = p2y = p2z = p2w = 0.0
    for u in range(-1, 2):
        for k in range(-1, 2):
            for j in range(-1, 2):
                for i in range(-1, 2):
                    ox, oy, oz, ow = _cell_point4(cx + i, cy + j, cz + k, cw + u, legacy)
                    px = i + ox * randomness
                    py = j + oy * randomness
                    pz = k + oz * randomness
                    pw = u + ow * randomness
                    if feature == F2:
                        d = _distance4(px - lx, py - ly, pz - lz, pw - lw, metric, exponent)
                        if d < d1:
                            d2, o2x, o2y, o2z, o2w = d1, o1x, o1y, o1z, o1w
                            p2x, p2y, p2z, p2w = p1x, p1y, p1z, p1w
                            d1, o1x, o1y, o1z, o1w = d, i, j, k, u
                            p1x, p1y, p1z, p1w = px, py, pz, pw
                        elif d < d2:
                            d2, o2x, o2y, o2z, o2w = d, i, j, k, u
                            p2x, p2y, p2z, p2w = px, py, pz, pw
                    else:
                        d = _bound4(px - lx, py - ly, pz - lz, pw - lw, metric, exponent)
                        if d < d1:
                            d1, o1x, o1y, o1z, o1w = d, i, j, k, u
                            p1x, p1y, p1z, p1w = px, py, pz, pw
    if feature == F2:
        r, g, b = _cell_color4(cx + o2x, cy + o2y, cz + o2z, cw + o2w, legacy)
        return d2, r, g, b, p2x + fx, p2y + fy, p2z + fz, p2w + fw
    d = _distance4(p1x - lx, p1y - ly, p1z - lz, p1w - lw, metric, exponent)
    r, g, b = _cell_color4(cx + o1x, cy + o1y, cz + o1z, cw + o1w, legacy)
    return d, r, g, b, p1x + fx, p1y + fy, p1z + fz, p1w + fw


@njit(**_JIT)
def distance_to_edge4(x, y, z, w, randomness, legacy):
    """Cycles' 4-D voronoi_distance_to_edge (Euclidean, whatever the metric)."""
    fx, fy, fz, fw = math.floor(x), math.floor(y), math.floor(z), math.floor(w)
    lx, ly, lz, lw = x - fx, y - fy, z - fz, w - fw
    cx, cy, cz, cw = int(fx), int(fy), int(fz), int(fw)
    vx = vy = vz = vw = 0.0
    best = 3.4028234663852886e38
    for u in range(-1, 2):
        for k in range(-1, 2):
            for j in range(-1, 2):
                for i in range(-1, 2):
                    ox, oy, oz, ow = _cell_point4(cx + i, cy + j, cz + k, cw + u, legacy)
                    tx = i + ox * randomness - lx
                    ty = j + oy * randomness - ly
                    tz = k + oz * randomness - lz
                    tw = u + ow * randomness - lw
                    d = tx * tx + ty * ty + tz * tz + tw * tw
                    if d < best:
                        best, vx, vy, vz, vw = d, tx, ty, tz, tw
    best = 3.4028234663852886e38
    for u in range(-1, 2):
        for k in range(-1, 2):
            for j in range(-1, 2):
                for i in range(-1, 2):
                    ox, oy, oz, ow = _cell_point4(cx + i, cy + j, cz + k, cw + u, legacy)
                    tx = i + ox * randomness - lx
                    ty = j + oy * randomness - ly
                    tz = k + oz * randomness - lz
                    tw = u + ow * randomness - lw
                    ex, ey, ez, ew = tx - vx, ty - vy, tz - vz, tw - vw
                    e2 = ex * ex + ey * ey + ez * ez + ew * ew
                    if e2 > 0.0001:
                        inv = 1.0 / math.sqrt(e2)
                        d = ((vx + tx) * 0.5 * ex + (vy + ty) * 0.5 * ey
                             + (vz + tz) * 0.5 * ez + (vw + tw) * 0.5 * ew) * inv
                        best = min(best, d)
    return best


@njit(**_JIT)
def n_sphere_radius4(x, y, z, w, randomness, legacy):
    """Cycles' 4-D voronoi_n_sphere_radius (as n_sphere_radius)."""
    fx, fy, fz, fw = math.floor(x), math.floor(y), math.floor(z), math.floor(w)
    lx, ly, lz, lw = x - fx, y - fy, z - fz, w - fw
    cx, cy, cz, cw = int(fx), int(fy), int(fz), int(fw)
    best = 3.4028234663852886e38
    qx = qy = qz = qw = 0.0
    oi = oj = ok = ou = 0
    for u in range(-1, 2):
        for k in range(-1, 2):
            for j in range(-1, 2):
                for i in range(-1, 2):
                    ox, oy, oz, ow = _cell_point4(cx + i, cy + j, cz + k, cw + u, legacy)
                    px, py = i + ox * randomness, j + oy * randomness
                    pz, pw = k + oz * randomness, u + ow * randomness
                    d = _distance4(px - lx, py - ly, pz - lz, pw - lw, EUCLIDEAN, 1.0)
                    if d < best:
                        best, qx, qy, qz, qw, oi, oj, ok, ou = d, px, py, pz, pw, i, j, k, u
    best = 3.4028234663852886e38
    rx = ry = rz = rw = 0.0
    for u in range(-1, 2):
        for k in range(-1, 2):
            for j in range(-1, 2):
                for i in range(-1, 2):
                    if i == 0 and j == 0 and k == 0 and u == 0:
                        continue
                    ii, jj, kk, uu = i + oi, j + oj, k + ok, u + ou
                    ox, oy, oz, ow = _cell_point4(cx + ii, cy + jj, cz + kk, cw + uu, legacy)
                    px, py = ii + ox * randomness, jj + oy * randomness
                    pz, pw = kk + oz * randomness, uu + ow * randomness
                    d = _distance4(qx - px, qy - py, qz - pz, qw - pw, EUCLIDEAN, 1.0)
                    if d < best:
                        best, rx, ry, rz, rw = d, px, py, pz, pw
    return _distance4(rx - qx, ry - qy, rz - qz, rw - qw, EUCLIDEAN, 1.0) / 2.0


# --- any dimension ---------------------------------------------------------------------------

@njit(**_JIT)
def _octave_any(x, y, z, w, dims, feature, metric, exponent, randomness, smoothness, legacy):
    """One octave in ``dims`` D: (distance, r, g, b, px, py, pz, pw), Cycles' float4
    position (1D: (0, 0, 0, w); 2D/3D: w = 0)."""
    if dims == 1:
        d, r, g, b, pw = octave1(w, feature, randomness, smoothness)
        return d, r, g, b, 0.0, 0.0, 0.0, pw
    if dims == 4:
        return octave4(x, y, z, w, feature, metric, exponent, randomness, smoothness, legacy)
    d, r, g, b, px, py, pz = octave(x, y, z, dims, feature, metric, exponent, randomness,
                                    smoothness, legacy)
    return d, r, g, b, px, py, pz, 0.0


@njit(**_JIT)
def _edge_any(x, y, z, w, dims, randomness, legacy):
    if dims == 1:
        return distance_to_edge1(w, randomness)
    if dims == 4:
        return distance_to_edge4(x, y, z, w, randomness, legacy)
    return distance_to_edge(x, y, z, dims, randomness, legacy)


@njit(**_JIT)
def voronoi_texture(x, y, z, w, dims, feature, metric, normalize, scale, detail, roughness,
                    lacunarity, smoothness, exponent, randomness, legacy=False):
    """Cycles' Voronoi Texture node at vector (x, y, z) and W (dims 1: W only, 2: x, y,
    3: x, y, z, 4: all four): (distance, r, g, b, px, py, pz, pw); the position (Position
    output px, py, pz and W output pw) is in the input's space (divided by scale);
    ``legacy``: Blender 4.x's feature points (module doc)."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = min(max(roughness, 0.0), 1.0)
    randomness = min(max(randomness, 0.0), 1.0)
    smoothness = min(max(smoothness / 2.0, 0.0), 0.5)
    x, y, z, w = x * scale, y * scale, z * scale, w * scale
    zero_input = detail == 0.0 or roughness == 0.0
    half = 0.5 + 0.5 * randomness
    if feature == N_SPHERE_RADIUS:  # one octave, no normalisation (Cycles)
        if dims == 1:
            rad = n_sphere_radius1(w, randomness)
        elif dims == 4:
            rad = n_sphere_radius4(x, y, z, w, randomness, legacy)
        else:
            rad = n_sphere_radius(x, y, z, dims, randomness, legacy)
        return rad, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if feature == DISTANCE_TO_EDGE:
        amp = 1.0
        max_amp = half
        sc = 1.0
        dist = 8.0
        for i in range(int(math.ceil(detail)) + 1):
            od = _edge_any(x * sc, y * sc, z * sc, w * sc, dims, randomness, legacy)
            if zero_input:
                dist = od
                break
            if i <= detail:
                max_amp = (1.0 - amp) * max_amp + amp * (half / sc)
                dist = (1.0 - amp) * dist + amp * min(dist, od / sc)
                sc *= lacunarity
                amp *= roughness
            else:
                rem = detail - math.floor(detail)
                if rem != 0.0:
                    lerp_amp = (1.0 - amp) * max_amp + amp * (half / sc)
                    max_amp = (1.0 - rem) * max_amp + rem * lerp_amp
                    lerp_d = (1.0 - amp) * dist + amp * min(dist, od / sc)
                    dist = (1.0 - rem) * dist + rem * min(dist, lerp_d)
        if normalize:
            dist /= max_amp
        return dist, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if dims == 1:  # Cycles' 1-D max distance ignores the metric, as its distance does
        max_distance = half
    elif dims == 4:
        max_distance = _distance4(half, half, half, half, metric, exponent)
    else:
        max_distance = _distance(half, half, half if dims == 3 else 0.0, metric, exponent)
    if feature == F2:
        max_distance *= 2.0
    amp = 1.0
    max_amp = 0.0
    sc = 1.0
    od = orr = og = ob = 0.0
    opx = opy = opz = opw = 0.0
    for i in range(int(math.ceil(detail)) + 1):
        d, r, g, b, px, py, pz, pw = _octave_any(x * sc, y * sc, z * sc, w * sc, dims,
                                                 feature, metric, exponent, randomness,
                                                 smoothness, legacy)
        if zero_input:
            max_amp = 1.0
            od, orr, og, ob, opx, opy, opz, opw = d, r, g, b, px, py, pz, pw
            break
        if i <= detail:
            max_amp += amp
            od, orr, og, ob, opx, opy, opz, opw = _octave_step(
                od, orr, og, ob, opx, opy, opz, opw, d, r, g, b, px, py, pz, pw, amp, sc, 1.0)
            sc *= lacunarity
            amp *= roughness
        else:
            rem = detail - math.floor(detail)
            if rem != 0.0:
                max_amp = (1.0 - rem) * max_amp + rem * (max_amp + amp)
                od, orr, og, ob, opx, opy, opz, opw = _octave_step(
                    od, orr, og, ob, opx, opy, opz, opw, d, r, g, b, px, py, pz, pw, amp, sc,
                    rem)
    if normalize:
        od /= max_amp * max_distance
        orr /= max_amp
        og /= max_amp
        ob /= max_amp
    if scale != 0.0:
        opx, opy, opz, opw = opx / scale, opy / scale, opz / scale, opw / scale
    else:
        opx = opy = opz = opw = 0.0
    return od, orr, og, ob, opx, opy, opz, opw


# --- 3-D F1 over a batch of points (the interpreter's instruction-major loop) --------------
#
# ``voronoi_texture``'s arithmetic for a 3-D Euclidean F1 with PCG feature points, in the
# same order at each point (bit for bit), cell by cell over the batch: each of the 27
# cells' loop over the points is inlined integer hashing and float arithmetic, which LLVM
# vectorises.

SCRATCH_ROWS = 20
"""Rows of the (SCRATCH_ROWS, n) float64 scratch ``voronoi_f1_3d_rows`` needs."""


@njit(**_JIT)
def _f1_3d_rows(X, Y, Z, sc, m, randomness, s):
    """``octave(sc X[i], sc Y[i], sc Z[i], 3, F1, EUCLIDEAN, ..., legacy=False)`` for
    i < m into scratch rows s[10:17]: distance, r, g, b, px, py, pz (rows 0-9 its own)."""
    LX, LY, LZ, FX, FY, FZ, BD, OX, OY, OZ = s[0], s[1], s[2], s[3], s[4], s[5], s[6], \
        s[7], s[8], s[9]
    D, CR, CG, CB, QX, QY, QZ = s[10], s[11], s[12], s[13], s[14], s[15], s[16]
    for i in range(m):
        x = X[i] * sc
        y = Y[i] * sc
        z = Z[i] * sc
        fx, fy, fz = math.floor(x), math.floor(y), math.floor(z)
        FX[i], FY[i], FZ[i] = fx, fy, fz
        LX[i], LY[i], LZ[i] = x - fx, y - fy, z - fz
        BD[i] = 3.4028234663852886e38
        OX[i] = OY[i] = OZ[i] = 0.0
        QX[i] = QY[i] = QZ[i] = 0.0
    for k in range(-1, 2):
        for j in range(-1, 2):
            for c in range(-1, 2):
                for i in range(m):
                    ox, oy, oz = hash_int3_to_float3(int(FX[i]) + c, int(FY[i]) + j,
                                                     int(FZ[i]) + k)
                    px = c + ox * randomness
                    py = j + oy * randomness
                    pz = k + oz * randomness
                    d = _bound(px - LX[i], py - LY[i], pz - LZ[i], EUCLIDEAN, 1.0)
                    if d < BD[i]:
                        BD[i] = d
                        OX[i], OY[i], OZ[i] = c, j, k
                        QX[i], QY[i], QZ[i] = px, py, pz
    for i in range(m):
        D[i] = _distance(QX[i] - LX[i], QY[i] - LY[i], QZ[i] - LZ[i], EUCLIDEAN, 1.0)
        CR[i], CG[i], CB[i] = hash_int3_to_float3(int(FX[i]) + int(OX[i]),
                                                  int(FY[i]) + int(OY[i]),
                                                  int(FZ[i]) + int(OZ[i]))
        QX[i] = QX[i] + FX[i]
        QY[i] = QY[i] + FY[i]
        QZ[i] = QZ[i] + FZ[i]


@njit(inline="always", **_JIT)
def _octave_step(od, orr, og, ob, opx, opy, opz, opw, d, r, g, b, px, py, pz, pw, amp, sc,
                 rem):
    """One octave of ``voronoi_texture``'s fBm: the sums (od, orr, og, ob: distance and
    colour, opx..opw: position) with the octave's (d, r, g, b, px, py, pz, pw) at amplitude
    amp and octave scale sc added; rem (float) 1.0 for a whole octave, else the fractional
    detail's last octave, the sums moved that fraction of the way to the whole octave's
    (Cycles' lerp). Returns the 8 new sums. A whole octave returns its sums as they are
    (not lerped by 1.0, which would round differently)."""
    nd = od + d * amp
    nr = orr + r * amp
    ng = og + g * amp
    nb = ob + b * amp
    nx = (1.0 - amp) * opx + amp * (px / sc)
    ny = (1.0 - amp) * opy + amp * (py / sc)
    nz = (1.0 - amp) * opz + amp * (pz / sc)
    nw = (1.0 - amp) * opw + amp * (pw / sc)
    if rem == 1.0:
        return nd, nr, ng, nb, nx, ny, nz, nw
    return ((1.0 - rem) * od + rem * nd, (1.0 - rem) * orr + rem * nr,
            (1.0 - rem) * og + rem * ng, (1.0 - rem) * ob + rem * nb,
            (1.0 - rem) * opx + rem * nx, (1.0 - rem) * opy + rem * ny,
            (1.0 - rem) * opz + rem * nz, (1.0 - rem) * opw + rem * nw)


@njit(inline="always", **_JIT)
def _octave_rows(od, orr, og, ob, opx, opy, opz, opw, s, m, amp, sc, rem):
    """``_octave_step`` at points i < m of ``voronoi_f1_3d_rows``: its sums (arrays, in
    place) with the octave in its scratch rows (``_f1_3d_rows``: distance s[10], colour
    s[11:14], position s[14:17]; W is 0)."""
    D, CR, CG, CB, QX, QY, QZ = s[10], s[11], s[12], s[13], s[14], s[15], s[16]
    for i in range(m):
        od[i], orr[i], og[i], ob[i], opx[i], opy[i], opz[i], opw[i] = _octave_step(
            od[i], orr[i], og[i], ob[i], opx[i], opy[i], opz[i], opw[i],
            D[i], CR[i], CG[i], CB[i], QX[i], QY[i], QZ[i], 0.0, amp, sc, rem)


@njit(**_JIT)
def voronoi_f1_3d_rows(x, y, z, m, scale, detail, roughness, lacunarity, randomness,
                       normalize, od, orr, og, ob, opx, opy, opz, opw, s):
    """``voronoi_texture`` of a 3-D F1 Euclidean Voronoi with PCG feature points (Blender
    5.0+) at the points (x[i], y[i], z[i]), i < m, with the same scale, detail, roughness,
    lacunarity and randomness at every point: od, orr, og, ob, opx, opy, opz, opw (>= m,)
    its distance, colour, position and W, bit for bit ``voronoi_texture``'s. The outputs
    may be x, y or z (read first); s (SCRATCH_ROWS, >= m) float64 scratch."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = min(max(roughness, 0.0), 1.0)
    randomness = min(max(randomness, 0.0), 1.0)
    X, Y, Z = s[17], s[18], s[19]
    D, CR, CG, CB, QX, QY, QZ = s[10], s[11], s[12], s[13], s[14], s[15], s[16]
    for i in range(m):
        X[i] = x[i] * scale
        Y[i] = y[i] * scale
        Z[i] = z[i] * scale
    zero_input = detail == 0.0 or roughness == 0.0
    half = 0.5 + 0.5 * randomness
    max_distance = _distance(half, half, half, EUCLIDEAN, 1.0)
    amp = 1.0
    max_amp = 0.0
    sc = 1.0
    for i in range(m):
        od[i] = orr[i] = og[i] = ob[i] = 0.0
        opx[i] = opy[i] = opz[i] = opw[i] = 0.0
    for it in range(int(math.ceil(detail)) + 1):
        _f1_3d_rows(X, Y, Z, sc, m, randomness, s)
        if zero_input:
            max_amp = 1.0
            for i in range(m):
                od[i], orr[i], og[i], ob[i] = D[i], CR[i], CG[i], CB[i]
                opx[i], opy[i], opz[i], opw[i] = QX[i], QY[i], QZ[i], 0.0
            break
        if it <= detail:
            max_amp += amp
            _octave_rows(od, orr, og, ob, opx, opy, opz, opw, s, m, amp, sc, 1.0)
            sc *= lacunarity
            amp *= roughness
        else:
            rem = detail - math.floor(detail)
            if rem != 0.0:
                max_amp = (1.0 - rem) * max_amp + rem * (max_amp + amp)
                _octave_rows(od, orr, og, ob, opx, opy, opz, opw, s, m, amp, sc, rem)
    for i in range(m):
        if normalize:
            od[i] /= max_amp * max_distance
            orr[i] /= max_amp
            og[i] /= max_amp
            ob[i] /= max_amp
        if scale != 0.0:
            opx[i], opy[i], opz[i], opw[i] = opx[i] / scale, opy[i] / scale, opz[i] / scale, \
                opw[i] / scale
        else:
            opx[i] = opy[i] = opz[i] = opw[i] = 0.0
