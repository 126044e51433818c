"""Cycles' Voronoi Texture (kernel/svm/voronoi.h) in 2 and 3 D: F1, F2, smooth F1,
distance to edge and n-sphere radius, with the Euclidean, Manhattan, Chebychev and Minkowski metrics and the
fractal octaves (detail, roughness, lacunarity, normalize) of Blender 4.0+. Feature
points come from the PCG integer hashes (Blender 5.0+), or with ``legacy`` from lookup3
on the cell's float coordinates (Blender 4.x, before Cycles commit c24e0712c of June 2025).

A 2-D point is (x, y, 0) with a one-cell-thick search in z; the metrics then see a zero
third component, which leaves every metric unchanged.
"""

from __future__ import annotations

import math

from numba import njit

from .. import _numba_cache  # noqa: F401
from .hash import hash_int2_to_float2, hash_int3_to_float3, hash_float2_to_float, \
    hash_float3_to_float, hash_float4_to_float

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


@njit(**_JIT)
def voronoi_texture(x, y, z, dims, feature, metric, normalize, scale, detail, roughness,
                    lacunarity, smoothness, exponent, randomness, legacy=False):
    """Cycles' Voronoi Texture node at vector (x, y, z):
    (distance, r, g, b, px, py, pz); position is in the input's space (divided by scale);
    ``legacy``: Blender 4.x's feature points (module doc)."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = min(max(roughness, 0.0), 1.0)
    randomness = min(max(randomness, 0.0), 1.0)
    smoothness = min(max(smoothness / 2.0, 0.0), 0.5)
    x, y, z = x * scale, y * scale, z * scale
    zero_input = detail == 0.0 or roughness == 0.0
    half = 0.5 + 0.5 * randomness
    if feature == N_SPHERE_RADIUS:  # one octave, no normalisation (Cycles)
        return n_sphere_radius(x, y, z, dims, randomness, legacy), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if feature == DISTANCE_TO_EDGE:
        amp = 1.0
        max_amp = half
        sc = 1.0
        dist = 8.0
        for i in range(int(math.ceil(detail)) + 1):
            od = distance_to_edge(x * sc, y * sc, z * sc, dims, randomness, legacy)
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
        return dist, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    max_distance = _distance(half, half, half if dims == 3 else 0.0, metric, exponent)
    if feature == F2:
        max_distance *= 2.0
    amp = 1.0
    max_amp = 0.0
    sc = 1.0
    od = orr = og = ob = 0.0
    opx = opy = opz = 0.0
    for i in range(int(math.ceil(detail)) + 1):
        d, r, g, b, px, py, pz = octave(x * sc, y * sc, z * sc, dims, feature, metric,
                                        exponent, randomness, smoothness, legacy)
        if zero_input:
            max_amp = 1.0
            od, orr, og, ob, opx, opy, opz = d, r, g, b, px, py, pz
            break
        if i <= detail:
            max_amp += amp
            od += d * amp
            orr += r * amp
            og += g * amp
            ob += b * amp
            opx = (1.0 - amp) * opx + amp * (px / sc)
            opy = (1.0 - amp) * opy + amp * (py / sc)
            opz = (1.0 - amp) * opz + amp * (pz / sc)
            sc *= lacunarity
            amp *= roughness
        else:
            rem = detail - math.floor(detail)
            if rem != 0.0:
                max_amp = (1.0 - rem) * max_amp + rem * (max_amp + amp)
                od = (1.0 - rem) * od + rem * (od + d * amp)
                orr = (1.0 - rem) * orr + rem * (orr + r * amp)
                og = (1.0 - rem) * og + rem * (og + g * amp)
                ob = (1.0 - rem) * ob + rem * (ob + b * amp)
                opx = (1.0 - rem) * opx + rem * ((1.0 - amp) * opx + amp * (px / sc))
                opy = (1.0 - rem) * opy + rem * ((1.0 - amp) * opy + amp * (py / sc))
                opz = (1.0 - rem) * opz + rem * ((1.0 - amp) * opz + amp * (pz / sc))
    if normalize:
        od /= max_amp * max_distance
        orr /= max_amp
        og /= max_amp
        ob /= max_amp
    if scale != 0.0:
        opx, opy, opz = opx / scale, opy / scale, opz / scale
    else:
        opx = opy = opz = 0.0
    return od, orr, og, ob, opx, opy, opz
