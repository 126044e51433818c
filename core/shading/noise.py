"""Cycles' Perlin noise and its fractals (kernel/svm/noise.h, fractal_noise.h, noisetex.h):
signed Perlin noise in 1-4 D on lookup3-hashed lattice gradients, fBm and its variants
(multifractal, hybrid and ridged multifractal, hetero terrain), and the Noise Texture
node (scale, detail, roughness, lacunarity, offset, gain, distortion, normalize, colour).

Points are passed as 4 components (x, y, z, w) and a dimension count; the unused ones
are ignored. Arithmetic in float64 (Cycles uses float32: values agree to ~1e-6).
"""

from __future__ import annotations

import math

import numpy as np

from numba import njit

from .. import _numba_cache  # noqa: F401
from .hash import hash_uint, hash_uint2, hash_uint3, hash_uint4, hash_float_to_float, \
    hash_float2_to_float

_JIT = dict(cache=True, error_model="numpy")

NOISE_MULTIFRACTAL = 0
NOISE_FBM = 1
NOISE_HYBRID_MULTIFRACTAL = 2
NOISE_RIDGED_MULTIFRACTAL = 3
NOISE_HETERO_TERRAIN = 4
NOISE_TYPES = {"MULTIFRACTAL": NOISE_MULTIFRACTAL, "FBM": NOISE_FBM,
               "HYBRID_MULTIFRACTAL": NOISE_HYBRID_MULTIFRACTAL,
               "RIDGED_MULTIFRACTAL": NOISE_RIDGED_MULTIFRACTAL,
               "HETERO_TERRAIN": NOISE_HETERO_TERRAIN}
"""Blender's ``noise_type`` enum -> the NOISE_* code of the program."""


@njit(inline="always", **_JIT)
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@njit(inline="always", **_JIT)
def _neg(v, cond):
    """-v where cond is set, else v: a multiply by +-1 (exact, -0.0 included), not a
    branch: cond is a hash bit, so a branch would be mispredicted half the time."""
    return v * (1.0 - 2.0 * (cond != 0))


@njit(inline="always", **_JIT)
def _mix(a, b, t):
    return (1.0 - t) * a + t * b


@njit(inline="always", **_JIT)
def _grad1(h, x):
    h = h & 15
    g = 1.0 + (h & 7)
    return _neg(g, h & 8) * x


@njit(inline="always", **_JIT)
def _grad2(h, x, y):
    h = h & 7
    u = x if h < 4 else y
    v = 2.0 * (y if h < 4 else x)
    return _neg(u, h & 1) + _neg(v, h & 2)


@njit(inline="always", **_JIT)
def _grad3(h, x, y, z):
    h = h & 15
    u = x if h < 8 else y
    vt = x if (h == 12 or h == 14) else z
    v = y if h < 4 else vt
    return _neg(u, h & 1) + _neg(v, h & 2)


@njit(inline="always", **_JIT)
def _grad4(h, x, y, z, w):
    h = h & 31
    u = x if h < 24 else y
    v = y if h < 16 else z
    s = z if h < 8 else w
    return _neg(u, h & 1) + _neg(v, h & 2) + _neg(s, h & 4)


@njit(**_JIT)
def perlin_1d(x):
    X = int(math.floor(x))
    fx = x - math.floor(x)
    return _mix(_grad1(hash_uint(X), fx), _grad1(hash_uint(X + 1), fx - 1.0), _fade(fx))


@njit(**_JIT)
def perlin_2d(x, y):
    X = int(math.floor(x))
    Y = int(math.floor(y))
    fx = x - math.floor(x)
    fy = y - math.floor(y)
    u = _fade(fx)
    v = _fade(fy)
    x1 = 1.0 - u
    return ((1.0 - v) * (_grad2(hash_uint2(X, Y), fx, fy) * x1
                         + _grad2(hash_uint2(X + 1, Y), fx - 1.0, fy) * u)
            + v * (_grad2(hash_uint2(X, Y + 1), fx, fy - 1.0) * x1
                   + _grad2(hash_uint2(X + 1, Y + 1), fx - 1.0, fy - 1.0) * u))


@njit(inline="always", **_JIT)
def _perlin_3d_w(X, Y, Z, fx, fy, fz, u, v, w):
    x1 = 1.0 - u
    y1 = 1.0 - v
    z1 = 1.0 - w
    v0 = _grad3(hash_uint3(X, Y, Z), fx, fy, fz)
    v1 = _grad3(hash_uint3(X + 1, Y, Z), fx - 1.0, fy, fz)
    v2 = _grad3(hash_uint3(X, Y + 1, Z), fx, fy - 1.0, fz)
    v3 = _grad3(hash_uint3(X + 1, Y + 1, Z), fx - 1.0, fy - 1.0, fz)
    v4 = _grad3(hash_uint3(X, Y, Z + 1), fx, fy, fz - 1.0)
    v5 = _grad3(hash_uint3(X + 1, Y, Z + 1), fx - 1.0, fy, fz - 1.0)
    v6 = _grad3(hash_uint3(X, Y + 1, Z + 1), fx, fy - 1.0, fz - 1.0)
    v7 = _grad3(hash_uint3(X + 1, Y + 1, Z + 1), fx - 1.0, fy - 1.0, fz - 1.0)
    return (z1 * (y1 * (v0 * x1 + v1 * u) + v * (v2 * x1 + v3 * u))
            + w * (y1 * (v4 * x1 + v5 * u) + v * (v6 * x1 + v7 * u)))


# inlined, so that a loop of them over points vectorises (``_snoise3_rows``)
@njit(inline="always", **_JIT)
def perlin_3d(x, y, z):
    fx = x - math.floor(x)
    fy = y - math.floor(y)
    fz = z - math.floor(z)
    return _perlin_3d_w(int(math.floor(x)), int(math.floor(y)), int(math.floor(z)),
                        fx, fy, fz, _fade(fx), _fade(fy), _fade(fz))


@njit(**_JIT)
def _tri4(X, Y, Z, W, fx, fy, fz, fw, u, v, t):
    x1 = 1.0 - u
    y1 = 1.0 - v
    z1 = 1.0 - t
    v0 = _grad4(hash_uint4(X, Y, Z, W), fx, fy, fz, fw)
    v1 = _grad4(hash_uint4(X + 1, Y, Z, W), fx - 1.0, fy, fz, fw)
    v2 = _grad4(hash_uint4(X, Y + 1, Z, W), fx, fy - 1.0, fz, fw)
    v3 = _grad4(hash_uint4(X + 1, Y + 1, Z, W), fx - 1.0, fy - 1.0, fz, fw)
    v4 = _grad4(hash_uint4(X, Y, Z + 1, W), fx, fy, fz - 1.0, fw)
    v5 = _grad4(hash_uint4(X + 1, Y, Z + 1, W), fx - 1.0, fy, fz - 1.0, fw)
    v6 = _grad4(hash_uint4(X, Y + 1, Z + 1, W), fx, fy - 1.0, fz - 1.0, fw)
    v7 = _grad4(hash_uint4(X + 1, Y + 1, Z + 1, W), fx - 1.0, fy - 1.0, fz - 1.0, fw)
    return (z1 * (y1 * (v0 * x1 + v1 * u) + v * (v2 * x1 + v3 * u))
            + t * (y1 * (v4 * x1 + v5 * u) + v * (v6 * x1 + v7 * u)))


@njit(**_JIT)
def perlin_4d(x, y, z, w):
    X, Y, Z, W = int(math.floor(x)), int(math.floor(y)), int(math.floor(z)), int(math.floor(w))
    fx, fy, fz, fw = x - math.floor(x), y - math.floor(y), z - math.floor(z), w - math.floor(w)
    u, v, t, s = _fade(fx), _fade(fy), _fade(fz), _fade(fw)
    a = _tri4(X, Y, Z, W, fx, fy, fz, fw, u, v, t)
    b = _tri4(X, Y, Z, W + 1, fx, fy, fz, fw - 1.0, u, v, t)
    return _mix(a, b, s)


@njit(inline="always", **_JIT)
def _wrap(p):
    """Cycles' precision guard: fmod(p, 1e5) + 0.5 where |p| >= 1e6 (p itself below 1e5,
    where fmod is exact and returns p: the libm call costs a quarter of a 3-D snoise)."""
    if abs(p) < 100000.0:
        return p
    return np.fmod(p, 100000.0) + (0.5 if abs(p) >= 1000000.0 else 0.0)


@njit(**_JIT)
def snoise(x, y, z, w, dims):
    """Signed Perlin noise of Cycles' ``snoise_{dims}d``, roughly in [-1, 1]."""
    if dims == 1:
        return 0.25 * perlin_1d(_wrap(x))
    if dims == 2:
        return 0.6616 * perlin_2d(_wrap(x), _wrap(y))
    if dims == 3:
        return 0.9820 * perlin_3d(_wrap(x), _wrap(y), _wrap(z))
    return 0.8344 * perlin_4d(_wrap(x), _wrap(y), _wrap(z), _wrap(w))


@njit(**_JIT)
def fractal(x, y, z, w, dims, detail, roughness, lacunarity, offset, gain, kind, normalize):
    """One of Cycles' fractal noises (NOISE_*) at point (x, y, z, w) of ``dims`` D."""
    n_oct = int(detail)
    rmd = detail - math.floor(detail)
    if kind == NOISE_FBM:
        fscale = 1.0
        amp = 1.0
        maxamp = 0.0
        total = 0.0
        for _ in range(n_oct + 1):
            t = snoise(fscale * x, fscale * y, fscale * z, fscale * w, dims)
            total += t * amp
            maxamp += amp
            amp *= roughness
            fscale *= lacunarity
        if rmd != 0.0:
            t = snoise(fscale * x, fscale * y, fscale * z, fscale * w, dims)
            sum2 = total + t * amp
            if normalize:
                return _mix(0.5 * total / maxamp + 0.5, 0.5 * sum2 / (maxamp + amp) + 0.5, rmd)
            return _mix(total, sum2, rmd)
        return 0.5 * total / maxamp + 0.5 if normalize else total
    if kind == NOISE_MULTIFRACTAL:
        value = 1.0
        pwr = 1.0
        for _ in range(n_oct + 1):
            value *= pwr * snoise(x, y, z, w, dims) + 1.0
            pwr *= roughness
            x, y, z, w = x * lacunarity, y * lacunarity, z * lacunarity, w * lacunarity
        if rmd != 0.0:
            value *= rmd * pwr * snoise(x, y, z, w, dims) + 1.0
        return value
    if kind == NOISE_HETERO_TERRAIN:
        pwr = roughness
        value = offset + snoise(x, y, z, w, dims)
        x, y, z, w = x * lacunarity, y * lacunarity, z * lacunarity, w * lacunarity
        for _ in range(1, n_oct + 1):
            value += (snoise(x, y, z, w, dims) + offset) * pwr * value
            pwr *= roughness
            x, y, z, w = x * lacunarity, y * lacunarity, z * lacunarity, w * lacunarity
        if rmd != 0.0:
            value += rmd * ((snoise(x, y, z, w, dims) + offset) * pwr * value)
        return value
    if kind == NOISE_HYBRID_MULTIFRACTAL:
        pwr = 1.0
        value = 0.0
        weight = 1.0
        i = 0
        while weight > 0.001 and i <= n_oct:
            weight = min(weight, 1.0)
            signal = (snoise(x, y, z, w, dims) + offset) * pwr
            pwr *= roughness
            value += weight * signal
            weight *= gain * signal
            x, y, z, w = x * lacunarity, y * lacunarity, z * lacunarity, w * lacunarity
            i += 1
        if rmd != 0.0 and weight > 0.001:
            weight = min(weight, 1.0)
            signal = (snoise(x, y, z, w, dims) + offset) * pwr
            value += rmd * weight * signal
        return value
    # NOISE_RIDGED_MULTIFRACTAL
    pwr = roughness
    signal = offset - abs(snoise(x, y, z, w, dims))
    signal *= signal
    value = signal
    weight = 1.0
    for _ in range(1, n_oct + 1):
        x, y, z, w = x * lacunarity, y * lacunarity, z * lacunarity, w * lacunarity
        weight = min(max(signal * gain, 0.0), 1.0)
        signal = offset - abs(snoise(x, y, z, w, dims))
        signal *= signal
        signal *= weight
        value += signal * pwr
        pwr *= roughness
    return value


@njit(**_JIT)
def _offset(seed, axis):
    """Cycles' random_float{n}_offset component (in [100, 200]); ``axis`` < 0: 1-D form."""
    if axis < 0:
        return 100.0 + hash_float_to_float(seed) * 100.0
    return 100.0 + hash_float2_to_float(seed, float(axis)) * 100.0


@njit(**_JIT)
def noise_texture(x, y, z, w, dims, scale, detail, roughness, lacunarity, offset, gain,
                  distortion, kind, normalize, color_needed=True):
    """Cycles' Noise Texture node: (factor, r, g, b) at vector (x, y, z) and W; g and b
    are 0 unless ``color_needed`` (two more fractals, as Cycles skips them too)."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = max(roughness, 0.0)
    x, y, z, w = x * scale, y * scale, z * scale, w * scale
    if dims == 1:
        x = w  # 1-D noise reads W only
        y = z = w = 0.0
    elif dims == 2:
        z = w = 0.0
    elif dims == 3:
        w = 0.0
    if distortion != 0.0:
        if dims == 1:
            x += snoise(x + _offset(0.0, -1), 0.0, 0.0, 0.0, 1) * distortion
        else:
            dx = snoise(x + _offset(0.0, 0), y + _offset(0.0, 1), z + _offset(0.0, 2),
                        w + _offset(0.0, 3), dims) * distortion
            dy = snoise(x + _offset(1.0, 0), y + _offset(1.0, 1), z + _offset(1.0, 2),
                        w + _offset(1.0, 3), dims) * distortion
            dz = 0.0
            dw = 0.0
            if dims >= 3:
                dz = snoise(x + _offset(2.0, 0), y + _offset(2.0, 1), z + _offset(2.0, 2),
                            w + _offset(2.0, 3), dims) * distortion
            if dims == 4:
                dw = snoise(x + _offset(3.0, 0), y + _offset(3.0, 1), z + _offset(3.0, 2),
                            w + _offset(3.0, 3), dims) * distortion
            x, y, z, w = x + dx, y + dy, z + dz, w + dw
    value = fractal(x, y, z, w, dims, detail, roughness, lacunarity, offset, gain, kind,
                    normalize)
    if not color_needed:
        return value, value, 0.0, 0.0
    # the colour's seeds follow the distortion's: dims (1-D: 1, 2), dims + 1
    s1 = float(dims) if dims > 1 else 1.0
    s2 = s1 + 1.0
    if dims == 1:
        g = fractal(x + _offset(s1, -1), 0.0, 0.0, 0.0, 1, detail, roughness, lacunarity,
                    offset, gain, kind, normalize)
        b = fractal(x + _offset(s2, -1), 0.0, 0.0, 0.0, 1, detail, roughness, lacunarity,
                    offset, gain, kind, normalize)
    else:
        g = fractal(x + _offset(s1, 0), y + _offset(s1, 1), z + _offset(s1, 2),
                    w + _offset(s1, 3), dims, detail, roughness, lacunarity, offset, gain,
                    kind, normalize)
        b = fractal(x + _offset(s2, 0), y + _offset(s2, 1), z + _offset(s2, 2),
                    w + _offset(s2, 3), dims, detail, roughness, lacunarity, offset, gain,
                    kind, normalize)
    return value, value, g, b


# --- the Noise Texture over a batch of points (the interpreter's instruction-major loop) ---
#
# The same arithmetic as ``noise_texture``, in the same order at each point (bit for bit),
# but each Perlin evaluation is a loop over the batch: its body is all inlined integer and
# float arithmetic, which LLVM vectorises (AVX: 3-D snoise 65 -> 25 ns a point).

SCRATCH_ROWS = 10
"""Rows of the (SCRATCH_ROWS, n) float64 scratch ``noise_texture3_rows`` needs."""


@njit(**_JIT)
def _snoise3_rows(X, Y, Z, fscale, m, t):
    """t[i] = snoise(fscale X[i], fscale Y[i], fscale Z[i], 0, 3) for i < m. The loop
    skips Cycles' precision guard (``_wrap``: p itself below 1e5) and runs again with it
    when a coordinate of the batch is beyond."""
    far = 0
    for i in range(m):
        x = fscale * X[i]
        y = fscale * Y[i]
        z = fscale * Z[i]
        far |= (abs(x) >= 100000.0) | (abs(y) >= 100000.0) | (abs(z) >= 100000.0) \
            | (x != x) | (y != y) | (z != z)
        t[i] = 0.9820 * perlin_3d(x, y, z)
    if far:
        for i in range(m):
            t[i] = snoise(fscale * X[i], fscale * Y[i], fscale * Z[i], 0.0, 3)


@njit(**_JIT)
def _fbm3_rows(X, Y, Z, m, detail, roughness, lacunarity, normalize, total, t):
    """total[i] = fractal(X[i], Y[i], Z[i], 0, 3, detail, ..., NOISE_FBM, normalize)
    for i < m (``fractal``'s fBm, octave by octave over the batch); t scratch."""
    n_oct = int(detail)
    rmd = detail - math.floor(detail)
    fscale = 1.0
    amp = 1.0
    maxamp = 0.0
    for i in range(m):
        total[i] = 0.0
    for _ in range(n_oct + 1):
        _snoise3_rows(X, Y, Z, fscale, m, t)
        for i in range(m):
            total[i] += t[i] * amp
        maxamp += amp
        amp *= roughness
        fscale *= lacunarity
    if rmd != 0.0:
        _snoise3_rows(X, Y, Z, fscale, m, t)
        for i in range(m):
            sum2 = total[i] + t[i] * amp
            if normalize:
                total[i] = _mix(0.5 * total[i] / maxamp + 0.5,
                                0.5 * sum2 / (maxamp + amp) + 0.5, rmd)
            else:
                total[i] = _mix(total[i], sum2, rmd)
    elif normalize:
        for i in range(m):
            total[i] = 0.5 * total[i] / maxamp + 0.5


@njit(**_JIT)
def noise_texture3_rows(x, y, z, m, scale, detail, roughness, lacunarity, distortion,
                        normalize, color_needed, fac, g, b, s):
    """``noise_texture`` of a 3-D fBm Noise Texture at the points (x[i], y[i], z[i]),
    i < m, with the same scale, detail, roughness, lacunarity and distortion at every
    point: fac[i], g[i], b[i] (its factor, the colour's green and blue; red is the
    factor; g and b 0 unless ``color_needed``), bit for bit ``noise_texture``'s. x, y,
    z, fac, g, b (>= m,) float64 (fac, g, b not x, y or z); s (SCRATCH_ROWS, >= m)
    float64 scratch."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = max(roughness, 0.0)
    X, Y, Z, t = s[0], s[1], s[2], s[3]
    for i in range(m):
        X[i] = x[i] * scale
        Y[i] = y[i] * scale
        Z[i] = z[i] * scale
    if distortion != 0.0:
        OX, OY, OZ = s[4], s[5], s[6]
        for k in range(3):  # the offset of x, y and z: snoise at seeds 0, 1, 2
            o0, o1, o2 = _offset(float(k), 0), _offset(float(k), 1), _offset(float(k), 2)
            for i in range(m):
                OX[i] = X[i] + o0
                OY[i] = Y[i] + o1
                OZ[i] = Z[i] + o2
            _snoise3_rows(OX, OY, OZ, 1.0, m, t)
            d = s[7 + k]
            for i in range(m):
                d[i] = t[i] * distortion
        DX, DY, DZ = s[7], s[8], s[9]
        for i in range(m):
            X[i] = X[i] + DX[i]
            Y[i] = Y[i] + DY[i]
            Z[i] = Z[i] + DZ[i]
    _fbm3_rows(X, Y, Z, m, detail, roughness, lacunarity, normalize, fac, t)
    if not color_needed:
        for i in range(m):
            g[i] = 0.0
            b[i] = 0.0
        return
    OX, OY, OZ = s[4], s[5], s[6]
    for c in range(2):  # noise_texture's seeds s1, s2 at 3 dimensions: 3 and 4
        seed = 3.0 + c
        out = g if c == 0 else b
        o0, o1, o2 = _offset(seed, 0), _offset(seed, 1), _offset(seed, 2)
        for i in range(m):
            OX[i] = X[i] + o0
            OY[i] = Y[i] + o1
            OZ[i] = Z[i] + o2
        _fbm3_rows(OX, OY, OZ, m, detail, roughness, lacunarity, normalize, out, t)
