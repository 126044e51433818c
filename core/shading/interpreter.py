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
from .noise import noise_texture
from .voronoi import voronoi_texture
from .images import image_sample, image_projected
from .normals import bump, normal_map, tangent
from ..scene.images import ProgramImages

_F = pg.FIRST_OPERAND
_CHUNK = 256


@njit(inline="always", **dict(cache=True, error_model="numpy"))
def _load_row(r, o, src, idx, i, P, N, Ng, I, back, gen, obj, objn, oloc, orand, ocol, oidx, uv,
              attr, tan, n2w, oalpha, midx, lp):
    """Source src (index idx) of row i of the inputs into registers r[o:o + 3]."""
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
        r[o] = lp[i, idx]
        r[o + 1] = r[o]
        r[o + 2] = r[o]
    elif src == 20 or src == 21:  # SOURCE_OBJECT_ALPHA, SOURCE_MATERIAL_INDEX
        r[o] = oalpha[i] if src == 20 else midx[i]
        r[o + 1] = r[o]
        r[o + 2] = r[o]
    elif src == 4 or src == 10 or src == 14:
        r[o] = back[i] if src == 4 else (orand[i] if src == 10 else oidx[i])
        r[o + 1] = r[o]
        r[o + 2] = r[o]
    elif src == 8:
        if idx < uv.shape[0]:
            r[o], r[o + 1] = uv[idx, i, 0], uv[idx, i, 1]
        else:
            r[o], r[o + 1] = 0.0, 0.0
        r[o + 2] = 0.0
    elif src == 11 or src == 12:
        if idx < attr.shape[0]:
            if src == 11:
                r[o], r[o + 1], r[o + 2] = attr[idx, i, 0], attr[idx, i, 1], attr[idx, i, 2]
            else:
                r[o] = r[o + 1] = r[o + 2] = attr[idx, i, 3]
        else:
            r[o] = r[o + 1] = r[o + 2] = 0.0
    elif src == 15 or src == 16:  # SOURCE_TANGENT, SOURCE_TANGENT_SIGN
        if idx < tan.shape[0]:
            if src == 15:
                r[o], r[o + 1], r[o + 2] = tan[idx, i, 0], tan[idx, i, 1], tan[idx, i, 2]
            else:
                r[o] = r[o + 1] = r[o + 2] = tan[idx, i, 3]
        else:
            r[o] = r[o + 1] = r[o + 2] = 0.0
    elif src == 17:  # SOURCE_NORMAL_TO_WORLD, row idx
        r[o], r[o + 1], r[o + 2] = n2w[i, idx, 0], n2w[i, idx, 1], n2w[i, idx, 2]
    else:
        r[o], r[o + 1], r[o + 2] = a[i, 0], a[i, 1], a[i, 2]


@njit(inline="always", **dict(cache=True, error_model="numpy"))
def _load_input(r, ins, i, stride, P, N, Ng, I, back, gen, obj, objn, oloc, orand, ocol, oidx,
                uv, attr, tan, n2w, oalpha, midx, lp):
    """OP_INPUT ins at point i. A bump offset (ins[3] 1 or 2, with stride = the points'
    count: the offset rows follow them) reads the source at P + w dPdx (or dPdy), w =
    ins[4] BUMP_WIDTH_UNIT, interpolated linearly from the point to its row at P + dPdx
    (every input is affine in the barycentrics over a triangle, the normal nearly so)."""
    src, idx, o = ins[1], ins[2], ins[_F]
    if src == 18 or src == 19:  # SOURCE_BUMP_DPDX / DPDY
        j = i + (1 if src == 18 else 2) * stride
        for c in range(3):
            r[o + c] = (np.float64(P[j, c]) - np.float64(P[i, c])) if stride > 0 else 0.0
        return
    _load_row(r, o, src, idx, i, P, N, Ng, I, back, gen, obj, objn, oloc, orand, ocol, oidx,
              uv, attr, tan, n2w, oalpha, midx, lp)
    if ins[3] != 0 and stride > 0:
        x, y, z = r[o], r[o + 1], r[o + 2]
        _load_row(r, o, src, idx, i + ins[3] * stride, P, N, Ng, I, back, gen, obj, objn,
                  oloc, orand, ocol, oidx, uv, attr, tan, n2w, oalpha, midx, lp)
        w = ins[4] * pg.BUMP_WIDTH_UNIT
        r[o] = x + w * (r[o] - x)
        r[o + 1] = y + w * (r[o + 1] - y)
        r[o + 2] = z + w * (r[o + 2] - z)


@njit(inline="always", **dict(cache=True, error_model="numpy"))
def _run(r, ins, tables, im_bytes, im_shorts, im_floats, im_tiles, im_first, im_count, px):
    """Execute one instruction (not OP_INPUT) on register file r (float64); the im_*
    arrays are ``ProgramImages``' fields, px a (8,) float64 scratch."""
    op = ins[0]
    a = ins[_F:]
    if op == pg.OP_MATH:
        v = math_op(ins[1], r[a[0]], r[a[1]], r[a[2]])
        r[a[3]] = clamp(v, 0.0, 1.0) if ins[2] else v
    elif op == pg.OP_VECTOR_MATH:
        x, y, z, s = vector_math(ins[1], r[a[0]], r[a[0] + 1], r[a[0] + 2], r[a[1]],
                                 r[a[1] + 1], r[a[1] + 2], r[a[2]], r[a[2] + 1], r[a[2] + 2],
                                 r[a[3]])
        r[a[4]], r[a[4] + 1], r[a[4] + 2], r[a[5]] = x, y, z, s
    elif op == pg.OP_MIX_FLOAT:
        t = clamp(r[a[0]], 0.0, 1.0) if ins[1] else r[a[0]]
        r[a[3]] = r[a[1]] * (1.0 - t) + r[a[2]] * t
    elif op == pg.OP_MIX_VECTOR or op == pg.OP_MIX_VECTOR_NONUNIFORM:
        for c in range(3):
            t = r[a[0] + c] if op == pg.OP_MIX_VECTOR_NONUNIFORM else r[a[0]]
            if ins[1]:
                t = clamp(t, 0.0, 1.0)
            r[a[3] + c] = r[a[1] + c] * (1.0 - t) + r[a[2] + c] * t
    elif op == pg.OP_MIX_COLOR:
        t = clamp(r[a[0]], 0.0, 1.0) if ins[2] else r[a[0]]
        x, y, z = blend(ins[1], t, r[a[1]], r[a[1] + 1], r[a[1] + 2], r[a[2]], r[a[2] + 1],
                        r[a[2] + 2])
        if ins[3]:
            x, y, z = clamp(x, 0.0, 1.0), clamp(y, 0.0, 1.0), clamp(z, 0.0, 1.0)
        r[a[3]], r[a[3] + 1], r[a[3] + 2] = x, y, z
    elif op == pg.OP_MAP_RANGE:
        r[a[6]] = map_range(ins[1], ins[2], r[a[0]], r[a[1]], r[a[2]], r[a[3]], r[a[4]],
                            r[a[5]])
    elif op == pg.OP_VECTOR_MAP_RANGE:
        for c in range(3):
            r[a[6] + c] = vector_map_range_1(ins[1], ins[2], r[a[0] + c], r[a[1] + c],
                                             r[a[2] + c], r[a[3] + c], r[a[4] + c],
                                             r[a[5] + c])
    elif op == pg.OP_CLAMP:
        lo, hi = r[a[1]], r[a[2]]
        if ins[1] == 1 and lo > hi:
            lo, hi = hi, lo
        r[a[3]] = clamp(r[a[0]], lo, hi)
    elif op == pg.OP_SEPARATE:
        x, y, z = r[a[0]], r[a[0] + 1], r[a[0] + 2]
        if ins[1] == 1:
            x, y, z = rgb_to_hsv(x, y, z)
        elif ins[1] == 2:
            x, y, z = rgb_to_hsl(x, y, z)
        r[a[1]], r[a[2]], r[a[3]] = x, y, z
    elif op == pg.OP_COMBINE:
        x, y, z = r[a[0]], r[a[1]], r[a[2]]
        if ins[1] == 1:
            x, y, z = hsv_to_rgb(x, y, z)
        elif ins[1] == 2:
            x, y, z = hsl_to_rgb(x, y, z)
        r[a[3]], r[a[3] + 1], r[a[3] + 2] = x, y, z
    elif op == pg.OP_RAMP:
        f = r[a[0]]
        for c in range(3):
            r[a[1] + c] = ramp_lookup(tables, ins[1], ins[2], f, ins[3] != 0, c)
        r[a[2]] = ramp_lookup(tables, ins[1], ins[2], f, ins[3] != 0, 3)
    elif op == pg.OP_MAPPING:
        x, y, z = mapping(ins[1], r[a[0]], r[a[0] + 1], r[a[0] + 2], r[a[1]], r[a[1] + 1],
                          r[a[1] + 2], r[a[2]], r[a[2] + 1], r[a[2] + 2], r[a[3]],
                          r[a[3] + 1], r[a[3] + 2])
        r[a[4]], r[a[4] + 1], r[a[4] + 2] = x, y, z
    elif op == pg.OP_INVERT:
        f = r[a[0]]
        for c in range(3):
            x = r[a[1] + c]
            r[a[2] + c] = f * (1.0 - x) + (1.0 - f) * x
    elif op == pg.OP_GAMMA:
        g = r[a[1]]
        for c in range(3):
            x = r[a[0] + c]
            if g == 0.0:
                x = 1.0
            elif x > 0.0:
                x = x ** g
            r[a[2] + c] = x
    elif op == pg.OP_HSV:
        fac = r[a[3]]
        cr, cg, cb = r[a[4]], r[a[4] + 1], r[a[4] + 2]
        h, s, v = rgb_to_hsv(cr, cg, cb)
        h = h + r[a[0]] + 0.5
        h = h - math.floor(h)
        s = clamp(s * r[a[1]], 0.0, 1.0)
        v *= r[a[2]]
        x, y, z = hsv_to_rgb(h, s, v)
        r[a[5]] = max(fac * x + (1.0 - fac) * cr, 0.0)
        r[a[5] + 1] = max(fac * y + (1.0 - fac) * cg, 0.0)
        r[a[5] + 2] = max(fac * z + (1.0 - fac) * cb, 0.0)
    elif op == pg.OP_BRIGHT_CONTRAST:
        ka = 1.0 + r[a[2]]
        kb = r[a[1]] - r[a[2]] * 0.5
        for c in range(3):
            r[a[3] + c] = max(ka * r[a[0] + c] + kb, 0.0)
    elif op == pg.OP_RGB_TO_BW:
        r[a[2]] = (r[a[0]] * r[a[1]] + r[a[0] + 1] * r[a[1] + 1]
                   + r[a[0] + 2] * r[a[1] + 2])
    elif op == pg.OP_CHECKER:
        s = r[a[3]]
        f = checker(r[a[0]] * s, r[a[0] + 1] * s, r[a[0] + 2] * s)
        src = a[1] if f == 1.0 else a[2]
        r[a[4]], r[a[4] + 1], r[a[4] + 2] = r[src], r[src + 1], r[src + 2]
        r[a[5]] = f
    elif op == pg.OP_GRADIENT:
        f = gradient(ins[1], r[a[0]], r[a[0] + 1], r[a[0] + 2])
        r[a[1]] = r[a[1] + 1] = r[a[1] + 2] = f
        r[a[2]] = f
    elif op == pg.OP_WHITE_NOISE:
        v, x, y, z = white_noise(ins[1], r[a[0]], r[a[0] + 1], r[a[0] + 2], r[a[1]])
        r[a[2]] = v
        r[a[3]], r[a[3] + 1], r[a[3] + 2] = x, y, z
    elif op == pg.OP_NOISE:
        v, x, y, z = noise_texture(r[a[0]], r[a[0] + 1], r[a[0] + 2], r[a[1]], ins[1],
                                   r[a[2]], r[a[3]], r[a[4]], r[a[5]], r[a[6]], r[a[7]],
                                   r[a[8]], ins[2], ins[3] != 0, ins[4] != 0)
        r[a[9]] = v
        r[a[10]], r[a[10] + 1], r[a[10] + 2] = x, y, z
    elif op == pg.OP_VORONOI:
        scale = r[a[2]]
        d, cr, cg, cb, px, py, pz, pw = voronoi_texture(
            r[a[0]], r[a[0] + 1], r[a[0] + 2], r[a[1]], ins[1], ins[2], ins[3],
            (ins[4] & 1) != 0, scale, r[a[3]], r[a[4]], r[a[5]], r[a[6]], r[a[7]], r[a[8]],
            (ins[4] & 2) != 0)
        r[a[9]] = d
        r[a[10]], r[a[10] + 1], r[a[10] + 2] = cr, cg, cb
        r[a[11]], r[a[11] + 1], r[a[11] + 2] = px, py, pz
        r[a[12]] = pw
    elif op == pg.OP_WAVE:
        s = r[a[1]]
        f = wave(ins[1], ins[2], ins[3], ins[4], r[a[0]] * s, r[a[0] + 1] * s, r[a[0] + 2] * s,
                 r[a[2]], r[a[3]], r[a[4]], r[a[5]], r[a[6]])
        r[a[7]] = r[a[7] + 1] = r[a[7] + 2] = f
        r[a[8]] = f
    elif op == pg.OP_MAGIC:
        x, y, z = magic(r[a[0]], r[a[0] + 1], r[a[0] + 2], r[a[1]], ins[1], r[a[2]])
        r[a[3]], r[a[3] + 1], r[a[3] + 2] = x, y, z
        r[a[4]] = (x + y + z) / 3.0
    elif op == pg.OP_BRICK:
        s = r[a[4]]
        tint, f = brick(r[a[0]] * s, r[a[0] + 1] * s, r[a[5]], r[a[6]], r[a[7]], r[a[8]],
                        r[a[9]], r[a[10]], ins[1], r[a[11]], ins[2])
        for c in range(3):
            c1 = r[a[1] + c]
            if f != 1.0:
                c1 = (1.0 - tint) * c1 + tint * r[a[2] + c]
            r[a[12] + c] = c1 * (1.0 - f) + r[a[3] + c] * f
        r[a[13]] = f
    elif op == pg.OP_BLACKBODY:
        x, y, z = blackbody_rec709(r[a[0]])
        for c in range(3):  # row c of the Rec.709 -> scene linear matrix is operand 1 + c
            m = a[1 + c]
            r[a[4] + c] = max(r[m] * x + r[m + 1] * y + r[m + 2] * z, 0.0)
    elif op == pg.OP_CURVES:
        fac = r[a[0]]
        lo, hi = r[a[2]], r[a[3]]
        for c in range(3):
            v = r[a[1] + c]
            t = (v - lo) / (hi - lo)
            mapped = curve_lookup(tables, ins[1], ins[2], t, c) if ins[3] else \
                ramp_lookup(tables, ins[1], ins[2], t, True, c)
            r[a[4] + c] = (1.0 - fac) * v + fac * mapped
    elif op == pg.OP_FLOAT_CURVE:
        fac = r[a[0]]
        v = r[a[1]]
        t = (v - r[a[2]]) / (r[a[3]] - r[a[2]])
        mapped = curve_lookup(tables, ins[1], ins[2], t, 0) if ins[3] else \
            ramp_lookup(tables, ins[1], ins[2], t, True, 0)
        r[a[4]] = (1.0 - fac) * v + fac * mapped
    elif op == pg.OP_IMAGE:
        image_sample(im_bytes, im_shorts, im_floats, im_tiles, im_first, im_count, ins[1],
                     r[a[0]], r[a[0] + 1], ins[2], ins[3], ins[4] != 0, px)
        r[a[1]], r[a[1] + 1], r[a[1] + 2], r[a[2]] = px[0], px[1], px[2], px[3]
    elif op == pg.OP_IMAGE_PROJECTED:
        image_projected(im_bytes, im_shorts, im_floats, im_tiles, im_first, im_count, ins[1],
                        r[a[0]], r[a[0] + 1], r[a[0] + 2], r[a[1]], r[a[1] + 1], r[a[1] + 2],
                        r[a[2]], ins[2], ins[3], (ins[4] & 1) != 0, ins[4] >> 1, px[:4],
                        px[4:])
        r[a[3]], r[a[3] + 1], r[a[3] + 2], r[a[4]] = px[0], px[1], px[2], px[3]
    elif op == pg.OP_FRESNEL or op == pg.OP_LAYER_WEIGHT:
        cosi = (r[a[1]] * r[a[2]] + r[a[1] + 1] * r[a[2] + 1]
                + r[a[1] + 2] * r[a[2] + 2])
        back = r[a[3]] != 0.0
        if op == pg.OP_FRESNEL:
            r[a[4]] = fresnel_node(r[a[0]], cosi, back)
        else:
            r[a[4]], r[a[5]] = layer_weight(r[a[0]], cosi, back)
    elif op == pg.OP_TRANSFORM:
        x, y, z = r[a[0]], r[a[0] + 1], r[a[0] + 2]
        w = 1.0
        if ins[1] == 1:
            m = a[7]
            w = r[m] * x + r[m + 1] * y + r[m + 2] * z + r[a[8]]
            w = 1.0 / w if w != 0.0 else 0.0
        for c in range(3):
            m = a[1 + 2 * c]
            r[a[9] + c] = (r[m] * x + r[m + 1] * y + r[m + 2] * z + r[a[2 + 2 * c]]) * w
    elif op == pg.OP_WAVELENGTH:
        x, y, z = wavelength_xyz(r[a[0]])
        for c in range(3):  # row c of the XYZ -> scene linear matrix is operand 1 + c
            m = a[1 + c]
            r[a[4] + c] = max((r[m] * x + r[m + 1] * y + r[m + 2] * z) * WAVELENGTH_SCALE,
                              0.0)
    elif op == pg.OP_NORMAL_MAP:
        c, t, n, m0, m1, m2 = a[0], a[2], a[4], a[6], a[7], a[8]
        x, y, z = normal_map(ins[1], ins[2], r[c], r[c + 1], r[c + 2], r[a[1]], r[t], r[t + 1],
                             r[t + 2], r[a[3]], r[n], r[n + 1], r[n + 2], r[a[5]], r[m0],
                             r[m0 + 1], r[m0 + 2], r[m1], r[m1 + 1], r[m1 + 2], r[m2],
                             r[m2 + 1], r[m2 + 2])
        r[a[9]], r[a[9] + 1], r[a[9] + 2] = x, y, z
    elif op == pg.OP_BUMP:
        n, dx, dy = a[6], a[7], a[8]
        x, y, z = bump(ins[1] != 0, r[a[0]], r[a[1]], r[a[2]], r[a[3]], r[a[4]], r[a[5]],
                       r[n], r[n + 1], r[n + 2], r[dx], r[dx + 1], r[dx + 2], r[dy],
                       r[dy + 1], r[dy + 2])
        r[a[9]], r[a[9] + 1], r[a[9] + 2] = x, y, z
    elif op == pg.OP_TANGENT:
        v, m0, m1, m2, n = a[0], a[1], a[2], a[3], a[4]
        x, y, z = tangent(ins[1], r[v], r[v + 1], r[v + 2], r[m0], r[m0 + 1], r[m0 + 2],
                          r[m1], r[m1 + 1], r[m1 + 2], r[m2], r[m2 + 1], r[m2 + 2], r[n],
                          r[n + 1], r[n + 2])
        r[a[5]], r[a[5] + 1], r[a[5] + 2] = x, y, z


@njit(parallel=True, **dict(cache=True, error_model="numpy"))
def evaluate_kernel(instructions, constants, tables, n_registers, outputs, P, N, Ng, I, back,
                    gen, obj, objn, oloc, orand, ocol, oidx, uv, attr, tan, n2w, stride,
                    im_bytes, im_shorts, im_floats, im_tiles, im_first, im_count, out, oalpha,
                    midx, lp):
    """Run the program on every point: out[i, o] = register outputs[o, 0] of point i.
    (N, O) float32 ``out``; every other array as ``ShadingInputs`` / ``ShaderProgram`` /
    ``ProgramImages`` (im_*); stride ``ShadingInputs.bump_points``; lp
    ``ShadingInputs.light_path``."""
    n = out.shape[0]
    k = constants.shape[0]
    n_chunks = (n + _CHUNK - 1) // _CHUNK
    for c in prange(n_chunks):
        r = np.zeros(n_registers, np.float64)
        px = np.zeros(8, np.float64)
        for i in range(c * _CHUNK, min(n, (c + 1) * _CHUNK)):
            for j in range(k):
                r[j] = constants[j]
            for s in range(instructions.shape[0]):
                ins = instructions[s]
                if ins[0] == pg.OP_INPUT:
                    _load_input(r, ins, i, stride, P, N, Ng, I, back, gen, obj, objn, oloc,
                                orand, ocol, oidx, uv, attr, tan, n2w, oalpha, midx, lp)
                else:
                    _run(r, ins, tables, im_bytes, im_shorts, im_floats, im_tiles,
                         im_first, im_count, px)
            for o in range(outputs.shape[0]):
                out[i, o] = r[outputs[o, 0]]


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


def closure_values(program: pg.ShaderProgram, values: np.ndarray, params: np.ndarray
                   ) -> dict[str, np.ndarray]:
    """``closure_params`` from the program's outputs already evaluated, values (N, O)
    float32 (``evaluate``): one evaluation serves every material running the same
    program (``HitShader.shade``)."""
    n = values.shape[0]
    rows = np.broadcast_to(np.asarray(params, np.float32), (n,) + np.shape(params)).copy()
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
