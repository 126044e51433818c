"""The shader program interpreter: one numba kernel runs a ``ShaderProgram`` over a batch
of hit points (``evaluate``), in parallel over points, each with its own registers.

This is the interface the integrators use once the closure model lands (issue 13):
``evaluate(program, inputs)`` gives the per-point values of the program's outputs, and
``closure_params(program, inputs, params)`` writes them into per-point copies of the
material's closure parameter rows (``closure_values``: the same from values already
evaluated).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401
from . import program as pg
from .inputs import ShadingInputs
from .converters import math_op, vector_math, map_range, vector_map_range_1, mapping, \
    ramp_lookup, curve_lookup, clamp
from .color import blend, rgb_to_hsv, hsv_to_rgb, rgb_to_hsl, hsl_to_rgb, \
    blackbody_rec709, wavelength_xyz, WAVELENGTH_SCALE
from .facing import fresnel_node, layer_weight
from .textures import checker, gradient, white_noise, wave, magic, brick
from .noise import noise_texture, noise_texture3_rows, NOISE_FBM, \
    SCRATCH_ROWS as NOISE_SCRATCH_ROWS
from .voronoi import voronoi_texture, voronoi_f1_3d_rows, F1, EUCLIDEAN, \
    SCRATCH_ROWS as VORONOI_SCRATCH_ROWS
from .images import image_sample, image_projected
from .normals import bump, normal_map, tangent
from ..scene.images import ProgramImages

_F = pg.FIRST_OPERAND
_CHUNK = 128  # points a chunk: its registers (n_registers x 1 kB) stay in cache


@njit(inline="always", **dict(cache=True, error_model="numpy"))
def _load_row(R, col, o, src, idx, i, P, N, Ng, I, back, gen, obj, objn, oloc, orand, ocol, oidx,
              uv, attr, tan, n2w, oalpha, midx, lp):
    """Source src (index idx) of row i of the inputs into registers R[o:o + 3, col]."""
    if src == 0:
        a = P
    elif src == 1:
        a = N
    elif src == 2:
        a = Ng
    elif src == 3:
        a = I
    elif src == 5:
        a = gen
    elif src == 6:
        a = obj
    elif src == 7:
        a = objn
    elif src == 9:
        a = oloc
    elif src == 13:
        a = ocol
    else:
        a = P  # not used below
    if src == 22:  # SOURCE_LIGHT_PATH, output idx
        R[o, col] = lp[i, idx]
        R[o + 1, col] = R[o, col]
        R[o + 2, col] = R[o, col]
    elif src == 20 or src == 21:  # SOURCE_OBJECT_ALPHA, SOURCE_MATERIAL_INDEX
        R[o, col] = oalpha[i] if src == 20 else midx[i]
        R[o + 1, col] = R[o, col]
        R[o + 2, col] = R[o, col]
    elif src == 4 or src == 10 or src == 14:
        R[o, col] = back[i] if src == 4 else (orand[i] if src == 10 else oidx[i])
        R[o + 1, col] = R[o, col]
        R[o + 2, col] = R[o, col]
    elif src == 8:
        if idx < uv.shape[0]:
            R[o, col], R[o + 1, col] = uv[idx, i, 0], uv[idx, i, 1]
        else:
            R[o, col], R[o + 1, col] = 0.0, 0.0
        R[o + 2, col] = 0.0
    elif src == 11 or src == 12:
        if idx < attr.shape[0]:
            if src == 11:
                for c in range(3):
                    R[o + c, col] = attr[idx, i, c]
            else:
                R[o, col] = R[o + 1, col] = R[o + 2, col] = attr[idx, i, 3]
        else:
            R[o, col] = R[o + 1, col] = R[o + 2, col] = 0.0
    elif src == 15 or src == 16:  # SOURCE_TANGENT, SOURCE_TANGENT_SIGN
        if idx < tan.shape[0]:
            if src == 15:
                for c in range(3):
                    R[o + c, col] = tan[idx, i, c]
            else:
                R[o, col] = R[o + 1, col] = R[o + 2, col] = tan[idx, i, 3]
        else:
            R[o, col] = R[o + 1, col] = R[o + 2, col] = 0.0
    elif src == 17:  # SOURCE_NORMAL_TO_WORLD, row idx
        R[o, col], R[o + 1, col], R[o + 2, col] = n2w[i, idx, 0], n2w[i, idx, 1], n2w[i, idx, 2]
    else:
        R[o, col], R[o + 1, col], R[o + 2, col] = a[i, 0], a[i, 1], a[i, 2]


@njit(inline="always", **dict(cache=True, error_model="numpy"))
def _load_input(R, col, ins, i, stride, P, N, Ng, I, back, gen, obj, objn, oloc, orand, ocol, oidx,
                uv, attr, tan, n2w, oalpha, midx, lp):
    """OP_INPUT ins at point i (row i of the inputs) into column col of the registers.
    A bump offset (ins[3] 1 or 2, with stride = the points' count: the offset rows
    follow them) reads the source at P + w dPdx (or dPdy), w = ins[4] BUMP_WIDTH_UNIT,
    interpolated linearly from the point to its row at P + dPdx (every input is affine
    in the barycentrics over a triangle, the normal nearly so)."""
    src, idx, o = ins[1], ins[2], ins[_F]
    if src == 18 or src == 19:  # SOURCE_BUMP_DPDX / DPDY
        j = i + (1 if src == 18 else 2) * stride
        for c in range(3):
            R[o + c, col] = (np.float64(P[j, c]) - np.float64(P[i, c])) if stride > 0 else 0.0
        return
    _load_row(R, col, o, src, idx, i, P, N, Ng, I, back, gen, obj, objn, oloc, orand, ocol, oidx,
              uv, attr, tan, n2w, oalpha, midx, lp)
    if ins[3] != 0 and stride > 0:
        x, y, z = R[o, col], R[o + 1, col], R[o + 2, col]
        _load_row(R, col, o, src, idx, i + ins[3] * stride, P, N, Ng, I, back, gen, obj, objn,
                  oloc, orand, ocol, oidx, uv, attr, tan, n2w, oalpha, midx, lp)
        w = ins[4] * pg.BUMP_WIDTH_UNIT
        R[o, col] = x + w * (R[o, col] - x)
        R[o + 1, col] = y + w * (R[o + 1, col] - y)
        R[o + 2, col] = z + w * (R[o + 2, col] - z)


@njit(**dict(cache=True, error_model="numpy"))
def _run_rows(R, n_cols, ins, tables, im_bytes, im_shorts, im_floats, im_tiles, im_first,
              im_count, px):
    """Execute one instruction ins (not OP_INPUT) at the first n_cols points of a chunk:
    columns [0, n_cols) of the registers R (n_registers, chunk) float64; the im_* arrays
    are ``ProgramImages``' fields, px a (8,) float64 scratch. The opcode's branch is
    taken once and loops over the points (a loop in each branch: the dispatch out of the
    points' loop); every point's arithmetic is the one-point evaluation's."""
    op = ins[0]
    a = ins[_F:]
    if op == pg.OP_MATH:
        for col in range(n_cols):
            v = math_op(ins[1], R[a[0], col], R[a[1], col], R[a[2], col])
            R[a[3], col] = clamp(v, 0.0, 1.0) if ins[2] else v
    elif op == pg.OP_VECTOR_MATH:
        for col in range(n_cols):
            x, y, z, s = vector_math(ins[1], R[a[0], col], R[a[0] + 1, col], R[a[0] + 2, col],
                                     R[a[1], col], R[a[1] + 1, col], R[a[1] + 2, col],
                                     R[a[2], col], R[a[2] + 1, col], R[a[2] + 2, col],
                                     R[a[3], col])
            R[a[4], col], R[a[4] + 1, col], R[a[4] + 2, col], R[a[5], col] = x, y, z, s
    elif op == pg.OP_MIX_FLOAT:
        for col in range(n_cols):
            t = clamp(R[a[0], col], 0.0, 1.0) if ins[1] else R[a[0], col]
            R[a[3], col] = R[a[1], col] * (1.0 - t) + R[a[2], col] * t
    elif op == pg.OP_MIX_VECTOR or op == pg.OP_MIX_VECTOR_NONUNIFORM:
        for col in range(n_cols):
            for c in range(3):
                t = R[a[0] + c, col] if op == pg.OP_MIX_VECTOR_NONUNIFORM else R[a[0], col]
                if ins[1]:
                    t = clamp(t, 0.0, 1.0)
                R[a[3] + c, col] = R[a[1] + c, col] * (1.0 - t) + R[a[2] + c, col] * t
    elif op == pg.OP_MIX_COLOR:
        for col in range(n_cols):
            t = clamp(R[a[0], col], 0.0, 1.0) if ins[2] else R[a[0], col]
            x, y, z = blend(ins[1], t, R[a[1], col], R[a[1] + 1, col], R[a[1] + 2, col],
                            R[a[2], col], R[a[2] + 1, col], R[a[2] + 2, col])
            if ins[3]:
                x, y, z = clamp(x, 0.0, 1.0), clamp(y, 0.0, 1.0), clamp(z, 0.0, 1.0)
            R[a[3], col], R[a[3] + 1, col], R[a[3] + 2, col] = x, y, z
    elif op == pg.OP_MAP_RANGE:
        for col in range(n_cols):
            R[a[6], col] = map_range(ins[1], ins[2], R[a[0], col], R[a[1], col], R[a[2], col],
                                     R[a[3], col], R[a[4], col], R[a[5], col])
    elif op == pg.OP_VECTOR_MAP_RANGE:
        for col in range(n_cols):
            for c in range(3):
                R[a[6] + c, col] = vector_map_range_1(ins[1], ins[2], R[a[0] + c, col],
                                                      R[a[1] + c, col], R[a[2] + c, col],
                                                      R[a[3] + c, col], R[a[4] + c, col],
                                                      R[a[5] + c, col])
    elif op == pg.OP_CLAMP:
        for col in range(n_cols):
            lo, hi = R[a[1], col], R[a[2], col]
            if ins[1] == 1 and lo > hi:
                lo, hi = hi, lo
            R[a[3], col] = clamp(R[a[0], col], lo, hi)
    elif op == pg.OP_SEPARATE:
        for col in range(n_cols):
            x, y, z = R[a[0], col], R[a[0] + 1, col], R[a[0] + 2, col]
            if ins[1] == 1:
                x, y, z = rgb_to_hsv(x, y, z)
            elif ins[1] == 2:
                x, y, z = rgb_to_hsl(x, y, z)
            R[a[1], col], R[a[2], col], R[a[3], col] = x, y, z
    elif op == pg.OP_COMBINE:
        for col in range(n_cols):
            x, y, z = R[a[0], col], R[a[1], col], R[a[2], col]
            if ins[1] == 1:
                x, y, z = hsv_to_rgb(x, y, z)
            elif ins[1] == 2:
                x, y, z = hsl_to_rgb(x, y, z)
            R[a[3], col], R[a[3] + 1, col], R[a[3] + 2, col] = x, y, z
    elif op == pg.OP_RAMP:
        for col in range(n_cols):
            f = R[a[0], col]
            for c in range(3):
                R[a[1] + c, col] = ramp_lookup(tables, ins[1], ins[2], f, ins[3] != 0, c)
            R[a[2], col] = ramp_lookup(tables, ins[1], ins[2], f, ins[3] != 0, 3)
    elif op == pg.OP_MAPPING:
        for col in range(n_cols):
            x, y, z = mapping(ins[1], R[a[0], col], R[a[0] + 1, col], R[a[0] + 2, col],
                              R[a[1], col], R[a[1] + 1, col], R[a[1] + 2, col], R[a[2], col],
                              R[a[2] + 1, col], R[a[2] + 2, col], R[a[3], col],
                              R[a[3] + 1, col], R[a[3] + 2, col])
            R[a[4], col], R[a[4] + 1, col], R[a[4] + 2, col] = x, y, z
    elif op == pg.OP_INVERT:
        for col in range(n_cols):
            f = R[a[0], col]
            for c in range(3):
                x = R[a[1] + c, col]
                R[a[2] + c, col] = f * (1.0 - x) + (1.0 - f) * x
    elif op == pg.OP_GAMMA:
        for col in range(n_cols):
            g = R[a[1], col]
            for c in range(3):
                x = R[a[0] + c, col]
                if g == 0.0:
                    x = 1.0
                elif x > 0.0:
                    x = x ** g
                R[a[2] + c, col] = x
    elif op == pg.OP_HSV:
        for col in range(n_cols):
            fac = R[a[3], col]
            cr, cg, cb = R[a[4], col], R[a[4] + 1, col], R[a[4] + 2, col]
            h, s, v = rgb_to_hsv(cr, cg, cb)
            h = h + R[a[0], col] + 0.5
            h = h - math.floor(h)
            s = clamp(s * R[a[1], col], 0.0, 1.0)
            v *= R[a[2], col]
            x, y, z = hsv_to_rgb(h, s, v)
            R[a[5], col] = max(fac * x + (1.0 - fac) * cr, 0.0)
            R[a[5] + 1, col] = max(fac * y + (1.0 - fac) * cg, 0.0)
            R[a[5] + 2, col] = max(fac * z + (1.0 - fac) * cb, 0.0)
    elif op == pg.OP_BRIGHT_CONTRAST:
        for col in range(n_cols):
            ka = 1.0 + R[a[2], col]
            kb = R[a[1], col] - R[a[2], col] * 0.5
            for c in range(3):
                R[a[3] + c, col] = max(ka * R[a[0] + c, col] + kb, 0.0)
    elif op == pg.OP_RGB_TO_BW:
        for col in range(n_cols):
            R[a[2], col] = (R[a[0], col] * R[a[1], col] + R[a[0] + 1, col] * R[a[1] + 1, col]
                            + R[a[0] + 2, col] * R[a[1] + 2, col])
    elif op == pg.OP_CHECKER:
        for col in range(n_cols):
            s = R[a[3], col]
            f = checker(R[a[0], col] * s, R[a[0] + 1, col] * s, R[a[0] + 2, col] * s)
            src = a[1] if f == 1.0 else a[2]
            for c in range(3):
                R[a[4] + c, col] = R[src + c, col]
            R[a[5], col] = f
    elif op == pg.OP_GRADIENT:
        for col in range(n_cols):
            f = gradient(ins[1], R[a[0], col], R[a[0] + 1, col], R[a[0] + 2, col])
            R[a[1], col] = R[a[1] + 1, col] = R[a[1] + 2, col] = f
            R[a[2], col] = f
    elif op == pg.OP_WHITE_NOISE:
        for col in range(n_cols):
            v, x, y, z = white_noise(ins[1], R[a[0], col], R[a[0] + 1, col], R[a[0] + 2, col],
                                     R[a[1], col])
            R[a[2], col] = v
            R[a[3], col], R[a[3] + 1, col], R[a[3] + 2, col] = x, y, z
    elif op == pg.OP_NOISE:
        for col in range(n_cols):
            v, x, y, z = noise_texture(R[a[0], col], R[a[0] + 1, col], R[a[0] + 2, col],
                                       R[a[1], col], ins[1], R[a[2], col], R[a[3], col],
                                       R[a[4], col], R[a[5], col], R[a[6], col], R[a[7], col],
                                       R[a[8], col], ins[2], ins[3] != 0, ins[4] != 0)
            R[a[9], col] = v
            R[a[10], col], R[a[10] + 1, col], R[a[10] + 2, col] = x, y, z
    elif op == pg.OP_VORONOI:
        for col in range(n_cols):
            scale = R[a[2], col]
            d, cr, cg, cb, qx, qy, qz, qw = voronoi_texture(
                R[a[0], col], R[a[0] + 1, col], R[a[0] + 2, col], R[a[1], col], ins[1], ins[2],
                ins[3], (ins[4] & 1) != 0, scale, R[a[3], col], R[a[4], col], R[a[5], col],
                R[a[6], col], R[a[7], col], R[a[8], col], (ins[4] & 2) != 0)
            R[a[9], col] = d
            R[a[10], col], R[a[10] + 1, col], R[a[10] + 2, col] = cr, cg, cb
            R[a[11], col], R[a[11] + 1, col], R[a[11] + 2, col] = qx, qy, qz
            R[a[12], col] = qw
    elif op == pg.OP_WAVE:
        for col in range(n_cols):
            s = R[a[1], col]
            f = wave(ins[1], ins[2], ins[3], ins[4], R[a[0], col] * s, R[a[0] + 1, col] * s,
                     R[a[0] + 2, col] * s, R[a[2], col], R[a[3], col], R[a[4], col], R[a[5], col],
                     R[a[6], col])
            R[a[7], col] = R[a[7] + 1, col] = R[a[7] + 2, col] = f
            R[a[8], col] = f
    elif op == pg.OP_MAGIC:
        for col in range(n_cols):
            x, y, z = magic(R[a[0], col], R[a[0] + 1, col], R[a[0] + 2, col], R[a[1], col], ins[1],
                            R[a[2], col])
            R[a[3], col], R[a[3] + 1, col], R[a[3] + 2, col] = x, y, z
            R[a[4], col] = (x + y + z) / 3.0
    elif op == pg.OP_BRICK:
        for col in range(n_cols):
            s = R[a[4], col]
            tint, f = brick(R[a[0], col] * s, R[a[0] + 1, col] * s, R[a[5], col], R[a[6], col],
                            R[a[7], col], R[a[8], col], R[a[9], col], R[a[10], col], ins[1],
                            R[a[11], col], ins[2])
            for c in range(3):
                c1 = R[a[1] + c, col]
                if f != 1.0:
                    c1 = (1.0 - tint) * c1 + tint * R[a[2] + c, col]
                R[a[12] + c, col] = c1 * (1.0 - f) + R[a[3] + c, col] * f
            R[a[13], col] = f
    elif op == pg.OP_BLACKBODY:
        for col in range(n_cols):
            x, y, z = blackbody_rec709(R[a[0], col])
            for c in range(3):  # row c of the Rec.709 -> scene linear matrix is operand 1 + c
                m = a[1 + c]
                R[a[4] + c, col] = max(R[m, col] * x + R[m + 1, col] * y + R[m + 2, col] * z, 0.0)
    elif op == pg.OP_CURVES:
        for col in range(n_cols):
            fac = R[a[0], col]
            lo, hi = R[a[2], col], R[a[3], col]
            for c in range(3):
                v = R[a[1] + c, col]
                t = (v - lo) / (hi - lo)
                mapped = curve_lookup(tables, ins[1], ins[2], t, c) if ins[3] else \
                    ramp_lookup(tables, ins[1], ins[2], t, True, c)
                R[a[4] + c, col] = (1.0 - fac) * v + fac * mapped
    elif op == pg.OP_FLOAT_CURVE:
        for col in range(n_cols):
            fac = R[a[0], col]
            v = R[a[1], col]
            t = (v - R[a[2], col]) / (R[a[3], col] - R[a[2], col])
            mapped = curve_lookup(tables, ins[1], ins[2], t, 0) if ins[3] else \
                ramp_lookup(tables, ins[1], ins[2], t, True, 0)
            R[a[4], col] = (1.0 - fac) * v + fac * mapped
    elif op == pg.OP_IMAGE:
        for col in range(n_cols):
            image_sample(im_bytes, im_shorts, im_floats, im_tiles, im_first, im_count, ins[1],
                         R[a[0], col], R[a[0] + 1, col], ins[2], ins[3], ins[4] != 0, px)
            R[a[1], col], R[a[1] + 1, col], R[a[1] + 2, col] = px[0], px[1], px[2]
            R[a[2], col] = px[3]
    elif op == pg.OP_IMAGE_PROJECTED:
        for col in range(n_cols):
            image_projected(im_bytes, im_shorts, im_floats, im_tiles, im_first, im_count, ins[1],
                            R[a[0], col], R[a[0] + 1, col], R[a[0] + 2, col], R[a[1], col],
                            R[a[1] + 1, col], R[a[1] + 2, col], R[a[2], col], ins[2], ins[3],
                            (ins[4] & 1) != 0, ins[4] >> 1, px[:4], px[4:])
            R[a[3], col], R[a[3] + 1, col], R[a[3] + 2, col] = px[0], px[1], px[2]
            R[a[4], col] = px[3]
    elif op == pg.OP_FRESNEL or op == pg.OP_LAYER_WEIGHT:
        for col in range(n_cols):
            cosi = (R[a[1], col] * R[a[2], col] + R[a[1] + 1, col] * R[a[2] + 1, col]
                    + R[a[1] + 2, col] * R[a[2] + 2, col])
            back = R[a[3], col] != 0.0
            if op == pg.OP_FRESNEL:
                R[a[4], col] = fresnel_node(R[a[0], col], cosi, back)
            else:
                R[a[4], col], R[a[5], col] = layer_weight(R[a[0], col], cosi, back)
    elif op == pg.OP_TRANSFORM:
        for col in range(n_cols):
            x, y, z = R[a[0], col], R[a[0] + 1, col], R[a[0] + 2, col]
            w = 1.0
            if ins[1] == 1:
                m = a[7]
                w = R[m, col] * x + R[m + 1, col] * y + R[m + 2, col] * z + R[a[8], col]
                w = 1.0 / w if w != 0.0 else 0.0
            for c in range(3):
                m = a[1 + 2 * c]
                R[a[9] + c, col] = (R[m, col] * x + R[m + 1, col] * y + R[m + 2, col] * z
                                    + R[a[2 + 2 * c], col]) * w
    elif op == pg.OP_WAVELENGTH:
        for col in range(n_cols):
            x, y, z = wavelength_xyz(R[a[0], col])
            for c in range(3):  # row c of the XYZ -> scene linear matrix is operand 1 + c
                m = a[1 + c]
                R[a[4] + c, col] = max((R[m, col] * x + R[m + 1, col] * y + R[m + 2, col] * z)
                                       * WAVELENGTH_SCALE, 0.0)
    elif op == pg.OP_NORMAL_MAP:
        for col in range(n_cols):
            c, t, n, m0, m1, m2 = a[0], a[2], a[4], a[6], a[7], a[8]
            x, y, z = normal_map(ins[1], ins[2], R[c, col], R[c + 1, col], R[c + 2, col],
                                 R[a[1], col], R[t, col], R[t + 1, col], R[t + 2, col],
                                 R[a[3], col], R[n, col], R[n + 1, col], R[n + 2, col],
                                 R[a[5], col], R[m0, col], R[m0 + 1, col], R[m0 + 2, col],
                                 R[m1, col], R[m1 + 1, col], R[m1 + 2, col], R[m2, col],
                                 R[m2 + 1, col], R[m2 + 2, col])
            R[a[9], col], R[a[9] + 1, col], R[a[9] + 2, col] = x, y, z
    elif op == pg.OP_BUMP:
        for col in range(n_cols):
            n, dx, dy = a[6], a[7], a[8]
            x, y, z = bump(ins[1] != 0, R[a[0], col], R[a[1], col], R[a[2], col], R[a[3], col],
                           R[a[4], col], R[a[5], col], R[n, col], R[n + 1, col], R[n + 2, col],
                           R[dx, col], R[dx + 1, col], R[dx + 2, col], R[dy, col], R[dy + 1, col],
                           R[dy + 2, col])
            R[a[9], col], R[a[9] + 1, col], R[a[9] + 2, col] = x, y, z
    elif op == pg.OP_TANGENT:
        for col in range(n_cols):
            v, m0, m1, m2, n = a[0], a[1], a[2], a[3], a[4]
            x, y, z = tangent(ins[1], R[v, col], R[v + 1, col], R[v + 2, col], R[m0, col],
                              R[m0 + 1, col], R[m0 + 2, col], R[m1, col], R[m1 + 1, col],
                              R[m1 + 2, col], R[m2, col], R[m2 + 1, col], R[m2 + 2, col],
                              R[n, col], R[n + 1, col], R[n + 2, col])
            R[a[5], col], R[a[5] + 1, col], R[a[5] + 2, col] = x, y, z


@njit(**dict(cache=True, error_model="numpy"))
def _noise_rows(ins, k):
    """OP_NOISE ins runs over the batch (``noise_texture3_rows``): a 3-D fBm whose
    scale, detail, roughness, lacunarity and distortion are constants (registers < k)."""
    a = ins[_F:]
    return (ins[1] == 3 and ins[2] == NOISE_FBM and a[2] < k and a[3] < k and a[4] < k
            and a[5] < k and a[8] < k)


@njit(**dict(cache=True, error_model="numpy"))
def _voronoi_rows(ins, k):
    """OP_VORONOI ins runs over the batch (``voronoi_f1_3d_rows``): a 3-D Euclidean F1
    with PCG feature points whose scale, detail, roughness, lacunarity and randomness
    are constants (registers < k)."""
    a = ins[_F:]
    return (ins[1] == 3 and ins[2] == F1 and ins[3] == EUCLIDEAN and (ins[4] & 2) == 0
            and a[2] < k and a[3] < k and a[4] < k and a[5] < k and a[8] < k)


@njit(parallel=True, **dict(cache=True, error_model="numpy"))
def evaluate_kernel(instructions, constants, tables, n_registers, outputs, P, N, Ng, I, back,
                    gen, obj, objn, oloc, orand, ocol, oidx, uv, attr, tan, n2w, stride,
                    im_bytes, im_shorts, im_floats, im_tiles, im_first, im_count, out, oalpha,
                    midx, lp):
    """Run the program on every point: out[i, o] = register outputs[o, 0] of point i.
    (N, O) float32 ``out``; every other array as ``ShadingInputs`` / ``ShaderProgram`` /
    ``ProgramImages`` (im_*); stride ``ShadingInputs.bump_points``; lp
    ``ShadingInputs.light_path``.

    Instruction-major over chunks of points: each instruction runs over the chunk's
    points before the next (registers (n_registers, chunk), one column a point), its
    opcode's branch taken once for the chunk (``_run_rows``), and the Noise Texture's Perlin
    evaluations and the Voronoi Texture's cells vectorise over the chunk
    (``noise_texture3_rows``, ``voronoi_f1_3d_rows``). A point's values do
    not depend on the others': bit for bit the point-by-point evaluation."""
    n = out.shape[0]
    k = constants.shape[0]
    n_chunks = (n + _CHUNK - 1) // _CHUNK
    for c in prange(n_chunks):
        lo = c * _CHUNK
        m = min(n, lo + _CHUNK) - lo
        R = np.zeros((n_registers, _CHUNK), np.float64)
        S = np.empty((max(NOISE_SCRATCH_ROWS, VORONOI_SCRATCH_ROWS), _CHUNK), np.float64)
        px = np.zeros(8, np.float64)
        for j in range(k):
            for col in range(m):
                R[j, col] = constants[j]
        for s in range(instructions.shape[0]):
            ins = instructions[s]
            a = ins[_F:]
            if ins[0] == pg.OP_INPUT:
                for col in range(m):
                    _load_input(R, col, ins, lo + col, stride, P, N, Ng, I, back, gen, obj,
                                objn, oloc, orand, ocol, oidx, uv, attr, tan, n2w, oalpha,
                                midx, lp)
            elif ins[0] == pg.OP_NOISE and _noise_rows(ins, k):
                noise_texture3_rows(R[a[0]], R[a[0] + 1], R[a[0] + 2], m, R[a[2], 0],
                                    R[a[3], 0], R[a[4], 0], R[a[5], 0], R[a[8], 0],
                                    ins[3] != 0, ins[4] != 0, R[a[9]], R[a[10] + 1],
                                    R[a[10] + 2], S)
                for col in range(m):
                    R[a[10], col] = R[a[9], col]
            elif ins[0] == pg.OP_VORONOI and _voronoi_rows(ins, k):
                voronoi_f1_3d_rows(R[a[0]], R[a[0] + 1], R[a[0] + 2], m, R[a[2], 0],
                                   R[a[3], 0], R[a[4], 0], R[a[5], 0], R[a[8], 0],
                                   (ins[4] & 1) != 0, R[a[9]], R[a[10]], R[a[10] + 1],
                                   R[a[10] + 2], R[a[11]], R[a[11] + 1], R[a[11] + 2],
                                   R[a[12]], S)
            else:
                _run_rows(R, m, ins, tables, im_bytes, im_shorts, im_floats, im_tiles,
                          im_first, im_count, px)
        for o in range(outputs.shape[0]):
            reg = outputs[o, 0]
            for col in range(m):
                out[lo + col, o] = R[reg, col]


_NO_IMAGES = ProgramImages.empty()


def evaluate(program: pg.ShaderProgram, inputs: ShadingInputs,
             images: ProgramImages | None = None) -> np.ndarray:
    """(N, O) float32: the program's outputs (``program.outputs`` rows, in order) at the
    N points of ``inputs``; ``images`` the slots its Image Texture instructions sample
    (None: none, such an instruction gives the missing-image magenta). Values are what
    the nodes compute (not clamped; the closure code owns the ranges)."""
    im = _NO_IMAGES if images is None else images
    out = np.empty((inputs.count, program.outputs.shape[0]), np.float32)
    if inputs.count == 0:
        return out
    evaluate_kernel(program.instructions, program.constants, program.tables,
                    program.n_registers, program.outputs, inputs.position, inputs.normal,
                    inputs.true_normal, inputs.incoming, inputs.backfacing, inputs.generated,
                    inputs.object_coords, inputs.object_normal, inputs.object_location,
                    inputs.object_random, inputs.object_color, inputs.object_index,
                    inputs.uv, inputs.attributes, inputs.tangents, inputs.normal_to_world,
                    inputs.bump_points, im.bytes, im.shorts,
                    im.floats, im.tiles, im.slot_first, im.slot_count, out,
                    inputs.object_alpha, inputs.material_index, inputs.light_path)
    return out


def closure_params(program: pg.ShaderProgram, inputs: ShadingInputs,
                   params: np.ndarray, images: ProgramImages | None = None
                   ) -> dict[str, np.ndarray]:
    """Per-point material values from a program.

    params: (C, PARAM_COUNT) float32, the material's closure rows with their constant
    inputs (closure c of the material = row c). Returns ``{"params": (N, C, PARAM_COUNT)
    float32, "emission": (N, 3) or None, "alpha": (N,) or None, "normal": (N, 3) or
    None, "weight": (N, C) float64 or None}``: each program output written into its
    slot, the others copied from params; "weight" the factor of each closure's weight
    (TARGET_WEIGHT, non-negative; 1 for the rows without one), None when the
    program has no TARGET_WEIGHT output.
    """
    return closure_values(program, evaluate(program, inputs, images), params)


def closure_values(program: pg.ShaderProgram, values: np.ndarray, params: np.ndarray,
                   out: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """``closure_params`` from the program's outputs already evaluated, values (N, O)
    float32 (``evaluate``): one evaluation serves every material running the same
    program (``HitShader.shade``). out: None, or (N, C, PARAM_COUNT) float64 to write
    the rows into (they are then "params", the same values as the float32 rows:
    ``HitShader.shade`` writes them straight into its per-batch closure table instead of
    converting and concatenating a float32 copy)."""
    n = values.shape[0]
    rows = np.broadcast_to(np.asarray(params, np.float32), (n,) + np.shape(params))
    if out is None:
        rows = rows.copy()
    else:
        out[...] = rows
        rows = out
    result = {"params": rows, "emission": None, "alpha": None, "normal": None,
              "weight": None}
    for o, (_, target, closure, slot) in enumerate(program.outputs.tolist()):
        if target == pg.TARGET_CLOSURE:
            rows[:, closure, slot] = values[:, o]
        elif target == pg.TARGET_WEIGHT:
            if result["weight"] is None:
                result["weight"] = np.ones((n, rows.shape[1]), np.float64)
            # the exporter clamps each Mix factor (a product of them stays in [0, 1]);
            # a cut-out under another Mix divides it by the opacity (above 1 is
            # meant there); NaN or infinity means nothing
            w = np.nan_to_num(values[:, o].astype(np.float64), nan=0.0, posinf=0.0)
            result["weight"][:, closure] *= np.maximum(w, 0.0)
        elif target == pg.TARGET_ALPHA:
            result["alpha"] = values[:, o].copy()
        else:
            key = "emission" if target == pg.TARGET_EMISSION else "normal"
            if result[key] is None:
                result[key] = np.zeros((n, 3), np.float32)
            result[key][:, slot] = values[:, o]
    return result
