"""Image Texture sampling with Cycles' definitions (kernel/device/cpu/image.h,
svm/image.h): the lookup OP_IMAGE runs on ``core.scene.images.ProgramImages``.

- Closest: texel floor(x w), floor(y h). Linear: bilinear between the texel centres, texel
  i centred at (i + 0.5) / w. Cubic and Smart: Cycles' cubic B-spline (4 x 4 texels).
- Extension per texel index: Repeat (periodic), Extend (clamped), Clip (a texel outside
  the image is transparent black), Mirror (Cycles' wrap_mirror).
- A UDIM slot: the tile 1001 + floor(u) + 10 floor(v) (u in [0, 10), v >= 0) sampled at
  the fractional UV; a point on no tile, and a missing image (slot -1), give Cycles'
  TEX_IMAGE_MISSING colour, magenta (1, 0, 1, 1).
- After filtering: the colour divided by alpha when ``unassociate`` (Cycles does so when
  the node's Alpha output is used and the alpha is not 0 or 1), then the sRGB decode for
  sRGB-encoded tiles (Cycles' compress_as_srgb). Every value read is channel / 255
  (uint8), / 65535 (uint16) or the float itself.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401

INTERPOLATIONS = {"Closest": 0, "Linear": 1, "Cubic": 2, "Smart": 2}
EXTENSIONS = {"REPEAT": 0, "EXTEND": 1, "CLIP": 2, "MIRROR": 3}
MISSING = (1.0, 0.0, 1.0, 1.0)
"""Cycles' TEX_IMAGE_MISSING_R, G, B, A."""

_KW = dict(cache=True, error_model="numpy")


@njit(inline="always", **_KW)
def _wrap(i, n, ext):
    """Texel index i of a row of n under extension ext; -1 for a Clip outside."""
    if ext == 0:
        i = i % n
        return i + n if i < 0 else i
    if ext == 1:
        return min(max(i, 0), n - 1)
    if ext == 2:
        return i if 0 <= i < n else -1
    m = abs(i + (1 if i < 0 else 0)) % (2 * n)
    return 2 * n - m - 1 if m >= n else m


@njit(inline="always", **_KW)
def _read(bytes_, shorts, floats, kind, off, w, x, y, c):
    if x < 0 or y < 0:
        return 0.0
    k = off + 4 * (y * w + x) + c
    if kind == 0:
        return bytes_[k] * (1.0 / 255.0)
    if kind == 1:
        return shorts[k] * (1.0 / 65535.0)
    return np.float64(floats[k])


@njit(inline="always", **_KW)
def _bspline(t):
    """Cycles' cubic B-spline weights at fraction t (SET_CUBIC_SPLINE_WEIGHTS)."""
    w0 = (1.0 / 6.0) * (t * (t * (-t + 3.0) - 3.0) + 1.0)
    w1 = (1.0 / 6.0) * (t * t * (3.0 * t - 6.0) + 4.0)
    w3 = (1.0 / 6.0) * (t * t * t)
    return w0, w1, 1.0 - w0 - w1 - w3, w3


@njit(**_KW)
def _srgb_decode(v):
    if v <= 0.04045:
        return max(v, 0.0) / 12.92
    return ((v + 0.055) / 1.055) ** 2.4


@njit(**_KW)
def _tile_sample(bytes_, shorts, floats, row, x, y, interp, ext, out):
    """RGBA of tile row ``row`` (a ``tiles`` row) at (x, y) into out[0:4], before the
    alpha and colour-space steps."""
    kind, off, w, h = row[0], row[1], row[2], row[3]
    for c in range(4):
        out[c] = 0.0
    if interp == 0:
        ix = _wrap(int(math.floor(x * w)), w, ext)
        iy = _wrap(int(math.floor(y * h)), h, ext)
        for c in range(4):
            out[c] = _read(bytes_, shorts, floats, kind, off, w, ix, iy, c)
        return
    if interp == 1:
        fx = x * w - 0.5
        fy = y * h - 0.5
        ix0 = int(math.floor(fx))
        iy0 = int(math.floor(fy))
        tx = fx - ix0
        ty = fy - iy0
        ix = _wrap(ix0, w, ext)
        nx = _wrap(ix0 + 1, w, ext)
        iy = _wrap(iy0, h, ext)
        ny = _wrap(iy0 + 1, h, ext)
        for c in range(4):
            out[c] = ((1.0 - ty) * ((1.0 - tx) * _read(bytes_, shorts, floats, kind, off, w,
                                                       ix, iy, c)
                                    + tx * _read(bytes_, shorts, floats, kind, off, w, nx,
                                                 iy, c))
                      + ty * ((1.0 - tx) * _read(bytes_, shorts, floats, kind, off, w, ix,
                                                 ny, c)
                              + tx * _read(bytes_, shorts, floats, kind, off, w, nx, ny, c)))
        return
    fx = x * w - 0.5
    fy = y * h - 0.5
    ix0 = int(math.floor(fx))
    iy0 = int(math.floor(fy))
    wx = _bspline(fx - ix0)
    wy = _bspline(fy - iy0)
    for b in range(4):
        yy = _wrap(iy0 - 1 + b, h, ext)
        for a in range(4):
            xx = _wrap(ix0 - 1 + a, w, ext)
            k = wx[a] * wy[b]
            for c in range(4):
                out[c] += k * _read(bytes_, shorts, floats, kind, off, w, xx, yy, c)


@njit(**_KW)
def image_sample(bytes_, shorts, floats, tiles, slot_first, slot_count, slot, x, y, interp,
                 ext, unassociate, out):
    """The Image Texture's (Color, Alpha) of ``slot`` at texture coordinates (x, y) into
    out[0:4] (module doc for every step)."""
    if slot < 0 or slot >= slot_first.shape[0]:
        out[0], out[1], out[2], out[3] = 1.0, 0.0, 1.0, 1.0
        return
    first = slot_first[slot]
    row = -1
    if tiles[first, 4] == 0:
        row = first
    else:
        tx = math.floor(x)
        ty = math.floor(y)
        if 0.0 <= tx < 10.0 and ty >= 0.0:
            number = 1001 + int(tx) + 10 * int(ty)
            for r in range(first, first + slot_count[slot]):
                if tiles[r, 4] == number:
                    row = r
                    break
            if row >= 0:
                x -= tx
                y -= ty
    if row < 0:
        out[0], out[1], out[2], out[3] = 1.0, 0.0, 1.0, 1.0
        return
    _tile_sample(bytes_, shorts, floats, tiles[row], x, y, interp, ext, out)
    a = out[3]
    if unassociate and a != 1.0 and a != 0.0:
        for c in range(3):
            out[c] /= a
    if tiles[row, 5] == 1:
        for c in range(3):
            out[c] = _srgb_decode(out[c])


PROJECTIONS = {"FLAT": 0, "BOX": 1, "SPHERE": 2, "TUBE": 3}
"""ShaderNodeTexImage.projection -> code (OP_IMAGE_PROJECTED's flags >> 1)."""


@njit(**_KW)
def map_to_sphere(x, y, z):
    """Cycles' map_to_sphere of a point in [-1, 1]^3: (u, v)."""
    ln = x * x + y * y + z * z
    if not ln > 0.0:
        return 0.0, 0.0
    u = 0.0 if (x == 0.0 and y == 0.0) else 0.5 - math.atan2(x, y) / (2.0 * math.pi)
    c = min(max(z / math.sqrt(ln), -1.0), 1.0)  # Cycles' safe_acosf
    return u, 1.0 - math.acos(c) / math.pi


@njit(**_KW)
def map_to_tube(x, y, z):
    """Cycles' map_to_tube of a point in [-1, 1]^3: (u, v)."""
    ln = math.sqrt(x * x + y * y)
    if not ln > 0.0:
        return 0.0, 0.0
    return (1.0 - math.atan2(x / ln, y / ln) / math.pi) * 0.5, (z + 1.0) * 0.5


@njit(**_KW)
def box_weights(nx, ny, nz, blend):
    """Cycles' svm_node_tex_image_box weights of the X, Y and Z projections for the
    object-space normal (nx, ny, nz) and the node's Blend in [0, 1]."""
    ax, ay, az = abs(nx), abs(ny), abs(nz)
    s = ax + ay + az
    if s > 0.0:
        ax, ay, az = ax / s, ay / s, az / s
    limit = 0.5 * (1.0 + blend)
    wx = wy = wz = 0.0
    if ax > limit * (ax + ay) and ax > limit * (ax + az):
        wx = 1.0
    elif ay > limit * (ax + ay) and ay > limit * (ay + az):
        wy = 1.0
    elif az > limit * (ax + az) and az > limit * (ay + az):
        wz = 1.0
    elif blend > 0.0:
        if az < (1.0 - limit) * (ay + ax):
            wx = min(max((ax / (ax + ay) - 0.5 * (1.0 - blend)) / blend, 0.0), 1.0)
            wy = 1.0 - wx
        elif ax < (1.0 - limit) * (ay + az):
            wy = min(max((ay / (ay + az) - 0.5 * (1.0 - blend)) / blend, 0.0), 1.0)
            wz = 1.0 - wy
        elif ay < (1.0 - limit) * (ax + az):
            wx = min(max((ax / (ax + az) - 0.5 * (1.0 - blend)) / blend, 0.0), 1.0)
            wz = 1.0 - wx
        else:
            d = 2.0 * limit - 1.0
            wx = ((2.0 - limit) * ax + (limit - 1.0)) / d
            wy = ((2.0 - limit) * ay + (limit - 1.0)) / d
            wz = ((2.0 - limit) * az + (limit - 1.0)) / d
    else:  # Cycles' "desperate mode": no valid choice, one side
        wx = 1.0
    return wx, wy, wz


@njit(**_KW)
def image_projected(bytes_, shorts, floats, tiles, slot_first, slot_count, slot, x, y, z,
                    nx, ny, nz, blend, interp, ext, unassociate, projection, out, tmp):
    """The Image Texture with its Box, Sphere or Tube projection (Cycles'
    svm_node_tex_image and svm_node_tex_image_box) of the vector (x, y, z), the
    object-space normal (nx, ny, nz) for Box: (Color, Alpha) into out[0:4]; tmp (4,)
    scratch. Box blends up to three flat lookups, each decoded and unassociated on its own
    as Cycles does."""
    if projection == 2 or projection == 3:
        px, py, pz = (x - 0.5) * 2.0, (y - 0.5) * 2.0, (z - 0.5) * 2.0
        if projection == 2:
            u, v = map_to_sphere(px, py, pz)
        else:
            u, v = map_to_tube(px, py, pz)
        image_sample(bytes_, shorts, floats, tiles, slot_first, slot_count, slot, u, v,
                     interp, ext, unassociate, out)
        return
    if projection == 0:
        image_sample(bytes_, shorts, floats, tiles, slot_first, slot_count, slot, x, y,
                     interp, ext, unassociate, out)
        return
    wx, wy, wz = box_weights(nx, ny, nz, blend)
    for c in range(4):
        out[c] = 0.0
    for side in range(3):
        w = wx if side == 0 else (wy if side == 1 else wz)
        if not w > 0.0:
            continue
        if side == 0:  # "map so that no textures are flipped" (Cycles' orientation)
            u, v = (1.0 - y if nx < 0.0 else y), z
        elif side == 1:
            u, v = (1.0 - x if ny > 0.0 else x), z
        else:
            u, v = (1.0 - y if nz > 0.0 else y), x
        image_sample(bytes_, shorts, floats, tiles, slot_first, slot_count, slot, u, v,
                     interp, ext, unassociate, tmp)
        for c in range(4):
            out[c] += w * tmp[c]
