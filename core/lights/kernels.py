"""Scalar numba kernels of the lights: sample one direction, intersect one ray.

Each analytic light is a row of ``LightSet.params`` (float64, layout below) so that one
compiled function serves every light kind, and the integrator's fused shading kernels
can call the same code as ``lights.sample_direct``. Units and conventions: see lights.py.

A sample returns (dx, dy, dz, distance, w0, w1, w2, cos_light, ok): the unit direction
from the shading point to the light, the distance to the sampled point (inf for the sun),
weight = incident radiance / pdf (solid angle), the cosine at the light surface and
whether the sample carries light.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from ..scene.contract import LIGHT_AREA, LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN

# Layout of one row of LightSet.params.
P_POS = 0          # 3: position, metres
P_AX = 3           # 3: unit local X
P_AY = 6           # 3: unit local Y
P_AZ = 9           # 3: unit local Z (emission along -Z)
P_STRENGTH = 12    # 3: colour x power
P_RADIANCE = 15    # 3: surface radiance of area / sphere / disk / sun disc
P_RADIUS = 18
P_SPHERE = 19      # 1 = sphere, 0 = facing disk ("soft falloff")
P_SPOT = 20        # 1 = spot cone
P_COS_HALF = 21
P_SMOOTH = 22      # 1 / ((1 - cos_half) blend), inf = hard edge
P_SUN_OMC = 23     # 1 - cos(half angle)
P_SIZE_X = 24
P_SIZE_Y = 25
P_ELLIPSE = 26
P_AREA = 27
P_KIND = 28
P_COUNT = 29


@njit(cache=True, error_model="numpy")
def smoothstep(x):
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x * x * (3.0 - 2.0 * x)


@njit(cache=True, error_model="numpy")
def spot_attenuation(cos_angle, cos_half, smooth):
    """Cycles' spot falloff for the cosine between -Z and the emitted direction."""
    if np.isinf(smooth):
        return 1.0 if cos_angle > cos_half else 0.0
    return smoothstep((cos_angle - cos_half) * smooth)


@njit(cache=True, error_model="numpy")
def sin_sqr_to_one_minus_cos(s2):
    """1 - sqrt(1 - s2) without cancellation for small s2."""
    return s2 / (1.0 + np.sqrt(max(0.0, 1.0 - s2)))


@njit(cache=True, error_model="numpy")
def _sample_local(q, px, py, pz, u1, u2):
    """Point and spot lights (radius 0, facing disk or sphere)."""
    cx, cy, cz = q[P_POS], q[P_POS + 1], q[P_POS + 2]
    radius = q[P_RADIUS]
    r2 = radius * radius
    lx, ly, lz = px - cx, py - cy, pz - cz
    d2 = lx * lx + ly * ly + lz * lz
    d = np.sqrt(d2)
    if d == 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    nx, ny, nz = lx / d, ly / d, lz / d  # from the light towards the point
    sphere = q[P_SPHERE] > 0.0 and radius > 0.0
    cl = 1.0
    if sphere:
        if d2 > r2:
            omc = sin_sqr_to_one_minus_cos(r2 / d2)
            x, y, z = sampling.uniform_cone(u1, u2, omc)
            dx, dy, dz = sampling.to_world(x, y, z, -nx, -ny, -nz)
            t = d * z - np.sqrt(max(0.0, r2 - d2 + d2 * z * z))
            fac = 2.0 * np.pi * omc
        else:
            # Inside the emitter every direction sees it: uniform sphere, pdf 1 / (4 pi).
            dx, dy, dz = sampling.uniform_sphere(u1, u2)
            b = lx * dx + ly * dy + lz * dz
            t = -b + np.sqrt(max(0.0, b * b - (d2 - r2)))
            fac = 4.0 * np.pi
        w0, w1, w2 = q[P_RADIANCE] * fac, q[P_RADIANCE + 1] * fac, q[P_RADIANCE + 2] * fac
    elif radius > 0.0:
        # Cycles' "soft falloff": a disk of radius r facing the point, sampled by area.
        x, y = sampling.concentric_disk(u1, u2)
        tx, ty, tz, bx, by, bz = sampling.basis(nx, ny, nz)
        dx = cx + radius * (x * tx + y * bx) - px
        dy = cy + radius * (x * ty + y * by) - py
        dz = cz + radius * (x * tz + y * bz) - pz
        t = np.sqrt(dx * dx + dy * dy + dz * dz)
        if t == 0.0:
            return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
        dx /= t
        dy /= t
        dz /= t
        cl = -(nx * dx + ny * dy + nz * dz)
        if cl <= 0.0:
            return dx, dy, dz, t, 0.0, 0.0, 0.0, 0.0, False
        fac = cl * np.pi * r2 / (t * t)
        w0, w1, w2 = q[P_RADIANCE] * fac, q[P_RADIANCE + 1] * fac, q[P_RADIANCE + 2] * fac
    else:
        dx, dy, dz = -nx, -ny, -nz
        t = d
        inv = 1.0 / (4.0 * np.pi * d2)
        w0, w1, w2 = q[P_STRENGTH] * inv, q[P_STRENGTH + 1] * inv, q[P_STRENGTH + 2] * inv
    if q[P_SPOT] > 0.0 and (not sphere or d2 > r2):
        # Cosine between the emission axis (-Z) and the direction light -> point.
        cos_a = dx * q[P_AZ] + dy * q[P_AZ + 1] + dz * q[P_AZ + 2]
        att = spot_attenuation(cos_a, q[P_COS_HALF], q[P_SMOOTH])
        w0 *= att
        w1 *= att
        w2 *= att
        if att == 0.0:
            return dx, dy, dz, t, 0.0, 0.0, 0.0, cl, False
    return dx, dy, dz, t, w0, w1, w2, cl, t > 0.0


@njit(cache=True, error_model="numpy")
def _in_spot_cone(q, c2, vx, vy, vz, dx, dy, dz, t):
    """Whether o + t d lies in the cone of ``spot_lit_interval`` (v = o - apex)."""
    x, y, z = vx + t * dx, vy + t * dy, vz + t * dz
    along = -(x * q[P_AZ] + y * q[P_AZ + 1] + z * q[P_AZ + 2])
    return along >= 0.0 and along * along >= c2 * (x * x + y * y + z * z)


@njit(cache=True, error_model="numpy")
def _insert_breakpoint(r, t0, t1, p1, p2, p3, m):
    """(p1, p2, p3, m): the sorted breakpoints p1 <= .. (m <= 2 of them) with r inserted
    after those not above it (a stable insertion sort), when t0 < r < t1."""
    if not t0 < r < t1:
        return p1, p2, p3, m
    if m == 0:
        return r, p2, p3, 1
    if m == 1:
        if r < p1:
            return r, p1, p3, 2
        return p1, r, p3, 2
    if r < p1:
        return r, p1, p2, 3
    if r < p2:
        return p1, r, p2, 3
    return p1, p2, r, 3


@njit(cache=True, error_model="numpy")
def spot_lit_interval(q, ox, oy, oz, dx, dy, dz, t0, t1):
    """The part [a, b] of the segment o + t d (unit d), t in [t0, t1] metres, that spot
    light q can light: inside the cone of the spot's half angle about its emission axis
    -Z whose apex lies r / sin(half angle) behind the centre (r the radius), the smallest
    such cone containing the light's sphere or facing disk, so every emitted direction
    within the half angle (the only ones the spot attenuation lets through) stays in it
    (a convex cone: a line meets it in one interval). Returns (a, b, ok); ok False where
    the segment misses it. Lights that are not spots, and spots of half angle 90 degrees
    or more, give (t0, t1, True). Volume Direct samples its distances in [a, b] only."""
    c = q[P_COS_HALF]
    if q[P_SPOT] <= 0.0 or c <= 0.0:
        return t0, t1, True
    c2 = c * c
    s = q[P_RADIUS] / np.sqrt(max(1.0 - c2, 1e-30))
    # v = o - apex, apex = centre + s Z (behind the light, against the emission -Z)
    vx = ox - q[P_POS] - s * q[P_AZ]
    vy = oy - q[P_POS + 1] - s * q[P_AZ + 1]
    vz = oz - q[P_POS + 2] - s * q[P_AZ + 2]
    ad = -(dx * q[P_AZ] + dy * q[P_AZ + 1] + dz * q[P_AZ + 2])
    av = -(vx * q[P_AZ] + vy * q[P_AZ + 1] + vz * q[P_AZ + 2])
    dv = dx * vx + dy * vy + dz * vz
    vv = vx * vx + vy * vy + vz * vz
    # (a . x)^2 - c^2 |x|^2 = qa t^2 + qb t + qc along the ray; the cone's nappe a . x >= 0
    qa = ad * ad - c2
    qb = 2.0 * (ad * av - c2 * dv)
    qc = av * av - c2 * vv
    # Breakpoints of membership (the quadratic's roots, the apex plane's crossing) strictly
    # inside (t0, t1), sorted: p1 <= p2 <= p3, m of them. Scalars, not an array: this runs
    # per sample in Volume Direct's kernel.
    p1, p2, p3, m = 0.0, 0.0, 0.0, 0
    if abs(qa) > 1e-12:
        disc = qb * qb - 4.0 * qa * qc
        if disc >= 0.0:
            sq = np.sqrt(disc)
            h = -0.5 * (qb + (sq if qb >= 0.0 else -sq))
            if h != 0.0:
                p1, p2, p3, m = _insert_breakpoint(h / qa, t0, t1, p1, p2, p3, m)
                p1, p2, p3, m = _insert_breakpoint(qc / h, t0, t1, p1, p2, p3, m)
    elif qb != 0.0:
        p1, p2, p3, m = _insert_breakpoint(-qc / qb, t0, t1, p1, p2, p3, m)
    if ad != 0.0:
        p1, p2, p3, m = _insert_breakpoint(-av / ad, t0, t1, p1, p2, p3, m)
    # Test each piece between t0, p1..pm, t1 at its midpoint. With no breakpoint inside,
    # the ends in ascending order, NaN last (as numpy's sort of the two).
    lo, hi = t0, t1
    if m == 0 and (hi < lo or (np.isnan(lo) and not np.isnan(hi))):
        lo, hi = hi, lo
    a = np.inf
    b = -np.inf
    for k in range(m + 1):
        if k == m:
            end = hi
        else:
            end = p1 if k == 0 else (p2 if k == 1 else p3)
        if np.isinf(end):
            mid = lo + max(1.0, abs(lo))
        else:
            mid = 0.5 * (lo + end)
        if _in_spot_cone(q, c2, vx, vy, vz, dx, dy, dz, mid):
            a = min(a, lo)
            b = max(b, end)
        lo = end
    if not a < b:
        return t0, t1, False
    return a, b, True


@njit(cache=True, error_model="numpy")
def _sample_sun(q, u1, u2):
    omc = q[P_SUN_OMC]
    ax, ay, az = q[P_AZ], q[P_AZ + 1], q[P_AZ + 2]
    if omc > 0.0:
        x, y, z = sampling.uniform_cone(u1, u2, omc)
        dx, dy, dz = sampling.to_world(x, y, z, ax, ay, az)
        fac = 2.0 * np.pi * omc
        l0, l1, l2 = q[P_RADIANCE] * fac, q[P_RADIANCE + 1] * fac, q[P_RADIANCE + 2] * fac
        return dx, dy, dz, np.inf, l0, l1, l2, 1.0, True
    return ax, ay, az, np.inf, q[P_STRENGTH], q[P_STRENGTH + 1], q[P_STRENGTH + 2], 1.0, True


@njit(cache=True, error_model="numpy")
def _sample_area(q, px, py, pz, u1, u2):
    sx, sy = q[P_SIZE_X], q[P_SIZE_Y]
    if q[P_ELLIPSE] > 0.0:
        x, y = sampling.concentric_disk(u1, u2)
        x *= 0.5 * sx
        y *= 0.5 * sy
    else:
        x = (u1 - 0.5) * sx
        y = (u2 - 0.5) * sy
    dx = q[P_POS] + x * q[P_AX] + y * q[P_AY] - px
    dy = q[P_POS + 1] + x * q[P_AX + 1] + y * q[P_AY + 1] - py
    dz = q[P_POS + 2] + x * q[P_AX + 2] + y * q[P_AY + 2] - pz
    t = np.sqrt(dx * dx + dy * dy + dz * dz)
    if t == 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    dx /= t
    dy /= t
    dz /= t
    # One-sided: the point must lie in front (-Z side); then -D . (-Z) = D . Z > 0.
    cl = dx * q[P_AZ] + dy * q[P_AZ + 1] + dz * q[P_AZ + 2]
    if cl <= 0.0:
        return dx, dy, dz, t, 0.0, 0.0, 0.0, 0.0, False
    fac = cl * q[P_AREA] / (t * t)
    return dx, dy, dz, t, q[P_RADIANCE] * fac, q[P_RADIANCE + 1] * fac, q[P_RADIANCE + 2] * fac, cl, True


@njit(cache=True, error_model="numpy")
def sample_light(q, px, py, pz, u1, u2):
    """Sample the analytic light with parameter row q from point p (see module doc)."""
    kind = int(q[P_KIND])
    if kind == LIGHT_POINT or kind == LIGHT_SPOT:
        return _sample_local(q, px, py, pz, u1, u2)
    if kind == LIGHT_SUN:
        return _sample_sun(q, u1, u2)
    if kind == LIGHT_AREA:
        return _sample_area(q, px, py, pz, u1, u2)
    return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, False


@njit(cache=True, error_model="numpy")
def sample_triangles(cdf, prob, v0, e1, e2, nrm, area, radiance, px, py, pz, u0, u1, u2):
    """Sample the emissive triangles (picked by cdf, uniform on the triangle) from p."""
    j = sampling.pick(cdf, u0)
    b1, b2 = sampling.uniform_triangle(u1, u2)
    dx = v0[j, 0] + b1 * e1[j, 0] + b2 * e2[j, 0] - px
    dy = v0[j, 1] + b1 * e1[j, 1] + b2 * e2[j, 1] - py
    dz = v0[j, 2] + b1 * e1[j, 2] + b2 * e2[j, 2] - pz
    t = np.sqrt(dx * dx + dy * dy + dz * dz)
    if t == 0.0 or prob[j] <= 0.0:
        return 0.0, 0.0, 1.0, t, 0.0, 0.0, 0.0, 0.0, False
    dx /= t
    dy /= t
    dz /= t
    cl = abs(dx * nrm[j, 0] + dy * nrm[j, 1] + dz * nrm[j, 2])
    if cl <= 0.0:
        return dx, dy, dz, t, 0.0, 0.0, 0.0, 0.0, False
    # radiance / pdf_solid_angle with pdf_area = prob / area and dA -> dw = cos / t^2.
    fac = cl * area[j] / (prob[j] * t * t)
    return dx, dy, dz, t, radiance[j, 0] * fac, radiance[j, 1] * fac, radiance[j, 2] * fac, cl, True


@njit(cache=True, error_model="numpy")
def sample_world(l0, l1, l2, nx, ny, nz, u1, u2, sphere=False):
    """Cosine-weighted direction about unit normal n towards a uniform background; with
    ``sphere`` (a surface that transmits) about n or -n with probability 1/2 each, so the
    world behind the surface is sampled too. Returns (d (3), inf, L / pdf (3), 1, ok), pdf
    ``world_pdf``."""
    side = 1.0
    if sphere:
        if u1 < 0.5:
            u1 = 2.0 * u1
        else:
            u1, side = 2.0 * u1 - 1.0, -1.0
        u1 = min(u1, 1.0 - 1e-12)
    x, y, z = sampling.cosine_hemisphere(u1, u2)
    dx, dy, dz = sampling.to_world(x, y, z, side * nx, side * ny, side * nz)
    if z <= 0.0:
        return dx, dy, dz, np.inf, 0.0, 0.0, 0.0, 1.0, False
    fac = 2.0 * np.pi / z if sphere else np.pi / z
    return dx, dy, dz, np.inf, l0 * fac, l1 * fac, l2 * fac, 1.0, True


@njit(cache=True, error_model="numpy")
def world_pdf(nx, ny, nz, dx, dy, dz, sphere):
    """Solid-angle pdf of ``sample_world`` about n giving direction d: cos / pi on n's side
    (0 behind), or with ``sphere`` |cos| / (2 pi) on both."""
    c = nx * dx + ny * dy + nz * dz
    if sphere:
        return abs(c) / (2.0 * np.pi)
    return max(0.0, c) / np.pi


@njit(cache=True, error_model="numpy")
def intersect_light(q, ox, oy, oz, dx, dy, dz):
    """Distance along the ray to light q's surface and the radiance seen, or (inf, 0, 0, 0).

    Area lights: front face only. Point/spot: the sphere, or the disk facing the ray
    origin; radius 0 is never hit. The sun is handled by the caller (at infinity)."""
    kind = int(q[P_KIND])
    wx, wy, wz = ox - q[P_POS], oy - q[P_POS + 1], oz - q[P_POS + 2]
    azx, azy, azz = q[P_AZ], q[P_AZ + 1], q[P_AZ + 2]
    att = 1.0
    if kind == LIGHT_AREA:
        den = dx * azx + dy * azy + dz * azz
        if den <= 0.0:
            return np.inf, 0.0, 0.0, 0.0
        t = -(wx * azx + wy * azy + wz * azz) / den
        if t <= 0.0:
            return np.inf, 0.0, 0.0, 0.0
        hx, hy, hz = wx + t * dx, wy + t * dy, wz + t * dz
        lx = hx * q[P_AX] + hy * q[P_AX + 1] + hz * q[P_AX + 2]
        ly = hx * q[P_AY] + hy * q[P_AY + 1] + hz * q[P_AY + 2]
        sx, sy = q[P_SIZE_X], q[P_SIZE_Y]
        if q[P_ELLIPSE] > 0.0:
            inside = (2.0 * lx / sx) ** 2 + (2.0 * ly / sy) ** 2 <= 1.0
        else:
            inside = abs(lx) <= 0.5 * sx and abs(ly) <= 0.5 * sy
        if not inside:
            return np.inf, 0.0, 0.0, 0.0
    elif kind == LIGHT_POINT or kind == LIGHT_SPOT:
        radius = q[P_RADIUS]
        if radius <= 0.0:
            return np.inf, 0.0, 0.0, 0.0
        r2 = radius * radius
        dist2 = wx * wx + wy * wy + wz * wz
        b = wx * dx + wy * dy + wz * dz
        is_spot = kind == LIGHT_SPOT
        if is_spot and b >= 0.0:
            return np.inf, 0.0, 0.0, 0.0
        if q[P_SPHERE] > 0.0:
            # Perpendicular offset instead of b^2 - c: no cancellation far from the light.
            px, py, pz = wx - b * dx, wy - b * dy, wz - b * dz
            disc = r2 - (px * px + py * py + pz * pz)
            if disc < 0.0:
                return np.inf, 0.0, 0.0, 0.0
            sq = np.sqrt(disc)
            t = -b - sq
            if t <= 0.0:
                t = -b + sq
            if t <= 0.0:
                return np.inf, 0.0, 0.0, 0.0
            if is_spot and dist2 > r2:
                att = spot_attenuation(dx * azx + dy * azy + dz * azz, q[P_COS_HALF], q[P_SMOOTH])
        else:
            dist = np.sqrt(dist2)
            if dist == 0.0:
                return np.inf, 0.0, 0.0, 0.0
            nx, ny, nz = wx / dist, wy / dist, wz / dist
            den = dx * nx + dy * ny + dz * nz
            if den >= 0.0:
                return np.inf, 0.0, 0.0, 0.0
            t = -dist / den
            hx, hy, hz = wx + t * dx, wy + t * dy, wz + t * dz
            if hx * hx + hy * hy + hz * hz > r2:
                return np.inf, 0.0, 0.0, 0.0
            if is_spot:
                att = spot_attenuation(dx * azx + dy * azy + dz * azz, q[P_COS_HALF], q[P_SMOOTH])
    else:
        return np.inf, 0.0, 0.0, 0.0
    return t, q[P_RADIANCE] * att, q[P_RADIANCE + 1] * att, q[P_RADIANCE + 2] * att


@njit(cache=True, error_model="numpy")
def light_pdf(q, px, py, pz, dx, dy, dz, t):
    """Solid-angle pdf (1/sr) with which ``sample_light(q, p, ...)`` produces the unit
    direction d whose ray from p meets the light's surface at distance t (metres), the
    hit ``intersect_light`` reports. 0 for the delta lights (radius 0, sun of angle 0),
    which no ray hits. Used for multiple importance sampling: a BSDF-sampled ray that
    hits a light weighs its radiance against this pdf."""
    kind = int(q[P_KIND])
    if kind == LIGHT_AREA:
        cl = dx * q[P_AZ] + dy * q[P_AZ + 1] + dz * q[P_AZ + 2]
        if cl <= 0.0 or q[P_AREA] <= 0.0:
            return 0.0
        return t * t / (cl * q[P_AREA])
    if kind == LIGHT_SUN:
        omc = q[P_SUN_OMC]
        return 1.0 / (2.0 * np.pi * omc) if omc > 0.0 else 0.0
    if kind == LIGHT_POINT or kind == LIGHT_SPOT:
        radius = q[P_RADIUS]
        if radius <= 0.0:
            return 0.0
        r2 = radius * radius
        lx, ly, lz = px - q[P_POS], py - q[P_POS + 1], pz - q[P_POS + 2]
        d2 = lx * lx + ly * ly + lz * lz
        if q[P_SPHERE] > 0.0:
            if d2 <= r2:
                return 1.0 / (4.0 * np.pi)
            return 1.0 / (2.0 * np.pi * sin_sqr_to_one_minus_cos(r2 / d2))
        d = np.sqrt(d2)
        if d == 0.0:
            return 0.0
        # The disk faces the shading point: its normal is (p - c) / |p - c|.
        cl = -(dx * lx + dy * ly + dz * lz) / d
        if cl <= 0.0:
            return 0.0
        return t * t / (cl * np.pi * r2)
    return 0.0


@njit(cache=True, error_model="numpy")
def triangle_pdf(prob, area, j, dx, dy, dz, nx, ny, nz, t):
    """Solid-angle pdf (1/sr) with which ``sample_triangles`` produces the direction d
    towards emissive triangle j (unit normal n, seen at distance t metres): the pick
    probability over the area, times t^2 / |cos| at the triangle."""
    cl = abs(dx * nx + dy * ny + dz * nz)
    if cl <= 0.0 or area[j] <= 0.0:
        return 0.0
    return prob[j] * t * t / (area[j] * cl)


@njit(cache=True, error_model="numpy")
def power_heuristic(n_f, pdf_f, n_g, pdf_g):
    """Veach's power heuristic (beta = 2): the weight of technique f, taking n_f samples of
    pdf pdf_f, against technique g (n_g samples of pdf_g). 1 where g cannot produce the
    sample (pdf_g = 0), 0 where f cannot."""
    a = n_f * pdf_f
    b = n_g * pdf_g
    if b <= 0.0:
        return 1.0 if a > 0.0 else 0.0
    return a * a / (a * a + b * b)
