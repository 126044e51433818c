"""Image textures and cut-out transparency at surface hits.

Storage is ``scene.Textures`` (every image packed in one (P, 4) float32 linear-RGBA array,
row 0 at the bottom like Blender's ``Image.pixels``). This module owns:

- the lookup: bilinear between the four nearest texel centres, texel (i, j) centred at
  UV ((i + 0.5) / w, (j + 0.5) / h), UV (0, 0) the bottom-left corner of the image, repeat
  wrapping in both directions (Blender's default "Repeat" extension);
- ``SurfaceTextures``: built once per render, it turns a batch of hits (triangle,
  Embree barycentrics u, v, material) into the textured diffuse albedo (N, 3) and the
  opacity (N,) the kernels read, so texture code lives here and not in every kernel.
  Without textures ``albedo`` is ``diffuse[mat]`` (the same float64 values as before) and
  without cut-outs ``opacity`` is never needed;
- cut-out transparency (Principled Alpha): ``intersect`` skips surfaces stochastically
  (a hit of opacity a is passed straight through with probability 1 - a, the ray
  keeps its weight and its classification: no bounce is counted, so what is seen through
  a cut-out lands in the pass it would land in without the cut-out, as in Cycles where
  transparency is not a bounce), and ``transmittance`` gives shadow rays the product of
  (1 - a) over the surfaces they cross (deterministic, no noise).
- the sRGB decode (``srgb_to_linear``) the exporter uses: the exact IEC 61966-2-1 EOTF.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..scene import geometry

MAX_LAYERS = 64
"""Cut-out surfaces a ray passes at most (further ones are treated as opaque)."""


def srgb_to_linear(c) -> np.ndarray:
    """sRGB-encoded values in [0, 1] -> linear, float32 (exact piecewise EOTF)."""
    c = np.asarray(c, np.float32)
    return np.where(c <= np.float32(0.04045), c / np.float32(12.92),
                    ((c + np.float32(0.055)) / np.float32(1.055)) ** np.float32(2.4)
                    ).astype(np.float32)


@njit(cache=True, error_model="numpy")
def _wrap(x, n):
    """x (texel units, centre-relative) -> (i0, i1, f): the two texels and the weight of i1."""
    xm = x - n * math.floor(x / n)  # in [0, n) (repeat)
    i0f = math.floor(xm)
    f = xm - i0f
    i0 = min(int(i0f), n - 1)
    i1 = i0 + 1
    if i1 >= n:
        i1 = 0
    return i0, i1, f


@njit(cache=True, error_model="numpy")
def texel(pixels, offset, width, height, k, s, t, c):
    """Bilinear value of channel c of texture k at UV (s, t)."""
    w = width[k]
    h = height[k]
    if not (math.isfinite(s) and math.isfinite(t)):
        s, t = 0.0, 0.0
    i0, i1, fx = _wrap(s * w - 0.5, w)
    j0, j1, fy = _wrap(t * h - 0.5, h)
    base = offset[k]
    p00 = pixels[base + j0 * w + i0, c]
    p10 = pixels[base + j0 * w + i1, c]
    p01 = pixels[base + j1 * w + i0, c]
    p11 = pixels[base + j1 * w + i1, c]
    return ((1.0 - fy) * ((1.0 - fx) * p00 + fx * p10)
            + fy * ((1.0 - fx) * p01 + fx * p11))


@njit(cache=True, error_model="numpy")
def _hit_uv(tri_uv, t, u, v):
    """UV at Embree barycentrics (u, v) of triangle t: (1 - u - v) uv0 + u uv1 + v uv2."""
    w = 1.0 - u - v
    s = w * tri_uv[t, 0, 0] + u * tri_uv[t, 1, 0] + v * tri_uv[t, 2, 0]
    q = w * tri_uv[t, 0, 1] + u * tri_uv[t, 1, 1] + v * tri_uv[t, 2, 1]
    return s, q


@njit(cache=True, parallel=True, error_model="numpy")
def _lookup_kernel(pixels, offset, width, height, tex, uv, out):
    for i in prange(tex.shape[0]):
        for c in range(4):
            out[i, c] = texel(pixels, offset, width, height, tex[i], uv[i, 0], uv[i, 1], c)


def lookup(textures, tex, uv) -> np.ndarray:
    """Bilinear RGBA (N, 4) float64 of textures ``tex`` (N,) int at UVs (N, 2)."""
    tex = np.ascontiguousarray(np.broadcast_to(np.asarray(tex, np.int64), (len(uv),)))
    uv = np.ascontiguousarray(uv, np.float64).reshape(-1, 2)
    out = np.empty((uv.shape[0], 4))
    if uv.shape[0]:
        _lookup_kernel(textures.pixels, textures.offset, textures.width.astype(np.int64),
                       textures.height.astype(np.int64), tex, uv, out)
    return out


@njit(cache=True, parallel=True, error_model="numpy")
def _albedo_kernel(diffuse, tex_of_mat, tri_uv, pixels, offset, width, height, prim, u, v,
                   mat, out):
    for i in prange(prim.shape[0]):
        t = prim[i]
        if t < 0:
            out[i, 0] = 0.0
            out[i, 1] = 0.0
            out[i, 2] = 0.0
            continue
        m = mat[i]
        k = tex_of_mat[m]
        if k < 0:
            out[i, 0] = diffuse[m, 0]
            out[i, 1] = diffuse[m, 1]
            out[i, 2] = diffuse[m, 2]
            continue
        s, q = _hit_uv(tri_uv, t, np.float64(u[i]), np.float64(v[i]))
        for c in range(3):
            out[i, c] = diffuse[m, c] * texel(pixels, offset, width, height, k, s, q, c)


@njit(cache=True, parallel=True, error_model="numpy")
def _opacity_kernel(opacity, tex_of_mat, tri_mat, tri_uv, pixels, offset, width, height,
                    prim, u, v, out):
    for i in prange(prim.shape[0]):
        t = prim[i]
        if t < 0:
            out[i] = 1.0
            continue
        m = tri_mat[t]
        a = opacity[m]
        k = tex_of_mat[m]
        if k >= 0:
            s, q = _hit_uv(tri_uv, t, np.float64(u[i]), np.float64(v[i]))
            a *= min(max(texel(pixels, offset, width, height, k, s, q, 3), 0.0), 1.0)
        out[i] = a


class SurfaceTextures:
    """Per-render texture and opacity tables (built once, read by every batch of hits).

    diffuse: (M, 3) float64 diffuse lobe weights (``bsdf.material_table``'s "diffuse").
    textured: some material has a diffuse texture; cutout: some material can be
    (partly) transparent. Both False for scenes without them: then ``albedo`` is a plain
    gather and the intersection helpers call Embree directly.
    """

    def __init__(self, scene, diffuse: np.ndarray):
        mats = scene.materials
        tx = scene.textures
        self.diffuse = diffuse
        self.tex_of_mat = np.ascontiguousarray(mats.diffuse_texture_index(), np.int64)
        self.alpha_tex = np.ascontiguousarray(mats.alpha_texture_index(), np.int64)
        self.opacity_of_mat = np.ascontiguousarray(np.clip(mats.opacity(), 0.0, 1.0))
        # Materials some triangle uses (bincount: O(T), no sort of millions of triangles).
        used = np.bincount(scene.mesh.material_index, minlength=mats.count)[:mats.count] > 0
        self.textured = bool(np.any((self.tex_of_mat >= 0) & used))
        self.cutout = bool(np.any(((self.opacity_of_mat < 1.0) | (self.alpha_tex >= 0)) & used))
        self.tri_mat = np.ascontiguousarray(scene.mesh.material_index, np.int32)
        self._scene_uvs = scene.mesh.uvs
        self.tri_uv = (np.ascontiguousarray(scene.mesh.uvs, np.float32)
                       if self.textured or self.cutout else np.zeros((0, 3, 2), np.float32))
        self.pixels = np.ascontiguousarray(tx.pixels, np.float32)
        self.offset = np.ascontiguousarray(tx.offset, np.int64)
        self.width = np.ascontiguousarray(tx.width, np.int64)
        self.height = np.ascontiguousarray(tx.height, np.int64)
        self.alpha_programmed = np.zeros(mats.count, bool)
        self.program_alpha = None
        self.shadow_path = self.with_length = None
        self._used = used

    def use_program_alpha(self, programmed: np.ndarray, alpha_at, shadow_path=None,
                          with_length=None) -> None:
        """Materials whose opacity a shader program computes: programmed (M,) bool, and
        alpha_at(prim, u, v, path) -> (N,) float64 in [0, 1] the program's opacity at hits
        on them (``HitShader.alpha_at``; path their Light Path context or None), which
        multiplies the material's own. shadow_path(lengths (N,)) -> (N, K) the Light
        Path context of shadow-ray hits, with_length(path (N, K), lengths (N,)) -> (N, K)
        a context with its Ray Length set (core/shading/light_path.py ``shadow``,
        ``with_length``; None: no context, zeros)."""
        self.alpha_programmed = np.asarray(programmed, bool)
        self.program_alpha = alpha_at
        self.shadow_path, self.with_length = shadow_path, with_length
        if np.any(self.alpha_programmed & self._used):
            self.cutout = True
            if self.tri_uv.shape[0] == 0:
                self.tri_uv = np.ascontiguousarray(self._scene_uvs, np.float32)

    def albedo(self, prim, u, v, mat) -> np.ndarray:
        """(N, 3) float64 diffuse albedo at N hits (prim (N,) triangle, -1 = none -> 0;
        u, v Embree barycentrics; mat (N,) material of the triangle)."""
        if not self.textured:
            return self.diffuse[mat]
        out = np.empty((prim.shape[0], 3))
        if prim.shape[0]:
            _albedo_kernel(self.diffuse, self.tex_of_mat, self.tri_uv, self.pixels, self.offset,
                           self.width, self.height, np.ascontiguousarray(prim),
                           np.ascontiguousarray(u), np.ascontiguousarray(v),
                           np.ascontiguousarray(mat), out)
        return out

    def photon_albedo(self, prim, u, v) -> np.ndarray:
        """Like ``albedo`` for a photon wavefront (misses allowed), or an empty (0, 3)
        array when nothing is textured (the scatter kernel then reads the material table)."""
        if not self.textured:
            return np.zeros((0, 3))
        mat = self.tri_mat[np.maximum(prim, 0)]
        return self.albedo(prim, u, v, mat)

    def opacity(self, prim, u, v, path=None) -> np.ndarray:
        """(N,) float64 opacity in [0, 1] at N hits (1 on misses); path: the rays' Light
        Path context for programmed cut-outs ((N, K) float32, core/shading/light_path.py;
        None: zeros, no flag)."""
        out = np.empty(prim.shape[0])
        if prim.shape[0]:
            _opacity_kernel(self.opacity_of_mat, self.alpha_tex, self.tri_mat, self.tri_uv,
                            self.pixels, self.offset, self.width, self.height,
                            np.ascontiguousarray(prim), np.ascontiguousarray(u),
                            np.ascontiguousarray(v), out)
            if self.program_alpha is not None:
                sel = np.flatnonzero(prim >= 0)
                sel = sel[self.alpha_programmed[self.tri_mat[prim[sel]]]]
                if sel.size:
                    out[sel] *= self.program_alpha(
                        prim[sel], u[sel], v[sel], None if path is None else path[sel])
        return out

    def photon_opacity(self, prim, u, v, path=None) -> np.ndarray:
        """``opacity`` for a photon wavefront (path: the hits' Light Path context), or an
        empty (0,) array without cut-outs."""
        if not self.cutout:
            return np.zeros(0)
        return self.opacity(prim, u, v, path)

    # --- rays through cut-outs ---------------------------------------------------------

    def intersect(self, accel, tri_vertices, tri_normals, extent, origins, directions,
                  tmax, uniforms, path=None):
        """Nearest hit that is not passed through (see the module doc): an ``accel.Hits``
        with t measured from the original origins.

        uniforms(index (n,) int64 into the batch, layer) -> (n,) uniforms in [0, 1): the
        random numbers deciding pass-through at the layer-th cut-out along each ray.
        path: (N, K) float32 the rays' Light Path context for programmed cut-outs (its Ray
        Length is set to each segment's, from the origin or the last cut-out passed, as
        Cycles' transparent bounces), or None (zeros).
        """
        hits = accel.intersect(origins, directions, tmax)
        if not self.cutout:
            return hits
        prim, t, u, v = hits.prim.copy(), hits.t.copy(), hits.u.copy(), hits.v.copy()
        o0 = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        limit = None if tmax is None else np.broadcast_to(
            np.asarray(tmax, np.float64), (o0.shape[0],))
        active = np.flatnonzero(prim >= 0)
        base = np.zeros(o0.shape[0])  # where each ray's current segment starts
        for layer in range(MAX_LAYERS):
            if active.size == 0:
                break
            lp = None
            if path is not None and self.with_length is not None:
                lp = self.with_length(path[active], t[active] - base[active])
            a = self.opacity(prim[active], u[active], v[active], lp)
            through = active[uniforms(active, layer) >= a]
            if through.size == 0:
                break
            o_new, t_base = self._past(tri_vertices, tri_normals, extent, prim[through],
                                       u[through], v[through], o0[through], d[through])
            tm = None if limit is None else np.maximum(limit[through] - t_base, 0.0)
            h2 = accel.intersect(o_new, d[through], tm)
            ok = h2.prim >= 0
            prim[through] = h2.prim
            u[through], v[through] = h2.u, h2.v
            t[through] = np.where(ok, t_base + h2.t, np.inf).astype(np.float32)
            base[through] = t_base
            active = through[ok]
        return type(hits)(prim, t, u, v)

    def transmittance(self, accel, tri_vertices, tri_normals, extent, origins, directions,
                      tfar) -> np.ndarray:
        """(N,) float64 fraction of light passing along shadow rays: 0 or 1 without
        cut-outs (Embree's occlusion test), else the product of (1 - opacity) over the
        surfaces crossed before tfar."""
        if not self.cutout:
            return (~accel.occluded(origins, directions, tfar)).astype(np.float64)
        n = origins.shape[0]
        trans = np.ones(n)
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        left = np.broadcast_to(np.asarray(tfar, np.float64), (n,)).copy()
        active = np.arange(n)
        cur_o = o.copy()
        for _ in range(MAX_LAYERS + 1):
            if active.size == 0:
                break
            h = accel.intersect(cur_o[active], d[active], left[active])
            hit = h.prim >= 0
            idx = active[hit]
            a = self.opacity(h.prim[hit], h.u[hit], h.v[hit],
                             None if self.shadow_path is None else self.shadow_path(h.t[hit]))
            trans[idx] *= 1.0 - a
            go = (trans[idx] > 0.0)
            idx = idx[go]
            if idx.size == 0:
                break
            hh = np.flatnonzero(hit)[go]
            o_new, t_base = self._past(tri_vertices, tri_normals, extent, h.prim[hh], h.u[hh],
                                       h.v[hh], cur_o[idx], d[idx])
            cur_o[idx] = o_new
            left[idx] = np.maximum(left[idx] - t_base, 0.0)
            active = idx
        else:
            trans[active] = 0.0  # too many layers: opaque
        return trans

    def _past(self, tri_vertices, tri_normals, extent, prim, u, v, o, d):
        """Origins just beyond the hits (offset to the far side of the surface) and their
        distance along d from o."""
        sp = geometry.surface_points(tri_vertices, tri_normals, self.tri_mat, prim, u, v, d,
                                     extent)
        o_new = geometry.offset_points(sp.position, sp.geometric_normal, sp.eps, d)
        t_base = np.einsum("ij,ij->i", o_new - o, d)
        return o_new, t_base
