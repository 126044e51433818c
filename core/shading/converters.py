"""Cycles' converter nodes as scalar numba functions (our own code after
kernel/svm/math_util.h, map_range.h, mapping_util.h, ramp.h and util/math.h): Math, Vector
Math, Map Range, Mapping, and the ramp / curve table lookups.

Each function takes and returns plain floats (vectors as 3 floats); the enum codes are
this module's dicts, keyed by Blender's RNA identifiers.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401

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

MAP_RANGE_TYPES = {"LINEAR": 0, "STEPPED": 1, "SMOOTHSTEP": 2, "SMOOTHERSTEP": 3}
MAPPING_TYPES = {"POINT": 0, "TEXTURE": 1, "VECTOR": 2, "NORMAL": 3}
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



LUMINANCE_REC709 = np.array([0.2126729, 0.7151522, 0.0721750], np.float32)
"""Rec.709 luminance weights (Blender's default scene-linear space); the exporter passes
the configuration's own as constants to RGB to BW."""
