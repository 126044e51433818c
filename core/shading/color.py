"""Cycles' colour nodes as scalar numba functions (our own code after util/color.h,
kernel/svm/color_util.h, math_util.h): RGB <-> HSV, the Mix blend modes, Blackbody.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401
from .converters import clamp

_JIT = dict(cache=True, error_model="numpy")

BLEND_TYPES = {name: i for i, name in enumerate((
    "MIX", "DARKEN", "MULTIPLY", "BURN", "LIGHTEN", "SCREEN", "DODGE", "ADD", "OVERLAY",
    "SOFT_LIGHT", "LINEAR_LIGHT", "DIFFERENCE", "EXCLUSION", "SUBTRACT", "DIVIDE", "HUE",
    "SATURATION", "COLOR", "VALUE"))}
"""ShaderNodeMix.blend_type (and MixRGB's) -> code."""


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


@njit(**_JIT)
def rgb_to_hsl(r, g, b):
    """Cycles' rgb_to_hsl (util/color.h): hue, saturation, lightness (capped at 1)."""
    cmax = max(r, max(g, b))
    cmin = min(r, min(g, b))
    lum = min(1.0, (cmax + cmin) / 2.0)
    if cmax == cmin:
        return 0.0, 0.0, lum
    cdelta = cmax - cmin
    s = cdelta / (2.0 - cmax - cmin) if lum > 0.5 else cdelta / (cmax + cmin)
    if cmax == r:
        h = (g - b) / cdelta + (6.0 if g < b else 0.0)
    elif cmax == g:
        h = (b - r) / cdelta + 2.0
    else:
        h = (r - g) / cdelta + 4.0
    return h / 6.0, s, lum


@njit(**_JIT)
def hsl_to_rgb(h, s, lum):
    """Cycles' hsl_to_rgb (util/color.h)."""
    nr = clamp(abs(h * 6.0 - 3.0) - 1.0, 0.0, 1.0)
    ng = clamp(2.0 - abs(h * 6.0 - 2.0), 0.0, 1.0)
    nb = clamp(2.0 - abs(h * 6.0 - 4.0), 0.0, 1.0)
    chroma = (1.0 - abs(2.0 * lum - 1.0)) * s
    return (nr - 0.5) * chroma + lum, (ng - 0.5) * chroma + lum, (nb - 0.5) * chroma + lum


CIE_COLOR_MATCH = np.array([
    0.0014, 0.0000, 0.0065, 0.0022, 0.0001, 0.0105, 0.0042, 0.0001, 0.0201,
    0.0076, 0.0002, 0.0362, 0.0143, 0.0004, 0.0679, 0.0232, 0.0006, 0.1102,
    0.0435, 0.0012, 0.2074, 0.0776, 0.0022, 0.3713, 0.1344, 0.0040, 0.6456,
    0.2148, 0.0073, 1.0391, 0.2839, 0.0116, 1.3856, 0.3285, 0.0168, 1.6230,
    0.3483, 0.0230, 1.7471, 0.3481, 0.0298, 1.7826, 0.3362, 0.0380, 1.7721,
    0.3187, 0.0480, 1.7441, 0.2908, 0.0600, 1.6692, 0.2511, 0.0739, 1.5281,
    0.1954, 0.0910, 1.2876, 0.1421, 0.1126, 1.0419, 0.0956, 0.1390, 0.8130,
    0.0580, 0.1693, 0.6162, 0.0320, 0.2080, 0.4652, 0.0147, 0.2586, 0.3533,
    0.0049, 0.3230, 0.2720, 0.0024, 0.4073, 0.2123, 0.0093, 0.5030, 0.1582,
    0.0291, 0.6082, 0.1117, 0.0633, 0.7100, 0.0782, 0.1096, 0.7932, 0.0573,
    0.1655, 0.8620, 0.0422, 0.2257, 0.9149, 0.0298, 0.2904, 0.9540, 0.0203,
    0.3597, 0.9803, 0.0134, 0.4334, 0.9950, 0.0087, 0.5121, 1.0000, 0.0057,
    0.5945, 0.9950, 0.0039, 0.6784, 0.9786, 0.0027, 0.7621, 0.9520, 0.0021,
    0.8425, 0.9154, 0.0018, 0.9163, 0.8700, 0.0017, 0.9786, 0.8163, 0.0014,
    1.0263, 0.7570, 0.0011, 1.0567, 0.6949, 0.0010, 1.0622, 0.6310, 0.0008,
    1.0456, 0.5668, 0.0006, 1.0026, 0.5030, 0.0003, 0.9384, 0.4412, 0.0002,
    0.8544, 0.3810, 0.0002, 0.7514, 0.3210, 0.0001, 0.6424, 0.2650, 0.0000,
    0.5419, 0.2170, 0.0000, 0.4479, 0.1750, 0.0000, 0.3608, 0.1382, 0.0000,
    0.2835, 0.1070, 0.0000, 0.2187, 0.0816, 0.0000, 0.1649, 0.0610, 0.0000,
    0.1212, 0.0446, 0.0000, 0.0874, 0.0320, 0.0000, 0.0636, 0.0232, 0.0000,
    0.0468, 0.0170, 0.0000, 0.0329, 0.0119, 0.0000, 0.0227, 0.0082, 0.0000,
    0.0158, 0.0057, 0.0000, 0.0114, 0.0041, 0.0000, 0.0081, 0.0029, 0.0000,
    0.0058, 0.0021, 0.0000, 0.0041, 0.0015, 0.0000, 0.0029, 0.0010, 0.0000,
    0.0020, 0.0007, 0.0000, 0.0014, 0.0005, 0.0000, 0.0010, 0.0004, 0.0000,
    0.0007, 0.0002, 0.0000, 0.0005, 0.0002, 0.0000, 0.0003, 0.0001, 0.0000,
    0.0002, 0.0001, 0.0000, 0.0002, 0.0001, 0.0000, 0.0001, 0.0000, 0.0000,
    0.0001, 0.0000, 0.0000, 0.0001, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000],
    np.float32).reshape(81, 3)
"""The CIE 1931 2-degree colour matching functions x, y, z at 380-780 nm every 5 nm, to
4 decimals: Cycles' cie_color_match table (kernel/tables.h), in float32 as Cycles."""


@njit(**_JIT)
def wavelength_xyz(lambda_nm):
    """Cycles' svm_node_wavelength before its XYZ -> RGB step: the table linearly
    interpolated at lambda_nm (nanometres); 0 outside (375, 780) nm (Cycles truncates
    the index towards 0, so 375-380 nm extrapolates the first interval)."""
    ii = (lambda_nm - 380.0) * (1.0 / 5.0)
    if not -1.0 < ii < 80.0:  # NaN too
        return 0.0, 0.0, 0.0
    i = int(ii)
    t = ii - i
    c = CIE_COLOR_MATCH
    return ((1.0 - t) * c[i, 0] + t * c[i + 1, 0], (1.0 - t) * c[i, 1] + t * c[i + 1, 1],
            (1.0 - t) * c[i, 2] + t * c[i + 1, 2])


WAVELENGTH_SCALE = 1.0 / 2.52
"""Cycles' empirical scale of the Wavelength node's RGB ("to make all comps <= 1")."""
