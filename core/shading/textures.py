"""Cycles' small procedural textures as scalar numba functions (our own code after
kernel/svm/checker.h, gradient.h, white_noise.h, wave.h, magic.h, brick.h): Checker,
Gradient, White Noise, Wave, Magic, Brick. (Noise and Voronoi have their own modules.)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401
from .hash import hash_float_to_float, hash_float2_to_float, hash_float3_to_float, \
    hash_float4_to_float, mul32
from .noise import fractal, NOISE_FBM
from .converters import clamp

_JIT = dict(cache=True, error_model="numpy")

GRADIENT_TYPES = {name: i for i, name in enumerate((
    "LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "RADIAL", "QUADRATIC_SPHERE", "SPHERICAL"))}



@njit(**_JIT)
def checker(x, y, z):
    """Cycles' svm_checker: 1 on the cells of even parity sum, 0 elsewhere."""
    x = (x + 0.000001) * 0.999999
    y = (y + 0.000001) * 0.999999
    z = (z + 0.000001) * 0.999999
    xi = abs(int(math.floor(x)))
    yi = abs(int(math.floor(y)))
    zi = abs(int(math.floor(z)))
    return 1.0 if ((xi % 2 == yi % 2) == (zi % 2 == 1)) else 0.0


@njit(**_JIT)
def gradient(kind, x, y, z):
    """Cycles' svm_gradient (GRADIENT_TYPES), saturated like the node."""
    if kind == 0:
        f = x
    elif kind == 1:
        r = max(x, 0.0)
        f = r * r
    elif kind == 2:
        r = min(max(x, 0.0), 1.0)
        t = r * r
        f = 3.0 * t - 2.0 * t * r
    elif kind == 3:
        f = (x + y) * 0.5
    elif kind == 4:
        f = math.atan2(y, x) / (2.0 * math.pi) + 0.5
    else:
        r = max(0.999999 - math.sqrt(x * x + y * y + z * z), 0.0)
        f = r * r if kind == 5 else r
    return clamp(f, 0.0, 1.0)


@njit(**_JIT)
def white_noise(dims, x, y, z, w):
    """Cycles' White Noise: (value, r, g, b) hashing the float32 bits of the input."""
    if dims == 1:
        return (hash_float_to_float(w), hash_float_to_float(w), hash_float2_to_float(w, 1.0),
                hash_float2_to_float(w, 2.0))
    if dims == 2:
        v = hash_float2_to_float(x, y)
        return v, v, hash_float3_to_float(x, y, 1.0), hash_float3_to_float(x, y, 2.0)
    if dims == 3:
        v = hash_float3_to_float(x, y, z)
        return v, v, hash_float4_to_float(x, y, z, 1.0), hash_float4_to_float(x, y, z, 2.0)
    v = hash_float4_to_float(x, y, z, w)
    return (v, v, hash_float4_to_float(z, x, w, y), hash_float4_to_float(w, z, y, x))






WAVE_TYPES = {"BANDS": 0, "RINGS": 1}
WAVE_BANDS_DIRECTIONS = {"X": 0, "Y": 1, "Z": 2, "DIAGONAL": 3}
WAVE_RINGS_DIRECTIONS = {"X": 0, "Y": 1, "Z": 2, "SPHERICAL": 3}
WAVE_PROFILES = {"SIN": 0, "SAW": 1, "TRI": 2}


@njit(**_JIT)
def wave(kind, bands_dir, rings_dir, profile, x, y, z, distortion, detail, dscale,
         droughness, phase):
    """Cycles' svm_wave at the scaled point (x, y, z)."""
    x = (x + 0.000001) * 0.999999
    y = (y + 0.000001) * 0.999999
    z = (z + 0.000001) * 0.999999
    if kind == 0:
        if bands_dir == 0:
            n = x * 20.0
        elif bands_dir == 1:
            n = y * 20.0
        elif bands_dir == 2:
            n = z * 20.0
        else:
            n = (x + y + z) * 10.0
    else:
        rx, ry, rz = x, y, z
        if rings_dir == 0:
            rx = 0.0
        elif rings_dir == 1:
            ry = 0.0
        elif rings_dir == 2:
            rz = 0.0
        n = math.sqrt(rx * rx + ry * ry + rz * rz) * 20.0
    n += phase
    if distortion != 0.0:
        f = fractal(x * dscale, y * dscale, z * dscale, 0.0, 3, detail, droughness, 2.0, 0.0,
                    0.0, NOISE_FBM, True)
        n += distortion * (f * 2.0 - 1.0)
    if profile == 0:
        return 0.5 + 0.5 * math.sin(n - math.pi / 2.0)
    n /= 2.0 * math.pi
    if profile == 1:
        return n - math.floor(n)
    return abs(n - math.floor(n + 0.5)) * 2.0


@njit(**_JIT)
def magic(x, y, z, scale, depth, distortion):
    """Cycles' svm_magic: (r, g, b)."""
    px = np.fmod(x * scale, 2.0 * math.pi)
    py = np.fmod(y * scale, 2.0 * math.pi)
    pz = np.fmod(z * scale, 2.0 * math.pi)
    a = math.sin((px + py + pz) * 5.0)
    b = math.cos((-px + py - pz) * 5.0)
    c = -math.cos((-px - py + pz) * 5.0)
    d = distortion
    if depth > 0:
        a *= d
        b *= d
        c *= d
        b = -math.cos(a - b + c) * d
        if depth > 1:
            a = math.cos(a - b - c) * d
            if depth > 2:
                c = math.sin(-a - b - c) * d
                if depth > 3:
                    a = -math.cos(-a + b - c) * d
                    if depth > 4:
                        b = -math.sin(-a + b + c) * d
                        if depth > 5:
                            b = -math.cos(-a + b + c) * d
                            if depth > 6:
                                a = math.cos(a + b + c) * d
                                if depth > 7:
                                    c = math.sin(a + b - c) * d
                                    if depth > 8:
                                        a = -math.cos(-a - b + c) * d
                                        if depth > 9:
                                            b = -math.sin(a - b + c) * d
    if d != 0.0:
        a /= 2.0 * d
        b /= 2.0 * d
        c /= 2.0 * d
    return 0.5 - a, 0.5 - b, 0.5 - c


@njit(inline="always", **_JIT)
def _brick_noise(n):
    n = (n + 1013) & 0x7FFFFFFF
    n = (n >> 13) ^ n
    inner = (mul32(mul32(n, n), 60493) + 19990303) & 0xFFFFFFFF
    nn = (mul32(n, inner) + 1376312589) & 0x7FFFFFFF
    return 0.5 * (float(nn) / 1073741824.0)


@njit(**_JIT)
def brick(x, y, mortar_size, mortar_smooth, bias, brick_width, row_height, offset_amount,
          offset_frequency, squash_amount, squash_frequency):
    """Cycles' svm_brick at the scaled point: (tint, mortar)."""
    rownum = int(math.floor(y / row_height))
    offset = 0.0
    if offset_frequency and squash_frequency:
        if rownum % squash_frequency == 0:
            brick_width *= squash_amount
        if rownum % offset_frequency == 0:
            offset = brick_width * offset_amount
    bricknum = int(math.floor((x + offset) / brick_width))
    bx = (x + offset) - brick_width * bricknum
    by = y - row_height * rownum
    key = ((rownum << 16) + (bricknum & 0xFFFF)) & 0xFFFFFFFF
    tint = clamp(_brick_noise(key) + bias, 0.0, 1.0)
    min_dist = min(min(bx, by), min(brick_width - bx, row_height - by))
    if min_dist >= mortar_size:
        mortar = 0.0
    elif mortar_smooth == 0.0:
        mortar = 1.0
    else:
        f = (1.0 - min_dist / mortar_size) / mortar_smooth
        mortar = 0.0 if f <= 0.0 else (1.0 if f >= 1.0 else (3.0 - 2.0 * f) * f * f)
    return tint, mortar

