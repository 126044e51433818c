"""The closure evaluator: a material's BSDF at one hit, for every integrator and the photons.

A material is a weighted sum of closures (core/scene/closures.py). ``table(materials)``
turns ``Materials.closure_table()`` into a ``ClosureTable`` (float64 / int32 arrays plus the
albedo look-up tables) that the numba functions below take as one argument:

- ``eval_bsdf``: f * |cos(ns, wi)| summed over the non-delta lobes (RGB), and the pdf with
  which ``sample_bsdf`` would have produced wi (solid angle, 1/sr; for MIS);
- ``sample_bsdf``: pick a closure by its sample weight, a lobe inside it, a direction;
  return the direction, the path weight f |cos| / pdf (RGB), the pdf (0 for a delta lobe) and
  the flags ``LOBE_*`` (0: no direction, the path ends);
- ``albedo``: the directional albedo of the diffuse-like lobes (0 when the material has none:
  photons are not stored there) and of the whole material (Russian roulette).

Conventions: wo points to the viewer (or where the photon came from), wi to the light (or
where the photon goes); every vector unit, world space. ns, ng: shading and geometric
normals, ng flipped to wo's side (ns is flipped to ng's side here if it is not); t: a unit
tangent (any vector not parallel to ns when the mesh has none: ``DEFAULT_TANGENT`` helps).
``entering``: wo is on the front of the mesh's geometric normal, so a dielectric's eta is
its IOR (else 1 / IOR). c0..c2: the texel colour that multiplies the COLOR slot (1, 1, 1
without a texture).

Like Cycles, radiance through a refraction is not scaled by eta^2 (bsdf_microfacet.h).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from ..scene import closures as cl
from . import bsdf

LOBE_DELTA = 1      # a singular direction (mirror, smooth glass): pdf 0, no eval
LOBE_GLOSSY = 2     # a rough microfacet lobe
LOBE_DIFFUSE = 4    # Lambert, Oren-Nayar, translucent, sheen
LOBE_TRANSMIT = 8   # wi is on the far side of the surface (ng)

DEFAULT_TANGENT = (1.0, 0.0, 0.0)
"""A tangent for meshes without one: ``frame`` makes it orthogonal to ns (and falls back to
another axis when it is parallel), as Cycles does with a zero tangent."""


class ClosureTable(NamedTuple):
    """The closure table as the kernels read it (``table``).

    kind: (C,) int32 CLOSURE_*; weight: (C, 3) float64; params: (C, PARAM_COUNT) float64;
    texture: (C,) int32 (-1 none); first, count: (M,) int32 closures of material m.
    """
    kind: np.ndarray
    weight: np.ndarray
    params: np.ndarray
    texture: np.ndarray
    first: np.ndarray
    count: np.ndarray


def table(materials) -> ClosureTable:
    """The ``ClosureTable`` of a ``core.scene.contract.Materials`` (stored or derived
    closures, ``Materials.closure_table()``), float64 / int32 contiguous copies."""
    t = materials.closure_table()
    return ClosureTable(
        kind=np.ascontiguousarray(t["kind"], np.int32),
        weight=np.ascontiguousarray(t["weight"], np.float64).reshape(-1, 3),
        params=np.ascontiguousarray(t["params"], np.float64).reshape(-1, cl.PARAM_COUNT),
        texture=np.ascontiguousarray(t["texture"], np.int32),
        first=np.ascontiguousarray(t["first"], np.int32),
        count=np.ascontiguousarray(t["count"], np.int32))


# --- placeholder lobes (the interface commit): Lambert, GGX without Fresnel, smooth glass ----

@njit(cache=True, error_model="numpy")
def frame(nsx, nsy, nsz, tx, ty, tz):
    """Orthonormal shading frame (t, b, n) from ns and a tangent (Gram-Schmidt; another
    axis when t is parallel to ns). Returns 9 floats tx, ty, tz, bx, by, bz."""
    d = tx * nsx + ty * nsy + tz * nsz
    ux, uy, uz = tx - d * nsx, ty - d * nsy, tz - d * nsz
    ln = np.sqrt(ux * ux + uy * uy + uz * uz)
    if ln < 1e-6:
        ux, uy, uz, _, _, _ = sampling.basis(nsx, nsy, nsz)
        ln = 1.0
    ux, uy, uz = ux / ln, uy / ln, uz / ln
    bx = nsy * uz - nsz * uy
    by = nsz * ux - nsx * uz
    bz = nsx * uy - nsy * ux
    return ux, uy, uz, bx, by, bz


@njit(cache=True, error_model="numpy")
def eval_bsdf(tab, m, c0, c1, c2, wox, woy, woz, wix, wiy, wiz, nsx, nsy, nsz,
              ngx, ngy, ngz, tx, ty, tz):
    """f * |cos(ns, wi)| over material m's non-delta lobes (RGB) and the solid-angle pdf
    ``sample_bsdf`` gives wi: (f0, f1, f2, pdf)."""
    if nsx * ngx + nsy * ngy + nsz * ngz < 0.0:
        nsx, nsy, nsz = -nsx, -nsy, -nsz
    ci = nsx * wix + nsy * wiy + nsz * wiz
    if ci <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    pdf = 0.0
    total = 0.0
    for c in range(tab.first[m], tab.first[m] + tab.count[m]):
        k = tab.kind[c]
        p = tab.params[c]
        w0, w1, w2 = tab.weight[c, 0], tab.weight[c, 1], tab.weight[c, 2]
        sw = (w0 + w1 + w2) / 3.0
        total += sw
        if k == cl.CLOSURE_DIFFUSE or k == cl.CLOSURE_PRINCIPLED:
            s = 1.0 - p[cl.METALLIC] if k == cl.CLOSURE_PRINCIPLED else 1.0
            v = ci / np.pi * s
            f0 += w0 * p[cl.COLOR] * c0 * v
            f1 += w1 * p[cl.COLOR + 1] * c1 * v
            f2 += w2 * p[cl.COLOR + 2] * c2 * v
            pdf += sw * ci / np.pi
        elif k == cl.CLOSURE_GLOSSY or k == cl.CLOSURE_METALLIC:
            alpha = min(p[cl.ROUGHNESS], 1.0) ** 2
            kd, ks = bsdf.eval_reflection(0.0, 0.0, alpha, nsx, nsy, nsz, wox, woy, woz,
                                          wix, wiy, wiz)
            v = ks * ci
            f0 += w0 * p[cl.COLOR] * c0 * v
            f1 += w1 * p[cl.COLOR + 1] * c1 * v
            f2 += w2 * p[cl.COLOR + 2] * c2 * v
            pdf += sw * ci / np.pi  # placeholder: cosine sampling
    if total <= 0.0:
        return f0, f1, f2, 0.0
    return f0, f1, f2, pdf / total


@njit(cache=True, error_model="numpy")
def sample_bsdf(tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz, ngx, ngy, ngz,
                tx, ty, tz, entering, u_lobe, u1, u2):
    """Sample wi for material m: (wix, wiy, wiz, w0, w1, w2, pdf, flags), w = f |cos| / pdf
    (path weight, RGB), pdf 0 for a delta lobe, flags LOBE_* (0: no direction)."""
    if nsx * ngx + nsy * ngy + nsz * ngz < 0.0:
        nsx, nsy, nsz = -nsx, -nsy, -nsz
    total = 0.0
    for c in range(tab.first[m], tab.first[m] + tab.count[m]):
        total += (tab.weight[c, 0] + tab.weight[c, 1] + tab.weight[c, 2]) / 3.0
    if total <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    acc = 0.0
    for c in range(tab.first[m], tab.first[m] + tab.count[m]):
        sw = (tab.weight[c, 0] + tab.weight[c, 1] + tab.weight[c, 2]) / 3.0
        acc += sw
        if u_lobe * total < acc or c == tab.first[m] + tab.count[m] - 1:
            k = tab.kind[c]
            p = tab.params[c]
            if k == cl.CLOSURE_GLASS or k == cl.CLOSURE_REFRACTION:
                ox, oy, oz, w0, w1, w2, tr, ok = bsdf.sample_delta(
                    0.0, 0.0, 0.0, 1.0, p[cl.COLOR] * c0, p[cl.COLOR + 1] * c1,
                    p[cl.COLOR + 2] * c2, p[cl.IOR], -wox, -woy, -woz, nsx, nsy, nsz,
                    ngx, ngy, ngz, entering, 1.0, u1)
                if not ok:
                    return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
                q = tab.weight[c, 0] * total / sw
                flags = LOBE_DELTA | (LOBE_TRANSMIT if tr else 0)
                return (ox, oy, oz, w0 * tab.weight[c, 0] * total / sw,
                        w1 * tab.weight[c, 1] * total / sw, w2 * tab.weight[c, 2] * total / sw,
                        0.0 * q, flags)
            break
    lx, ly, lz = _cosine(u1, u2)
    bx0, by0, bz0, bx1, by1, bz1 = sampling.basis(nsx, nsy, nsz)
    wix = lx * bx0 + ly * bx1 + lz * nsx
    wiy = lx * by0 + ly * by1 + lz * nsy
    wiz = lx * bz0 + ly * bz1 + lz * nsz
    if wix * ngx + wiy * ngy + wiz * ngz <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    f0, f1, f2, pdf = eval_bsdf(tab, m, c0, c1, c2, wox, woy, woz, wix, wiy, wiz,
                                nsx, nsy, nsz, ngx, ngy, ngz, tx, ty, tz)
    if pdf <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    return wix, wiy, wiz, f0 / pdf, f1 / pdf, f2 / pdf, pdf, LOBE_DIFFUSE


@njit(cache=True, error_model="numpy")
def _cosine(u1, u2):
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    return r * np.cos(phi), r * np.sin(phi), np.sqrt(max(0.0, 1.0 - u1))


@njit(cache=True, error_model="numpy")
def albedo(tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz):
    """Directional albedo at wo: (d0, d1, d2, a0, a1, a2): the diffuse-like lobes' part (0
    when material m has none: no photon is stored there) and the whole material's."""
    d0 = d1 = d2 = a0 = a1 = a2 = 0.0
    for c in range(tab.first[m], tab.first[m] + tab.count[m]):
        k = tab.kind[c]
        p = tab.params[c]
        w0 = tab.weight[c, 0] * p[cl.COLOR] * c0
        w1 = tab.weight[c, 1] * p[cl.COLOR + 1] * c1
        w2 = tab.weight[c, 2] * p[cl.COLOR + 2] * c2
        if k == cl.CLOSURE_DIFFUSE or k == cl.CLOSURE_PRINCIPLED:
            d0 += w0
            d1 += w1
            d2 += w2
        a0 += w0
        a1 += w1
        a2 += w2
    return d0, d1, d2, min(a0, 1.0), min(a1, 1.0), min(a2, 1.0)
