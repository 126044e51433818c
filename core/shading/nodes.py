"""Cycles' converter, colour and small texture nodes as scalar numba functions (our own
code after kernel/svm/math_util.h, color_util.h, map_range.h, mapping_util.h, ramp.h,
checker.h, gradient.h, white_noise.h and util/color.h, util/math.h).

Each function takes and returns plain floats (vectors and colours as 3 floats); the enum
codes are this module's dicts, keyed by Blender's RNA identifiers.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401
from .hash import hash_float_to_float, hash_float2_to_float, hash_float3_to_float, \
    hash_float4_to_float, mul32
from .noise import fractal, NOISE_FBM

_JIT = dict(cache=True, error_model="numpy")

MATH_OPS = {name: i for i, name in enumerate((
    "ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "MULTIPLY_ADD", "POWER", "LOGARITHM", "SQRT",
    "INVERSE_SQRT", "ABSOLUTE", "EXPONENT", "MINIMUM", "MAXIMUM", "LESS_THAN",
    "GREATER_THAN", "SIGN", "COMPARE", "SMOOTH_MIN", "SMOOTH_MAX", "ROUND", "FLOOR", "CEIL",
    "TRUNC", "FRACT", "MODULO", "FLOORED_MODULO", "WRAP", "SNAP", "PINGPONG", "SINE",
    "COSINE", "TANGENT", "ARCSINE", "ARCCOSINE", "ARCTANGENT", "ARCTAN2", "SINH", "COSH",
    "TANH", "RADIANS", "DEGREES"))}
"""ShaderNodeMath.operation -> code."""

VECTOR_MATH_OPS = {name: i for i, name in enumerate((
    "ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "MULTIPLY_ADD", "CROSS_PRODUCT", "PROJECT",
    "REFLECT", "REFRACT", "FACEFORWARD", "DOT_PRODUCT", "DISTANCE", "LENGTH", "SCALE",
    "NORMALIZE", "ABSOLUTE", "POWER", "SIGN", "MINIMUM", "MAXIMUM", "FLOOR", "CEIL",
    "FRACTION", "MODULO", "WRAP", "SNAP", "SINE", "COSINE", "TANGENT"))}
"""ShaderNodeVectorMath.operation -> code (ROUND is read as FLOOR(a + 0.5) below)."""
VECTOR_MATH_OPS["ROUND"] = len(VECTOR_MATH_OPS)
VECTOR_MATH_SCALAR_OUT = {"DOT_PRODUCT", "DISTANCE", "LENGTH"}

BLEND_TYPES = {name: i for i, name in enumerate((
    "MIX", "DARKEN", "MULTIPLY", "BURN", "LIGHTEN", "SCREEN", "DODGE", "ADD", "OVERLAY",
    "SOFT_LIGHT", "LINEAR_LIGHT", "DIFFERENCE", "EXCLUSION", "SUBTRACT", "DIVIDE", "HUE",
    "SATURATION", "COLOR", "VALUE"))}
"""ShaderNodeMix.blend_type (and MixRGB's) -> code."""

MAP_RANGE_TYPES = {"LINEAR": 0, "STEPPED": 1, "SMOOTHSTEP": 2, "SMOOTHERSTEP": 3}
MAPPING_TYPES = {"POINT": 0, "TEXTURE": 1, "VECTOR": 2, "NORMAL": 3}
GRADIENT_TYPES = {name: i for i, name in enumerate((
    "LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "RADIAL", "QUADRATIC_SPHERE", "SPHERICAL"))}


# --- scalar helpers (util/math.h) ------------------------------------------------------

@njit(inline="always", **_JIT)
def safe_divide(a, b):
    return a / b if b != 0.0 else 0.0


@njit(inline="always", **_JIT)
def safe_powf(a, b):
    if a < 0.0 and b != float(int(b)):
        return 0.0
    if b == 0.0:
        return 1.0
    if a == 0.0:
        return 0.0
    return a ** b


@njit(inline="always", **_JIT)
def _signf(a):
    if a == 0.0:
        return 0.0
    return -1.0 if a < 0.0 else 1.0


@njit(inline="always", **_JIT)
def _smoothmin(a, b, k):
    if k != 0.0:
        h = max(k - abs(a - b), 0.0) / k
        return min(a, b) - h * h * h * k * (1.0 / 6.0)
    return min(a, b)


@njit(inline="always", **_JIT)
def _fmod(a, b):
    return np.fmod(a, b) if b != 0.0 else 0.0


@njit(inline="always", **_JIT)
def _wrapf(value, vmax, vmin):
    r = vmax - vmin
    return value - r * math.floor((value - vmin) / r) if r != 0.0 else vmin


@njit(inline="always", **_JIT)
def clamp(x, lo, hi):
    return min(max(x, lo), hi)


@njit(**_JIT)
def math_op(op, a, b, c):
    """ShaderNodeMath: operation ``op`` (MATH_OPS) on inputs a, b, c."""
    if op == 0:
        return a + b
    if op == 1:
        return a - b
    if op == 2:
        return a * b
    if op == 3:
        return safe_divide(a, b)
    if op == 4:
        return a * b + c
    if op == 5:
        return safe_powf(a, b)
    if op == 6:
        return 0.0 if (a <= 0.0 or b <= 0.0) else safe_divide(math.log(a), math.log(b))
    if op == 7:
        return math.sqrt(max(a, 0.0))
    if op == 8:
        return 1.0 / math.sqrt(a) if a > 0.0 else 0.0
    if op == 9:
        return abs(a)
    if op == 10:
        return math.exp(a)
    if op == 11:
        return min(a, b)
    if op == 12:
        return max(a, b)
    if op == 13:
        return 1.0 if a < b else 0.0
    if op == 14:
        return 1.0 if a > b else 0.0
    if op == 15:
        return _signf(a)
    if op == 16:
        return 1.0 if (a == b or abs(a - b) <= max(c, 1.1920928955078125e-07)) else 0.0
    if op == 17:
        return _smoothmin(a, b, c)
    if op == 18:
        return -_smoothmin(-a, -b, c)
    if op == 19:
        return math.floor(a + 0.5)
    if op == 20:
        return math.floor(a)
    if op == 21:
        return math.ceil(a)
    if op == 22:
        return math.floor(a) if a >= 0.0 else math.ceil(a)
    if op == 23:
        return a - math.floor(a)
    if op == 24:
        return _fmod(a, b)
    if op == 25:
        return a - math.floor(a / b) * b if b != 0.0 else 0.0
    if op == 26:
        return _wrapf(a, b, c)
    if op == 27:
        return math.floor(safe_divide(a, b)) * b
    if op == 28:
        if b == 0.0:
            return 0.0
        t = (a - b) / (b * 2.0)
        return abs((t - math.floor(t)) * b * 2.0 - b)
    if op == 29:
        return math.sin(a)
    if op == 30:
        return math.cos(a)
    if op == 31:
        return math.tan(a)
    if op == 32:
        return math.asin(clamp(a, -1.0, 1.0))
    if op == 33:
        return math.acos(clamp(a, -1.0, 1.0))
    if op == 34:
        return math.atan(a)
    if op == 35:
        return 0.0 if (a == 0.0 and b == 0.0) else math.atan2(a, b)
    if op == 36:
        return math.sinh(a)
    if op == 37:
        return math.cosh(a)
    if op == 38:
        return math.tanh(a)
    if op == 39:
        return a * (math.pi / 180.0)
    if op == 40:
        return a * (180.0 / math.pi)
    return 0.0


@njit(**_JIT)
def vector_math(op, ax, ay, az, bx, by, bz, cx, cy, cz, s):
    """ShaderNodeVectorMath: (vx, vy, vz, value) of operation ``op`` (VECTOR_MATH_OPS)
    on vectors a, b, c and the Scale input s."""
    if op == 0:
        return ax + bx, ay + by, az + bz, 0.0
    if op == 1:
        return ax - bx, ay - by, az - bz, 0.0
    if op == 2:
        return ax * bx, ay * by, az * bz, 0.0
    if op == 3:
        return safe_divide(ax, bx), safe_divide(ay, by), safe_divide(az, bz), 0.0
    if op == 4:
        return ax * bx + cx, ay * by + cy, az * bz + cz, 0.0
    if op == 5:
        return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx, 0.0
    if op == 6:
        l2 = bx * bx + by * by + bz * bz
        if l2 == 0.0:
            return 0.0, 0.0, 0.0, 0.0
        f = (ax * bx + ay * by + az * bz) / l2
        return f * bx, f * by, f * bz, 0.0
    if op == 7 or op == 8:
        ln = math.sqrt(bx * bx + by * by + bz * bz)
        if ln != 0.0:
            bx, by, bz = bx / ln, by / ln, bz / ln
        d = ax * bx + ay * by + az * bz
        if op == 7:
            return ax - 2.0 * bx * d, ay - 2.0 * by * d, az - 2.0 * bz * d, 0.0
        k = 1.0 - s * s * (1.0 - d * d)
        if k < 0.0:
            return 0.0, 0.0, 0.0, 0.0
        f = s * d + math.sqrt(k)
        return s * ax - f * bx, s * ay - f * by, s * az - f * bz, 0.0
    if op == 9:
        if cx * bx + cy * by + cz * bz < 0.0:
            return ax, ay, az, 0.0
        return -ax, -ay, -az, 0.0
    if op == 10:
        return 0.0, 0.0, 0.0, ax * bx + ay * by + az * bz
    if op == 11:
        dx, dy, dz = ax - bx, ay - by, az - bz
        return 0.0, 0.0, 0.0, math.sqrt(dx * dx + dy * dy + dz * dz)
    if op == 12:
        return 0.0, 0.0, 0.0, math.sqrt(ax * ax + ay * ay + az * az)
    if op == 13:
        return ax * s, ay * s, az * s, 0.0
    if op == 14:
        ln = math.sqrt(ax * ax + ay * ay + az * az)
        if ln == 0.0:
            return ax, ay, az, 0.0
        return ax / ln, ay / ln, az / ln, 0.0
    if op == 15:
        return abs(ax), abs(ay), abs(az), 0.0
    if op == 16:
        return safe_powf(ax, bx), safe_powf(ay, by), safe_powf(az, bz), 0.0
    if op == 17:
        return _signf(ax), _signf(ay), _signf(az), 0.0
    if op == 18:
        return min(ax, bx), min(ay, by), min(az, bz), 0.0
    if op == 19:
        return max(ax, bx), max(ay, by), max(az, bz), 0.0
    if op == 20:
        return math.floor(ax), math.floor(ay), math.floor(az), 0.0
    if op == 21:
        return math.ceil(ax), math.ceil(ay), math.ceil(az), 0.0
    if op == 22:
        return ax - math.floor(ax), ay - math.floor(ay), az - math.floor(az), 0.0
    if op == 23:
        return _fmod(ax, bx), _fmod(ay, by), _fmod(az, bz), 0.0
    if op == 24:
        return (math_op(25, ax - cx, bx - cx, 0.0) + cx, math_op(25, ay - cy, by - cy, 0.0) + cy,
                math_op(25, az - cz, bz - cz, 0.0) + cz, 0.0)
    if op == 25:
        return (math.floor(safe_divide(ax, bx)) * bx, math.floor(safe_divide(ay, by)) * by,
                math.floor(safe_divide(az, bz)) * bz, 0.0)
    if op == 26:
        return math.sin(ax), math.sin(ay), math.sin(az), 0.0
    if op == 27:
        return math.cos(ax), math.cos(ay), math.cos(az), 0.0
    if op == 28:
        return math.tan(ax), math.tan(ay), math.tan(az), 0.0
    if op == 29:
        return math.floor(ax + 0.5), math.floor(ay + 0.5), math.floor(az + 0.5), 0.0
    return 0.0, 0.0, 0.0, 0.0


# --- colour (util/color.h, svm/color_util.h) -------------------------------------------

@njit(**_JIT)
def rgb_to_hsv(r, g, b):
    cmax = max(r, max(g, b))
    cmin = min(r, min(g, b))
    cdelta = cmax - cmin
    v = cmax
    s = cdelta / cmax if cmax != 0.0 else 0.0
    h = 0.0
    if s != 0.0:
        cr, cg, cb = (cmax - r) / cdelta, (cmax - g) / cdelta, (cmax - b) / cdelta
        if r == cmax:
            h = cb - cg
        elif g == cmax:
            h = 2.0 + cr - cb
        else:
            h = 4.0 + cg - cr
        h /= 6.0
        if h < 0.0:
            h += 1.0
    return h, s, v


@njit(**_JIT)
def hsv_to_rgb(h, s, v):
    if s == 0.0:
        return v, v, v
    if h == 1.0:
        h = 0.0
    h *= 6.0
    i = math.floor(h)
    f = h - i
    p = v * (1.0 - s)
    q = v * (1.0 - (s * f))
    t = v * (1.0 - (s * (1.0 - f)))
    if i == 0.0:
        return v, t, p
    if i == 1.0:
        return q, v, p
    if i == 2.0:
        return p, v, t
    if i == 3.0:
        return p, q, v
    if i == 4.0:
        return t, p, v
    return v, p, q


@njit(inline="always", **_JIT)
def _lerp(a, b, t):
    return a + t * (b - a)


@njit(inline="always", **_JIT)
def _overlay(t, a, b):
    if a < 0.5:
        return a * ((1.0 - t) + 2.0 * t * b)
    return 1.0 - ((1.0 - t) + 2.0 * t * (1.0 - b)) * (1.0 - a)


@njit(inline="always", **_JIT)
def _div(t, a, b):
    return (1.0 - t) * a + t * a / b if b != 0.0 else a


@njit(inline="always", **_JIT)
def _dodge(t, a, b):
    if a == 0.0:
        return a
    tmp = 1.0 - t * b
    if tmp <= 0.0:
        return 1.0
    tmp = a / tmp
    return 1.0 if tmp > 1.0 else tmp


@njit(inline="always", **_JIT)
def _burn(t, a, b):
    tmp = (1.0 - t) + t * b
    if tmp <= 0.0:
        return 0.0
    tmp = 1.0 - (1.0 - a) / tmp
    return clamp(tmp, 0.0, 1.0)


@njit(**_JIT)
def blend(mode, t, r1, g1, b1, r2, g2, b2):
    """Cycles' svm_mix: colour 1 and 2 blended by mode (BLEND_TYPES) with factor t."""
    if mode == 0:  # MIX (end-value preserving)
        if t == 0.0:
            return r1, g1, b1
        if t == 1.0:
            return r2, g2, b2
        return ((1.0 - t) * r1 + t * r2, (1.0 - t) * g1 + t * g2, (1.0 - t) * b1 + t * b2)
    if mode == 1:
        return _lerp(r1, min(r1, r2), t), _lerp(g1, min(g1, g2), t), _lerp(b1, min(b1, b2), t)
    if mode == 2:
        return (r1 * ((1.0 - t) + t * r2), g1 * ((1.0 - t) + t * g2), b1 * ((1.0 - t) + t * b2))
    if mode == 3:
        return _burn(t, r1, r2), _burn(t, g1, g2), _burn(t, b1, b2)
    if mode == 4:
        return _lerp(r1, max(r1, r2), t), _lerp(g1, max(g1, g2), t), _lerp(b1, max(b1, b2), t)
    if mode == 5:
        tm = 1.0 - t
        return (1.0 - (tm + t * (1.0 - r2)) * (1.0 - r1), 1.0 - (tm + t * (1.0 - g2)) * (1.0 - g1),
                1.0 - (tm + t * (1.0 - b2)) * (1.0 - b1))
    if mode == 6:
        return _dodge(t, r1, r2), _dodge(t, g1, g2), _dodge(t, b1, b2)
    if mode == 7:
        return r1 + t * r2, g1 + t * g2, b1 + t * b2
    if mode == 8:
        return _overlay(t, r1, r2), _overlay(t, g1, g2), _overlay(t, b1, b2)
    if mode == 9:
        tm = 1.0 - t
        sr = 1.0 - (1.0 - r2) * (1.0 - r1)
        sg = 1.0 - (1.0 - g2) * (1.0 - g1)
        sb = 1.0 - (1.0 - b2) * (1.0 - b1)
        return (tm * r1 + t * ((1.0 - r1) * r2 * r1 + r1 * sr),
                tm * g1 + t * ((1.0 - g1) * g2 * g1 + g1 * sg),
                tm * b1 + t * ((1.0 - b1) * b2 * b1 + b1 * sb))
    if mode == 10:
        return r1 + t * (2.0 * r2 - 1.0), g1 + t * (2.0 * g2 - 1.0), b1 + t * (2.0 * b2 - 1.0)
    if mode == 11:
        return (_lerp(r1, abs(r1 - r2), t), _lerp(g1, abs(g1 - g2), t),
                _lerp(b1, abs(b1 - b2), t))
    if mode == 12:
        return (max(_lerp(r1, r1 + r2 - 2.0 * r1 * r2, t), 0.0),
                max(_lerp(g1, g1 + g2 - 2.0 * g1 * g2, t), 0.0),
                max(_lerp(b1, b1 + b2 - 2.0 * b1 * b2, t), 0.0))
    if mode == 13:
        return r1 - t * r2, g1 - t * g2, b1 - t * b2
    if mode == 14:
        return _div(t, r1, r2), _div(t, g1, g2), _div(t, b1, b2)
    if mode == 15 or mode == 17:  # HUE, COLOR
        h2, s2, v2 = rgb_to_hsv(r2, g2, b2)
        if s2 == 0.0:
            return r1, g1, b1
        h, s, v = rgb_to_hsv(r1, g1, b1)
        h = h2
        if mode == 17:
            s = s2
        tr, tg, tb = hsv_to_rgb(h, s, v)
        return _lerp(r1, tr, t), _lerp(g1, tg, t), _lerp(b1, tb, t)
    if mode == 16:
        h, s, v = rgb_to_hsv(r1, g1, b1)
        if s == 0.0:
            return r1, g1, b1
        h2, s2, v2 = rgb_to_hsv(r2, g2, b2)
        return hsv_to_rgb(h, (1.0 - t) * s + t * s2, v)
    if mode == 18:
        h, s, v = rgb_to_hsv(r1, g1, b1)
        h2, s2, v2 = rgb_to_hsv(r2, g2, b2)
        return hsv_to_rgb(h, s, (1.0 - t) * v + t * v2)
    return 0.0, 0.0, 0.0


# --- Map Range, Mapping ------------------------------------------------------------------

@njit(inline="always", **_JIT)
def _smoothstep(e0, e1, x):
    if x < e0:
        return 0.0
    if x >= e1:
        return 1.0
    t = (x - e0) / (e1 - e0)
    return (3.0 - 2.0 * t) * (t * t)


@njit(inline="always", **_JIT)
def _smootherstep(e0, e1, x):
    x = clamp(safe_divide(x - e0, e1 - e0), 0.0, 1.0)
    return x * x * x * (x * (x * 6.0 - 15.0) + 10.0)


@njit(**_JIT)
def map_range(kind, use_clamp, value, from_min, from_max, to_min, to_max, steps):
    """Float Map Range (MAP_RANGE_TYPES), with Cycles' Clamp of kind RANGE after it for
    the linear and stepped types when ``use_clamp``."""
    if from_max == from_min:
        result = 0.0
    else:
        f = (value - from_min) / (from_max - from_min)
        if kind == 1:
            f = math.floor(f * (steps + 1.0)) / steps if steps > 0.0 else 0.0
        elif kind == 2:
            f = (1.0 - _smoothstep(from_max, from_min, value) if from_min > from_max
                 else _smoothstep(from_min, from_max, value))
        elif kind == 3:
            f = (1.0 - _smootherstep(from_max, from_min, value) if from_min > from_max
                 else _smootherstep(from_min, from_max, value))
        result = to_min + f * (to_max - to_min)
    if use_clamp and kind <= 1:
        result = clamp(result, to_max, to_min) if to_min > to_max else \
            clamp(result, to_min, to_max)
    return result


@njit(**_JIT)
def vector_map_range_1(kind, use_clamp, value, from_min, from_max, to_min, to_max, steps):
    """One component of the vector Map Range (safe division; no clamp for the smooth
    types)."""
    f = safe_divide(value - from_min, from_max - from_min)
    if kind == 1:
        f = math.floor(f * (steps + 1.0)) / steps if steps > 0.0 else 0.0
    elif kind == 2:
        f = clamp(f, 0.0, 1.0)
        f = (3.0 - 2.0 * f) * (f * f)
    elif kind == 3:
        f = clamp(f, 0.0, 1.0)
        f = f * f * f * (f * (f * 6.0 - 15.0) + 10.0)
    result = to_min + f * (to_max - to_min)
    if use_clamp and kind <= 1:
        result = clamp(result, to_max, to_min) if to_min > to_max else \
            clamp(result, to_min, to_max)
    return result


@njit(**_JIT)
def mapping(kind, vx, vy, vz, lx, ly, lz, rx, ry, rz, sx, sy, sz):
    """ShaderNodeMapping (MAPPING_TYPES): Euler XYZ rotation as Cycles'
    euler_to_transform."""
    cx, cy, cz = math.cos(rx), math.cos(ry), math.cos(rz)
    snx, sny, snz = math.sin(rx), math.sin(ry), math.sin(rz)
    # rows of the rotation matrix R (transform_direction computes R @ v)
    m00, m01, m02 = cy * cz, sny * snx * cz - cx * snz, sny * cx * cz + snx * snz
    m10, m11, m12 = cy * snz, sny * snx * snz + cx * cz, sny * cx * snz - snx * cz
    m20, m21, m22 = -sny, cy * snx, cy * cx
    if kind == 1:  # TEXTURE: R^T (v - location) / scale
        ux, uy, uz = vx - lx, vy - ly, vz - lz
        ox = m00 * ux + m10 * uy + m20 * uz
        oy = m01 * ux + m11 * uy + m21 * uz
        oz = m02 * ux + m12 * uy + m22 * uz
        return safe_divide(ox, sx), safe_divide(oy, sy), safe_divide(oz, sz)
    if kind == 3:  # NORMAL
        ux, uy, uz = safe_divide(vx, sx), safe_divide(vy, sy), safe_divide(vz, sz)
    else:
        ux, uy, uz = vx * sx, vy * sy, vz * sz
    ox = m00 * ux + m01 * uy + m02 * uz
    oy = m10 * ux + m11 * uy + m12 * uz
    oz = m20 * ux + m21 * uy + m22 * uz
    if kind == 0:
        return ox + lx, oy + ly, oz + lz
    if kind == 3:
        ln = math.sqrt(ox * ox + oy * oy + oz * oz)
        if ln != 0.0:
            return ox / ln, oy / ln, oz / ln
    return ox, oy, oz


@njit(**_JIT)
def ramp_lookup(table, first, size, f, interpolate, channel):
    """Cycles' rgb_ramp_lookup on rows [first, first + size) of a (T, 4) table, without
    extrapolation: f clamped to [0, 1], linear between rows unless not ``interpolate``."""
    f = clamp(f, 0.0, 1.0) * (size - 1)
    i = min(max(int(f), 0), size - 1)
    t = f - i
    a = table[first + i, channel]
    if interpolate and t > 0.0:
        a = (1.0 - t) * a + t * table[first + i + 1, channel]
    return a


@njit(**_JIT)
def curve_lookup(table, first, size, f, channel):
    """Cycles' float_ramp_lookup with extrapolation, the table spanning [0, 1] of the
    curve's x range (the exporter remaps x into it)."""
    if f < 0.0 or f > 1.0:
        if f < 0.0:
            t0 = table[first, channel]
            dy = t0 - table[first + 1, channel]
            f = -f
        else:
            t0 = table[first + size - 1, channel]
            dy = t0 - table[first + size - 2, channel]
            f = f - 1.0
        return t0 + dy * f * (size - 1)
    return ramp_lookup(table, first, size, f, True, channel)


# --- small textures -----------------------------------------------------------------------

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


LUMINANCE_REC709 = np.array([0.2126729, 0.7151522, 0.0721750], np.float32)
"""Rec.709 luminance weights (Blender's default scene-linear space); the exporter passes
the configuration's own as constants to RGB to BW."""


# --- Wave, Magic, Brick, Blackbody (svm/wave.h, magic.h, brick.h, math_util.h) ----------

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


_BB_R = np.array([
    [1.61919106e+03, -2.05010916e-03, 5.02995757e+00],
    [2.48845471e+03, -1.11330907e-03, 3.22621544e+00],
    [3.34143193e+03, -4.86551192e-04, 1.76486769e+00],
    [4.09461742e+03, -1.27446582e-04, 7.25731635e-01],
    [4.67028036e+03, 2.91258199e-05, 1.26703442e-01],
    [4.59509185e+03, 2.87495649e-05, 1.50345020e-01],
    [3.78717450e+03, 9.35907826e-06, 3.99075871e-01]])
_BB_G = np.array([
    [-4.88999748e+02, 6.04330754e-04, -7.55807526e-02],
    [-7.55994277e+02, 3.16730098e-04, 4.78306139e-01],
    [-1.02363977e+03, 1.20223470e-04, 9.36662319e-01],
    [-1.26571316e+03, 4.87340896e-06, 1.27054498e+00],
    [-1.42529332e+03, -4.01150431e-05, 1.43972784e+00],
    [-1.17554822e+03, -2.16378048e-05, 1.30408023e+00],
    [-5.00799571e+02, -4.59832026e-06, 1.09098763e+00]])
_BB_B = np.array([
    [5.96945309e-11, -4.85742887e-08, -9.70622247e-05, -4.07936148e-03],
    [2.40430366e-11, 5.55021075e-08, -1.98503712e-04, 2.89312858e-02],
    [-1.40949732e-11, 1.89878968e-07, -3.56632824e-04, 9.10767778e-02],
    [-3.61460868e-11, 2.84822009e-07, -4.93211319e-04, 1.56723440e-01],
    [-1.97075738e-11, 1.75359352e-07, -2.50542825e-04, -2.22783266e-02],
    [-1.61997957e-13, -1.64216008e-08, 3.86216271e-04, -7.38077418e-01],
    [6.72650283e-13, -2.73078809e-08, 4.24098264e-04, -7.52335691e-01]])
"""Cycles' blackbody fit (kernel/tables.h): Rec.709 colour of temperature t in 800-12000 K."""


@njit(**_JIT)
def blackbody_rec709(t):
    """Cycles' svm_math_blackbody_color_rec709 (not clamped; the node clamps at 0)."""
    if t >= 12000.0:
        return 0.8262954810464208, 0.9945080501520986, 1.566307710274283
    if t < 800.0:
        return 5.413294490189271, -0.20319390035873933, -0.0822535242887164
    if t >= 6365.0:
        i = 6
    elif t >= 3315.0:
        i = 5
    elif t >= 1902.0:
        i = 4
    elif t >= 1449.0:
        i = 3
    elif t >= 1167.0:
        i = 2
    elif t >= 965.0:
        i = 1
    else:
        i = 0
    inv = 1.0 / t
    return (_BB_R[i, 0] * inv + _BB_R[i, 1] * t + _BB_R[i, 2],
            _BB_G[i, 0] * inv + _BB_G[i, 1] * t + _BB_G[i, 2],
            ((_BB_B[i, 0] * t + _BB_B[i, 1]) * t + _BB_B[i, 2]) * t + _BB_B[i, 3])
