"""The closure evaluator: a material's BSDF at one hit, for every integrator and the photons.

A material is a weighted sum of closures (core/scene/closures.py). ``table(materials)``
turns ``Materials.closure_table()`` into a ``ClosureTable`` (float64 / int32 arrays plus the
albedo look-up tables of ``albedo_tables``) that the numba functions below take as one
argument:

- ``eval_bsdf``: f * |cos(ns, wi)| summed over the non-delta lobes (RGB), and the pdf with
  which ``sample_bsdf`` would have produced wi (solid angle, 1/sr; for MIS);
- ``sample_bsdf``: pick a lobe by its sample weight (over every closure of the material, as
  Cycles does), sample a direction from it; return the direction, the path weight
  f |cos| / pdf (RGB; for a rough lobe f and pdf are the whole material's, so the weight is
  the one MIS expects), the pdf (0 for a delta lobe) and the flags ``LOBE_*`` (0: no
  direction, the path ends);
- ``albedo``: the directional albedo of the diffuse-like lobes (0 when the material has none:
  photons are not stored there) and of the whole material (Russian roulette); estimates
  from the albedo tables, not clamped (a Mix/Add above 1 gives above 1).

Conventions: wo points to the viewer (or where the photon came from), wi to the light (or
where the photon goes; a photon's weight is then ``adjoint_weight``'s, the BSDF seen from
wi, Cycles' BSDFs not being reciprocal); every vector unit, world space. ns, ng: shading
and geometric normals, ng flipped to wo's side (ns is flipped to ng's side here if it is not; where wo is
below ns the geometric normal shades); t: a unit tangent (``DEFAULT_TANGENT`` when the mesh
has none; it is made orthogonal to ns here). ``entering``: wo is on the front of the mesh's
geometric normal, so a dielectric's eta is its IOR (else 1 / IOR). c0..c2: the texel colour
that multiplies the COLOR slot of the closures that have a texture (closure_texture >= 0);
the others ignore it.

What each closure becomes (Cycles 4.x/5.x, kernel/svm/closure.h):

- Diffuse: Lambert, or Oren-Nayar (oren_nayar.py) when Roughness > 1e-5;
- Glossy: GGX reflection (microfacet.py), anisotropic along the tangent (rotated by
  Anisotropic Rotation), no Fresnel, multiscatter compensated for Multiscatter GGX;
  Beckmann is Beckmann (D sampled, no compensation, as Cycles); Ashikhmin-Shirley is
  rendered as GGX of the same roughness;
- Glass: rough dielectric, generalized Schlick "real curve" Fresnel, COLOR tinting both;
  Refraction: the transmission alone, no Fresnel; Translucent: Lambert on the far side;
- Sheen: the Microfiber LTC (sheen.py); Metallic: GGX with F82 tint or the physical
  conductor Fresnel;
- Principled v2, top to bottom: sheen, coat (with its tint's absorption along the refracted
  path), metal (F82 tint, weight Metallic), transmission (rough glass, or Thin Wall's
  reflection + straight-through transmission), the dielectric specular layer (IOR, Specular
  IOR Level, Specular Tint), diffuse (Oren-Nayar with Diffuse Roughness); each layer scales
  the ones below by 1 - max(its directional albedo / the weight), like
  closure_layering_weight. Subsurface is rendered as diffuse (thin wall: half diffuse, half
  translucent, as Cycles' thin subsurface at anisotropy 0). Emission and alpha are per
  material, not here.

Like Cycles, radiance through a refraction is not scaled by eta^2 (bsdf_microfacet.h).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .. import sampling
from .. import spectral
from ..scene import closures as cl
from . import albedo_tables, dispersion, fresnel, lambert, microfacet, oren_nayar, sheen

LOBE_DELTA = 1      # a singular direction (mirror, smooth glass): pdf 0, no eval
LOBE_GLOSSY = 2     # a rough microfacet lobe
LOBE_DIFFUSE = 4    # Lambert, Oren-Nayar, translucent, sheen
LOBE_TRANSMIT = 8   # wi is on the far side of the surface (ng)

DEFAULT_TANGENT = (1.0, 0.0, 0.0)
"""A tangent for meshes without one: ``frame`` makes it orthogonal to ns (and falls back to
another axis when it is parallel)."""


def default_tangents(n: int) -> np.ndarray:
    """(n, 3) float64 C-contiguous rows of DEFAULT_TANGENT (the tangents of hits whose
    BSDF is isotropic)."""
    out = np.empty((n, 3))
    out[:] = DEFAULT_TANGENT
    return out

CUTOFF = 1e-5  # Cycles' CLOSURE_WEIGHT_CUTOFF: a layer weighted less is skipped


class ClosureTable(NamedTuple):
    """The closure table as the kernels read it (``table``).

    kind: (C,) int32 CLOSURE_*; weight: (C, 3) float64; params: (C, PARAM_COUNT) float64;
    texture: (C,) int32 (-1 none); first, count: (M,) int32 closures of material m.
    (The albedo look-up tables are albedo_tables.py's module constants, not fields: every
    array here is reference-counted at each call that takes the table.)
    abbe: (C,) float64, the Abbe number of each closure's material (``Materials.abbe``;
    0 = no dispersion): the transmission lobes' IOR at a path's wavelength.
    """
    kind: np.ndarray
    weight: np.ndarray
    params: np.ndarray
    texture: np.ndarray
    first: np.ndarray
    count: np.ndarray
    abbe: np.ndarray


def table(materials) -> ClosureTable:
    """The ``ClosureTable`` of a ``core.scene.contract.Materials`` (stored or derived
    closures, ``Materials.closure_table()``), float64 / int32 contiguous copies."""
    t = materials.closure_table()
    abbe = np.zeros(t["kind"].shape[0])
    for m, v in enumerate(materials.abbe()):
        abbe[t["first"][m]:t["first"][m] + t["count"][m]] = v
    return ClosureTable(
        kind=np.ascontiguousarray(t["kind"], np.int32),
        weight=np.ascontiguousarray(t["weight"], np.float64).reshape(-1, 3),
        params=np.ascontiguousarray(t["params"], np.float64).reshape(-1, cl.PARAM_COUNT),
        texture=np.ascontiguousarray(t["texture"], np.int32),
        first=np.ascontiguousarray(t["first"], np.int32),
        count=np.ascontiguousarray(t["count"], np.int32),
        abbe=abbe)


# --- the lobe list of one hit ------------------------------------------------------------------
# Each closure expands, for the wo at hand, into rows of a (n, NL) float64 array:
L_LAMBERT, L_OREN_NAYAR, L_TRANSLUCENT, L_GGX, L_DIELECTRIC, L_SHEEN, L_THIN_T = range(7)
T, W, SW, AX, AY, ROT_C, ROT_S, ETA, MODE, P0, Q0, RT, TT, EST, BECK = (
    0, 1, 4, 5, 6, 7, 8, 9, 10, 11, 14, 17, 20, 23, 24)
# T type; W (3) weight (energy compensation included); SW sample weight; AX, AY alphas (Oren-
# Nayar: AX = sigma; sheen: AX, AY = the LTC's a, b); ROT_C, ROT_S the lobe frame's rotation
# about n; ETA; MODE (GGX: FR_*; dielectric: 1 = refraction only); P0 (3) F0 / n / the
# Oren-Nayar albedo; Q0 (3) F82's b / k; RT, TT (3) reflection and transmission tints;
# EST the lobe's directional albedo per unit weight (luminance-free mean, for ``albedo``);
# BECK 1 for a Beckmann microfacet lobe (GGX and dielectric rows), else 0 (GGX).
# OWN 1 for a lobe with a normal of its own, CN (3) that unit normal in the hit's local
# frame (the Principled coat under a linked Coat Normal, and its sheen, about the mix of
# the shading normal and the coat normal by the coat weight): the lobe sees wo, wi in a
# frame about CN and its cosine is |wi . CN| (Cycles gives each closure its own N); OWN 0:
# the shading normal, z.
OWN, CN = 25, 26
NL = 29
MAX_LOBES = 8  # per closure (Principled: sheen, coat, metal, 2 transmission, specular, 2 base)
FR_NONE, FR_DIELECTRIC, FR_SCHLICK, FR_F82, FR_CONDUCTOR = range(5)
LOBE_BLOCK = 256
"""Hits a parallel task of a kernel shades with one ``lobe_buffer`` (the direct-light,
continuation and diffuse-albedo kernels: one allocation per block, not per hit)."""


@njit(cache=True, error_model="numpy")
def frame(nsx, nsy, nsz, tx, ty, tz):
    """Orthonormal shading frame (t, b = n x t) from ns and a tangent (Gram-Schmidt;
    another axis when t is parallel to ns). Returns tx, ty, tz, bx, by, bz."""
    d = tx * nsx + ty * nsy + tz * nsz
    ux, uy, uz = tx - d * nsx, ty - d * nsy, tz - d * nsz
    ln = np.sqrt(ux * ux + uy * uy + uz * uz)
    if ln < 1e-6:
        ux, uy, uz, _, _, _ = sampling.basis(nsx, nsy, nsz)
        ln = np.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / ln, uy / ln, uz / ln
    bx = nsy * uz - nsz * uy
    by = nsz * ux - nsx * uz
    bz = nsx * uy - nsy * ux
    return ux, uy, uz, bx, by, bz


@njit(cache=True, error_model="numpy")
def _mean3(a, b, c):
    return (a + b + c) / 3.0


@njit(cache=True, error_model="numpy")
def _row(L, n, kind, w0, w1, w2, sw):
    """Start lobe row n (zeroed, rotation identity) and return n + 1."""
    for j in range(NL):
        L[n, j] = 0.0
    L[n, T] = kind
    L[n, W], L[n, W + 1], L[n, W + 2] = w0, w1, w2
    L[n, SW] = max(sw, 0.0)
    L[n, ROT_C] = 1.0
    L[n, EST] = 1.0
    return n + 1


@njit(cache=True, error_model="numpy")
def _compensate(L, k, rough, mu, glass, eta, f0, f1, f2):
    """Multiscatter GGX on lobe k: weight *= 1 + Fms (1 - E) / E per channel (Fss = f*), the
    sample weight by the mean "darkening" (Cycles' microfacet_ggx_preserve_energy). Returns
    the darkening (RGB) that Cycles folds into the lobe's weight (its albedo for layering)."""
    if glass:
        e, e_avg = albedo_tables.glass_e(albedo_tables.GLASS_E, albedo_tables.GLASS_EAVG,
                                         rough, mu, eta)
    else:
        e, e_avg = albedo_tables.reflect_e(albedo_tables.GGX_E, albedo_tables.GGX_EAVG,
                                           rough, mu)
    e = max(e, 1e-4)
    scale = 1.0 / e
    m0 = albedo_tables.compensation(e, e_avg, f0)
    m1 = albedo_tables.compensation(e, e_avg, f1)
    m2 = albedo_tables.compensation(e, e_avg, f2)
    L[k, W] *= m0
    L[k, W + 1] *= m1
    L[k, W + 2] *= m2
    d0, d1, d2 = m0 / scale, m1 / scale, m2 / scale
    L[k, SW] *= _mean3(d0, d1, d2)
    L[k, EST] *= e  # the single-scattering part; the weight carries the rest
    return d0, d1, d2


@njit(cache=True, error_model="numpy")
def _rough_of(ax, ay):
    return np.sqrt(np.sqrt(ax * ay))


@njit(cache=True, error_model="numpy")
def _ggx_lobe(L, n, w0, w1, w2, ax, ay, rc, rs, mode, p, q, eta, mu, multi, fss,
              beck=False):
    """Append a GGX (``beck``: Beckmann) reflection lobe with Fresnel ``mode`` (params p, q:
    3-tuples) and its sample weight mean(w) * mean(Fresnel albedo estimate); multiscatter
    when ``multi``. Returns (n + 1, estimated albedo RGB per unit weight, darkening RGB).
    Beckmann's albedo estimates read the GGX tables (estimates only: sample weights,
    Russian roulette)."""
    k = n
    n = _row(L, n, L_GGX, w0, w1, w2, _mean3(w0, w1, w2))
    L[k, BECK] = 1.0 if beck else 0.0
    L[k, AX], L[k, AY], L[k, ROT_C], L[k, ROT_S] = ax, ay, rc, rs
    L[k, ETA], L[k, MODE] = eta, mode
    L[k, P0], L[k, P0 + 1], L[k, P0 + 2] = p[0], p[1], p[2]
    L[k, Q0], L[k, Q0 + 1], L[k, Q0 + 2] = q[0], q[1], q[2]
    rough = _rough_of(ax, ay)
    # Fresnel albedo estimate at wo (bsdf_microfacet_estimate_albedo)
    if mode == FR_SCHLICK or mode == FR_DIELECTRIC:
        s = albedo_tables.read_3d(albedo_tables.SCHLICK_S, rough, mu,
                                  albedo_tables.ior_z(eta))
        e0, e1, e2 = p[0] + (1.0 - p[0]) * s, p[1] + (1.0 - p[1]) * s, p[2] + (1.0 - p[2]) * s
    elif mode == FR_F82:
        s = albedo_tables.read_2d(albedo_tables.SCHLICK5_S, rough, mu)
        e0, e1, e2 = p[0] + (1.0 - p[0]) * s, p[1] + (1.0 - p[1]) * s, p[2] + (1.0 - p[2]) * s
    elif mode == FR_CONDUCTOR:
        e0 = fresnel.conductor(mu, p[0], q[0])
        e1 = fresnel.conductor(mu, p[1], q[1])
        e2 = fresnel.conductor(mu, p[2], q[2])
    else:
        e0 = e1 = e2 = 1.0
    L[k, SW] *= _mean3(e0, e1, e2)
    L[k, EST] = 1.0
    d0 = d1 = d2 = 1.0
    if multi:
        d0, d1, d2 = _compensate(L, k, rough, mu, False, 1.0, fss[0], fss[1], fss[2])
    else:
        L[k, EST] = albedo_tables.read_2d(albedo_tables.GGX_E, rough, mu)
    return n, (e0, e1, e2), (d0, d1, d2)


@njit(cache=True, error_model="numpy")
def _glass_lobe(L, n, w0, w1, w2, alpha, eta, refract_only, f0, rt, tt, mu, multi,
                beck=False):
    """Append a rough dielectric lobe (f0, rt, tt: 3-tuples), GGX or (``beck``) Beckmann.
    Returns n + 1."""
    k = n
    n = _row(L, n, L_DIELECTRIC, w0, w1, w2, _mean3(w0, w1, w2))
    L[k, BECK] = 1.0 if beck else 0.0
    L[k, AX] = alpha
    L[k, AY] = alpha
    L[k, ETA] = eta
    L[k, MODE] = 1.0 if refract_only else 0.0
    L[k, P0], L[k, P0 + 1], L[k, P0 + 2] = f0[0], f0[1], f0[2]
    L[k, RT], L[k, RT + 1], L[k, RT + 2] = rt[0], rt[1], rt[2]
    L[k, TT], L[k, TT + 1], L[k, TT + 2] = tt[0], tt[1], tt[2]
    rough = np.sqrt(alpha)
    if refract_only:
        L[k, EST] = 1.0
        return n
    s = albedo_tables.read_3d(albedo_tables.SCHLICK_S, rough, mu, albedo_tables.ior_z(eta))
    est = 0.0
    for j in range(3):
        fj = f0[j] + (1.0 - f0[j]) * s
        est += (fj * rt[j] + (1.0 - fj) * tt[j]) / 3.0
    L[k, SW] *= est
    L[k, EST] = est
    if multi:
        _compensate(L, k, rough, mu, True, eta, tt[0], tt[1], tt[2])
    return n


@njit(cache=True, error_model="numpy")
def _layer(a0, a1, a2, v0, v1, v2):
    """closure_layering_weight: v * clamp(1 - max(a / v), 0, 1) (a: the layer's albedo)."""
    m = 0.0
    if v0 > 0.0:
        m = max(m, a0 / v0)
    if v1 > 0.0:
        m = max(m, a1 / v1)
    if v2 > 0.0:
        m = max(m, a2 / v2)
    k = min(max(1.0 - m, 0.0), 1.0)
    return v0 * k, v1 * k, v2 * k


@njit(cache=True, error_model="numpy")
def _sheen_lobe(L, n, w0, w1, w2, roughness, mu, wox, woy):
    """Append a sheen lobe (weight w times the LTC's albedo); returns (n', albedo factor)."""
    r = min(max(roughness, 1e-3), 1.0)
    a = albedo_tables.read_2d(albedo_tables.SHEEN[0], mu, r)
    b = albedo_tables.read_2d(albedo_tables.SHEEN[1], mu, r)
    alb = albedo_tables.read_2d(albedo_tables.SHEEN[2], mu, r)
    if abs(a) < 1e-5 or alb < 1e-5:
        return n, 0.0
    k = n
    n = _row(L, n, L_SHEEN, w0 * alb, w1 * alb, w2 * alb, _mean3(w0, w1, w2) * alb)
    L[k, AX] = a
    L[k, AY] = b
    L[k, ROT_C], L[k, ROT_S] = sheen.frame_of(wox, woy)
    return n, alb


@njit(cache=True, error_model="numpy")
def _aniso_rotation(rotation):
    ang = rotation * 2.0 * np.pi
    return np.cos(ang), np.sin(ang)


@njit(cache=True, error_model="numpy")
def _diffuse(L, n, w0, w1, w2, sigma, r0, r1, r2):
    if sigma < 1e-5:
        return _row(L, n, L_LAMBERT, w0, w1, w2, _mean3(w0, w1, w2))
    k = n
    n = _row(L, n, L_OREN_NAYAR, w0, w1, w2, _mean3(w0, w1, w2))
    L[k, AX] = sigma
    L[k, P0], L[k, P0 + 1], L[k, P0 + 2] = r0, r1, r2
    return n


@njit(cache=True, error_model="numpy")
def _principled(L, n, W0, W1, W2, p, b0, b1, b2, wox, woy, woz, entering, abbe, lam,
                cnx=0.0, cny=0.0, cnz=0.0):
    """Principled BSDF v2 (svm_node_closure_bsdf, CLOSURE_BSDF_PRINCIPLED_ID); abbe, lam:
    the transmission's dispersion at the path's wavelength (``transmission_ior``); cn: the
    coat's own unit normal in the local frame (a linked Coat Normal), 0 for none: the coat
    lobe, its albedo (the layering of the base below) and its tint's path length then go
    by cos(wo, cn), as Cycles' coat closure with bsdf->N = coat_normal; the sheen lobe
    (its frame, LTC and albedo) by normalize(mix(z, cn, min(coat weight, 1))), as Cycles'
    sheen closure. Where wo is below cn both keep the shading normal."""
    mu = woz
    multi = int(p[cl.DISTRIBUTION]) == cl.DISTRIBUTION_MULTI_GGX
    sheen_w = max(p[cl.SHEEN_WEIGHT], 0.0)
    coat_w = max(p[cl.COAT_WEIGHT], 0.0)
    # The coat's own normal: cn where wo is above it, else the shading normal shades
    own = False
    mu_c = mu
    if cnx != 0.0 or cny != 0.0 or cnz != 0.0:
        mu_o = cnx * wox + cny * woy + cnz * woz
        if mu_o > 1e-7:
            own = True
            mu_c = min(mu_o, 1.0)
    # Sheen on top, about normalize(mix(n, cn, saturate(coat weight))) as Cycles' sheen
    # closure (the shading normal without a coat normal; wo is above both, so above it)
    if sheen_w > CUTOFF:
        s0 = sheen_w * max(p[cl.SHEEN_TINT], 0.0) * W0
        s1 = sheen_w * max(p[cl.SHEEN_TINT + 1], 0.0) * W1
        s2 = sheen_w * max(p[cl.SHEEN_TINT + 2], 0.0) * W2
        t = min(coat_w, 1.0)
        k = n
        tilted = own and t > 0.0
        # wo in the sheen's frame: the shading normal's, or the mix's
        mu_s, sox, soy = mu, wox, woy
        snx, sny, snz = 0.0, 0.0, 1.0
        if tilted:
            snx, sny, snz = t * cnx, t * cny, 1.0 - t + t * cnz
            ln = np.sqrt(snx * snx + sny * sny + snz * snz)
            snx, sny, snz = snx / ln, sny / ln, snz / ln
            sox, soy, soz = _into_frame(snx, sny, snz, wox, woy, woz)
            mu_s = min(soz, 1.0)
        n, alb = _sheen_lobe(L, n, s0, s1, s2, min(max(p[cl.SHEEN_ROUGHNESS], 0.0), 1.0),
                             mu_s, sox, soy)
        if tilted and n > k:
            L[k, OWN] = 1.0
            L[k, CN], L[k, CN + 1], L[k, CN + 2] = snx, sny, snz
        if alb > 0.0:
            W0, W1, W2 = _layer(s0 * alb, s1 * alb, s2 * alb, W0, W1, W2)
    # Coat
    if coat_w > CUTOFF:
        cr = min(max(p[cl.COAT_ROUGHNESS], 0.0), 1.0)
        cior = max(p[cl.COAT_IOR], 1.0)
        ca = cr * cr
        f0c = fresnel.f0_from_ior(cior)
        fss = fresnel.dielectric_fss(cior)
        k = n
        n, est, dk = _ggx_lobe(L, n, coat_w * W0, coat_w * W1, coat_w * W2, ca, ca,
                               1.0, 0.0, FR_DIELECTRIC, (f0c, f0c, f0c), (0.0, 0.0, 0.0),
                               cior, mu_c, True, (fss, fss, fss))
        if own:
            L[k, OWN] = 1.0
            L[k, CN], L[k, CN + 1], L[k, CN + 2] = cnx, cny, cnz
        W0, W1, W2 = _layer(coat_w * W0 * dk[0] * est[0], coat_w * W1 * dk[1] * est[1],
                            coat_w * W2 * dk[2] * est[2], W0, W1, W2)
        t0, t1, t2 = (max(p[cl.COAT_TINT], 0.0), max(p[cl.COAT_TINT + 1], 0.0),
                      max(p[cl.COAT_TINT + 2], 0.0))
        if t0 != 1.0 or t1 != 1.0 or t2 != 1.0:
            # Beer's law along the path refracted into a coat of unit thickness
            cos_nt = np.sqrt(max(1.0 - (1.0 - mu_c * mu_c) / (cior * cior), 1e-12))
            depth = 1.0 / cos_nt
            W0 *= 1.0 + coat_w * (t0 ** depth - 1.0)
            W1 *= 1.0 + coat_w * (t1 ** depth - 1.0)
            W2 *= 1.0 + coat_w * (t2 ** depth - 1.0)
    base0, base1, base2 = max(p[cl.COLOR] * b0, 0.0), max(p[cl.COLOR + 1] * b1, 0.0), \
        max(p[cl.COLOR + 2] * b2, 0.0)
    cb0, cb1, cb2 = min(base0, 1.0), min(base1, 1.0), min(base2, 1.0)
    ior = max(p[cl.IOR], 1e-5)
    rough = min(max(p[cl.ROUGHNESS], 0.0), 1.0)
    aniso = min(max(p[cl.ANISOTROPIC], 0.0), 1.0)
    ax = ay = rough * rough
    rc, rs = 1.0, 0.0
    if aniso > 0.0:
        aspect = np.sqrt(1.0 - aniso * 0.9)
        ax /= aspect
        ay *= aspect
        rc, rs = _aniso_rotation(p[cl.ANISOTROPIC_ROTATION])
    st0, st1, st2 = (max(p[cl.SPECULAR_TINT], 0.0), max(p[cl.SPECULAR_TINT + 1], 0.0),
                     max(p[cl.SPECULAR_TINT + 2], 0.0))
    # Metal
    metallic = min(max(p[cl.METALLIC], 0.0), 1.0)
    if metallic > CUTOFF:
        q = (fresnel.f82_b(cb0, min(st0, 1.0)), fresnel.f82_b(cb1, min(st1, 1.0)),
             fresnel.f82_b(cb2, min(st2, 1.0)))
        fss = (fresnel.f82_fss(cb0, q[0]), fresnel.f82_fss(cb1, q[1]),
               fresnel.f82_fss(cb2, q[2]))
        n, _, _ = _ggx_lobe(L, n, metallic * W0, metallic * W1, metallic * W2, ax, ay,
                            rc, rs, FR_F82, (cb0, cb1, cb2), q, 1.0, mu, multi, fss)
        W0 *= 1.0 - metallic
        W1 *= 1.0 - metallic
        W2 *= 1.0 - metallic
    thin = p[cl.THIN_WALL] > 0.5
    # Transmission
    tw = min(max(p[cl.TRANSMISSION], 0.0), 1.0)
    if tw > CUTOFF:
        if thin:
            n = _thin_glass(L, n, tw * W0, tw * W1, tw * W2, rough * rough, ior,
                            (st0, st1, st2), (cb0, cb1, cb2), mu)
        else:
            tior = transmission_ior(ior, abbe, lam)
            eta = tior if entering else 1.0 / tior
            f0 = fresnel.f0_from_ior(tior)
            n = _glass_lobe(L, n, tw * W0, tw * W1, tw * W2, rough * rough, eta, False,
                            (min(f0 * st0, 1.0), min(f0 * st1, 1.0), min(f0 * st2, 1.0)),
                            (1.0, 1.0, 1.0), (np.sqrt(cb0), np.sqrt(cb1), np.sqrt(cb2)), mu,
                            multi)
        W0 *= 1.0 - tw
        W1 *= 1.0 - tw
        W2 *= 1.0 - tw
    # Dielectric specular layer: IOR scaled by Specular IOR Level
    level = max(p[cl.SPECULAR_LEVEL], 0.0)
    eta = ior
    f0 = fresnel.f0_from_ior(eta)
    if level != 0.5:
        f0 *= 2.0 * level
        eta = fresnel.ior_from_f0(f0)
        if ior < 1.0:
            eta = 1.0 / eta
    if eta != 1.0:
        f00, f01, f02 = min(f0 * st0, 1.0), min(f0 * st1, 1.0), min(f0 * st2, 1.0)
        f0r = fresnel.f0_from_ior(eta)
        s = (fresnel.dielectric_fss(eta) - f0r) / (1.0 - f0r) if f0r < 1.0 else 1.0
        s = min(max(s, 0.0), 1.0)
        fss = (f00 + (1.0 - f00) * s, f01 + (1.0 - f01) * s, f02 + (1.0 - f02) * s)
        n, est, dk = _ggx_lobe(L, n, W0, W1, W2, ax, ay, rc, rs, FR_SCHLICK,
                               (f00, f01, f02), (0.0, 0.0, 0.0), eta, mu, multi, fss)
        W0, W1, W2 = _layer(W0 * dk[0] * est[0], W1 * dk[1] * est[1], W2 * dk[2] * est[2],
                            W0, W1, W2)
    # Diffuse base (subsurface rendered as diffuse)
    ss = min(max(p[cl.SUBSURFACE_WEIGHT], 0.0), 1.0)
    sigma = min(max(p[cl.DIFFUSE_ROUGHNESS], 0.0), 1.0)
    if thin and ss > CUTOFF:
        h = 0.5 * ss
        n = _diffuse(L, n, cb0 * h * W0, cb1 * h * W1, cb2 * h * W2, 0.0, cb0, cb1, cb2)
        n = _row(L, n, L_TRANSLUCENT, cb0 * h * W0, cb1 * h * W1, cb2 * h * W2,
                 _mean3(cb0 * W0, cb1 * W1, cb2 * W2) * h)
        ss_as_diffuse = 0.0
    else:
        ss_as_diffuse = ss
    d0 = (base0 * (1.0 - ss) + cb0 * ss_as_diffuse) * W0
    d1 = (base1 * (1.0 - ss) + cb1 * ss_as_diffuse) * W1
    d2 = (base2 * (1.0 - ss) + cb2 * ss_as_diffuse) * W2
    if d0 > 0.0 or d1 > 0.0 or d2 > 0.0:
        n = _diffuse(L, n, d0, d1, d2, sigma, base0, base1, base2)
    return n


@njit(cache=True, error_model="numpy")
def _thin_glass(L, n, w0, w1, w2, alpha, ior, rtint, ttint, mu):
    """Thin Wall transmission (Blender 5.2, bsdf_thin_glass_setup): a glossy reflection and a
    straight-through transmission (GGX about -n of the mirrored wo, roughened for the two
    refractions), weighted by the sheet's reflectance and transmittance summed over its
    internal reflections (OpenPBR's thin-walled case)."""
    s, cos_t, _ = fresnel.schlick_real(mu, ior)
    f0 = fresnel.f0_from_ior(ior)
    R = np.zeros(3)
    Tt = np.zeros(3)
    for j in range(3):
        fj = min(f0 * rtint[j], 1.0)
        r1 = fj + (1.0 - fj) * s
        t1 = 1.0 - r1
        c = ttint[j] ** (1.0 / cos_t) if cos_t > 0.0 else 0.0
        den = 1.0 - (r1 * c) ** 2
        Tt[j] = c * t1 * t1 / den if den > 0.0 else 0.0
        R[j] = r1 + Tt[j] * r1 * c
    rough = np.sqrt(alpha)
    if R[0] > 0.0 or R[1] > 0.0 or R[2] > 0.0:
        k = n
        n, _, _ = _ggx_lobe(L, n, R[0] * w0, R[1] * w1, R[2] * w2, alpha, alpha, 1.0, 0.0,
                            FR_NONE, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0, mu, True, rtint)
    if Tt[0] > 0.0 or Tt[1] > 0.0 or Tt[2] > 0.0:
        at = min(max(alpha * np.sqrt(3.4 * (ior - 1.0) * (ior - 0.5) ** 2 / (ior ** 3))
                     if ior > 1.0 else 0.0, 0.0), 1.0)
        k = n
        n = _row(L, n, L_THIN_T, Tt[0] * w0, Tt[1] * w1, Tt[2] * w2,
                 _mean3(Tt[0] * w0, Tt[1] * w1, Tt[2] * w2))
        L[k, AX] = at
        L[k, AY] = at
        if not microfacet.is_singular(at, at):
            _compensate(L, k, np.sqrt(at), mu, False, 1.0, 1.0, 1.0, 1.0)
    return n


@njit(cache=True, error_model="numpy")
def lobe_buffer(tab):
    """Room for the lobe rows of any material of ``tab`` (``hit_lobes_into``): (R, NL)
    float64, R = MAX_LOBES x the most closures a material has. A kernel over many hits
    takes one per block of hits: a heap allocation per hit (``hit_lobes``) was a fifth
    of the direct-light kernel's time (issue 13, docs/core_renderer.md)."""
    most = 1
    for m in range(tab.count.shape[0]):
        most = max(most, tab.count[m])
    return np.empty((most * MAX_LOBES, NL))


@njit(cache=True, error_model="numpy", inline="always")
def _material_buffer(tab, m):
    """Room for material m's lobe rows: (MAX_LOBES x its closure count, NL) float64."""
    return np.empty((max(tab.count[m], 1) * MAX_LOBES, NL))


@njit(cache=True, error_model="numpy")
def _lobes(tab, m, c0, c1, c2, wox, woy, woz, entering, lam=0.0, ux=1.0, uy=0.0, uz=0.0,
           bx=0.0, by=1.0, bz=0.0, nx=0.0, ny=0.0, nz=1.0):
    """The lobe rows (n, NL) of material m for wo (local frame, wo.z > 0); lam the path's
    wavelength in nm (0: RGB, the transmission lobes at their IOR); u, b, n: the local
    frame's axes in world space (a world-space Coat Normal is taken into it)."""
    L = _material_buffer(tab, m)
    n = _lobes_into(L, tab, m, c0, c1, c2, wox, woy, woz, entering, lam, ux, uy, uz,
                    bx, by, bz, nx, ny, nz)
    return L[:n]


@njit(cache=True, error_model="numpy")
def _lobes_into(L, tab, m, c0, c1, c2, wox, woy, woz, entering, lam, ux, uy, uz,
                bx, by, bz, nx, ny, nz):
    """``_lobes`` written into L's first rows (at least MAX_LOBES x material m's closure
    count of them); returns their number."""
    first = tab.first[m]
    count = tab.count[m]
    n = 0
    mu = min(max(woz, 0.0), 1.0)
    for c in range(first, first + count):
        kind = tab.kind[c]
        p = tab.params[c]
        W0, W1, W2 = tab.weight[c, 0], tab.weight[c, 1], tab.weight[c, 2]
        if W0 <= 0.0 and W1 <= 0.0 and W2 <= 0.0:
            continue
        if tab.texture[c] >= 0:
            b0, b1, b2 = c0, c1, c2
        else:
            b0 = b1 = b2 = 1.0
        col0 = max(p[cl.COLOR] * b0, 0.0)
        col1 = max(p[cl.COLOR + 1] * b1, 0.0)
        col2 = max(p[cl.COLOR + 2] * b2, 0.0)
        rough = min(max(p[cl.ROUGHNESS], 0.0), 1.0)
        multi = int(p[cl.DISTRIBUTION]) == cl.DISTRIBUTION_MULTI_GGX
        beck = int(p[cl.DISTRIBUTION]) == cl.DISTRIBUTION_BECKMANN
        if kind == cl.CLOSURE_PRINCIPLED:
            gx, gy, gz = p[cl.COAT_NORMAL], p[cl.COAT_NORMAL + 1], p[cl.COAT_NORMAL + 2]
            cnx = cny = cnz = 0.0
            if gx != 0.0 or gy != 0.0 or gz != 0.0:
                cnx = gx * ux + gy * uy + gz * uz
                cny = gx * bx + gy * by + gz * bz
                cnz = gx * nx + gy * ny + gz * nz
                ln = np.sqrt(cnx * cnx + cny * cny + cnz * cnz)
                if ln > 0.0:
                    cnx, cny, cnz = cnx / ln, cny / ln, cnz / ln
                else:
                    cnx = cny = cnz = 0.0
            n = _principled(L, n, W0, W1, W2, p, b0, b1, b2, wox, woy, woz, entering,
                            tab.abbe[c], lam, cnx, cny, cnz)
        elif kind == cl.CLOSURE_DIFFUSE:
            n = _diffuse(L, n, W0 * col0, W1 * col1, W2 * col2, rough,
                         min(col0, 1.0), min(col1, 1.0), min(col2, 1.0))
        elif kind == cl.CLOSURE_TRANSLUCENT:
            n = _row(L, n, L_TRANSLUCENT, W0 * col0, W1 * col1, W2 * col2,
                     _mean3(W0 * col0, W1 * col1, W2 * col2))
        elif kind == cl.CLOSURE_SHEEN:
            n, _ = _sheen_lobe(L, n, W0 * col0, W1 * col1, W2 * col2, rough, mu, wox, woy)
        elif kind == cl.CLOSURE_GLOSSY:
            a = rough * rough
            an = min(max(p[cl.ANISOTROPIC], -0.99), 0.99)
            ax = ay = a
            rc, rs = 1.0, 0.0
            if abs(an) > 1e-4:
                if an < 0.0:
                    ax, ay = a / (1.0 + an), a * (1.0 + an)
                else:
                    ax, ay = a * (1.0 - an), a / (1.0 - an)
                rc, rs = _aniso_rotation(p[cl.ANISOTROPIC_ROTATION])
            n, _, _ = _ggx_lobe(L, n, W0 * col0, W1 * col1, W2 * col2, ax, ay, rc, rs,
                                FR_NONE, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0, mu, multi,
                                (col0, col1, col2), beck)
        elif kind == cl.CLOSURE_METALLIC:
            a = rough * rough
            an = min(max(p[cl.ANISOTROPIC], 0.0), 1.0)
            ax = ay = a
            rc, rs = 1.0, 0.0
            if an > 0.0:
                aspect = np.sqrt(1.0 - an * 0.9)
                ax, ay = a / aspect, a * aspect
                rc, rs = _aniso_rotation(p[cl.ANISOTROPIC_ROTATION])
            if int(p[cl.FRESNEL_TYPE]) == cl.FRESNEL_CONDUCTOR:
                nn = (max(p[cl.METAL_N], 0.0), max(p[cl.METAL_N + 1], 0.0),
                      max(p[cl.METAL_N + 2], 0.0))
                kk = (max(p[cl.METAL_K], 0.0), max(p[cl.METAL_K + 1], 0.0),
                      max(p[cl.METAL_K + 2], 0.0))
                fss = (fresnel.conductor_fss(nn[0], kk[0]), fresnel.conductor_fss(nn[1], kk[1]),
                       fresnel.conductor_fss(nn[2], kk[2]))
                n, _, _ = _ggx_lobe(L, n, W0, W1, W2, ax, ay, rc, rs, FR_CONDUCTOR, nn,
                                    kk, 1.0, mu, multi, fss, beck)
            else:
                f0 = (min(col0, 1.0), min(col1, 1.0), min(col2, 1.0))
                tint = (min(max(p[cl.SPECULAR_TINT], 0.0), 1.0),
                        min(max(p[cl.SPECULAR_TINT + 1], 0.0), 1.0),
                        min(max(p[cl.SPECULAR_TINT + 2], 0.0), 1.0))
                q = (fresnel.f82_b(f0[0], tint[0]), fresnel.f82_b(f0[1], tint[1]),
                     fresnel.f82_b(f0[2], tint[2]))
                fss = (fresnel.f82_fss(f0[0], q[0]), fresnel.f82_fss(f0[1], q[1]),
                       fresnel.f82_fss(f0[2], q[2]))
                n, _, _ = _ggx_lobe(L, n, W0, W1, W2, ax, ay, rc, rs, FR_F82, f0, q, 1.0,
                                    mu, multi, fss, beck)
        elif kind == cl.CLOSURE_GLASS or kind == cl.CLOSURE_REFRACTION:
            ior = transmission_ior(max(p[cl.IOR], 1e-5), tab.abbe[c], lam)
            eta = ior if entering else 1.0 / ior
            if kind == cl.CLOSURE_GLASS:
                f0 = fresnel.f0_from_ior(ior)
                n = _glass_lobe(L, n, W0, W1, W2, rough * rough, eta, False,
                                (f0, f0, f0), (col0, col1, col2), (col0, col1, col2), mu,
                                multi, beck)
            else:
                n = _glass_lobe(L, n, W0 * col0, W1 * col1, W2 * col2, rough * rough,
                                eta, True, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (1.0, 1.0, 1.0),
                                mu, False, beck)
    return n



@njit(cache=True, error_model="numpy")
def transmission_ior(ior, abbe, lam):
    """A transmission lobe's IOR at wavelength lam nm (``dispersion.ior_at``, kept above
    1e-5 as the lobes keep the IOR slot); ior itself, bit for bit, for an RGB path (lam 0)
    or a material without dispersion (abbe 0)."""
    if lam > 0.0 and abbe > 0.0:
        return max(dispersion.ior_at(ior, abbe, lam), 1e-5)
    return ior


@njit(cache=True, error_model="numpy")
def dispersive(tab, m):
    """Material row m has a transmission lobe with dispersion (a Glass or Refraction
    closure, or a Principled one with Transmission and no Thin Wall, of Abbe number > 0):
    a path meeting it picks its wavelength there (docs/dispersion.md)."""
    for c in range(tab.first[m], tab.first[m] + tab.count[m]):
        if tab.abbe[c] <= 0.0:
            continue
        kind = tab.kind[c]
        if kind == cl.CLOSURE_GLASS or kind == cl.CLOSURE_REFRACTION:
            return True
        if (kind == cl.CLOSURE_PRINCIPLED and tab.params[c, cl.TRANSMISSION] > CUTOFF
                and not tab.params[c, cl.THIN_WALL] > 0.5):
            return True
    return False


@njit(cache=True, error_model="numpy")
def pick_wavelength(tab, m, lam, u, t0, t1, t2):
    """The wavelength rule of docs/dispersion.md at material row m, for photons
    (core/photons/scatter.py) and camera paths (core/integrators/camera_paths.py) alike: a
    path still RGB (lam 0) where ``dispersive(tab, m)`` holds picks its wavelength
    ``spectral.sample_wavelength(u)`` (u a uniform in [0, 1)) and its throughput or flux
    (t0, t1, t2) is multiplied by that wavelength's RGB weight (mean (1, 1, 1) per
    channel). Returns (lam nm, t0, t1, t2), unchanged where there is no pick."""
    if lam == 0.0 and dispersive(tab, m):
        li, _, s0, s1, s2 = spectral.sample_wavelength(u)
        return li, t0 * s0, t1 * s1, t2 * s2
    return lam, t0, t1, t2


@njit(cache=True, error_model="numpy")
def transmits(tab, m):
    """Material row m (of any ClosureTable, programmed rows included) has a closure that
    can send light through the surface: Glass, Refraction, Translucent, or a Principled
    BSDF with Transmission (or, with Thin Wall, Subsurface: its translucent half). Direct
    light samples the world over the whole sphere there (core/lights/kernels.py
    ``sample_world``), not only the front hemisphere."""
    for c in range(tab.first[m], tab.first[m] + tab.count[m]):
        if tab.weight[c, 0] <= 0.0 and tab.weight[c, 1] <= 0.0 and tab.weight[c, 2] <= 0.0:
            continue
        kind = tab.kind[c]
        if (kind == cl.CLOSURE_GLASS or kind == cl.CLOSURE_REFRACTION
                or kind == cl.CLOSURE_TRANSLUCENT):
            return True
        if kind == cl.CLOSURE_PRINCIPLED:
            p = tab.params[c]
            if p[cl.TRANSMISSION] > CUTOFF or (p[cl.THIN_WALL] > 0.5
                                               and p[cl.SUBSURFACE_WEIGHT] > CUTOFF):
                return True
    return False


@njit(cache=True, parallel=True, error_model="numpy")
def _transmits_kernel(tab, rows, out):
    for i in prange(rows.shape[0]):
        out[i] = transmits(tab, rows[i])


def refracting(tab: ClosureTable) -> np.ndarray:
    """(M,) bool per material row of ``tab``: it has a dielectric lobe (Glass, Refraction,
    a Principled BSDF's transmission), so a path it transmits is inside the material's
    IOR after a front face (not a thin wall's straight-through transmission)."""
    out = np.zeros(tab.first.shape[0], bool)
    _refracts_kernel(tab, out)
    return out


@njit(cache=True, error_model="numpy")
def _refracts_kernel(tab, out):
    for m in range(out.shape[0]):
        L = _lobes(tab, m, 1.0, 1.0, 1.0, 0.0, 0.0, 1.0, True)
        for k in range(L.shape[0]):
            if int(L[k, T]) == L_DIELECTRIC:
                out[m] = True


def transmitting(tab: ClosureTable, rows) -> np.ndarray:
    """``transmits`` at N hits: (N,) bool for the material rows (N,) int32 of ``tab``."""
    rows = np.ascontiguousarray(rows, np.int32)
    out = np.zeros(rows.shape[0], bool)
    if rows.shape[0]:
        _transmits_kernel(tab, rows, out)
    return out


@njit(cache=True, error_model="numpy")
def lobe_presence(tab, m):
    """Which kinds of lobe material m has, seen at normal incidence with texel colour 1:
    (diffuse, rough, delta, transmits, non_lambert, diffuse_transmits) bools: a
    diffuse-like lobe (Lambert, Oren-Nayar, translucent, sheen: photons are stored there),
    a rough microfacet lobe (light sampling sees it), a singular one (mirror, smooth glass:
    paths follow it), one that transmits (Glass, Refraction, Translucent, Thin Wall), a
    diffuse-like lobe that is not Lambert (its reflected photon light is not d / pi E: the
    photon terms evaluate the BSDF per photon there) and a diffuse-like lobe that
    transmits (Translucent: photons and gather rays of the far side count)."""
    L = _lobes(tab, m, 1.0, 1.0, 1.0, 0.0, 0.0, 1.0, True)
    diffuse = rough = delta = transmits = non_lambert = diffuse_transmits = False
    for k in range(L.shape[0]):
        if max(L[k, W], max(L[k, W + 1], L[k, W + 2])) <= 0.0:
            continue
        t = int(L[k, T])
        if t == L_GGX or t == L_DIELECTRIC or t == L_THIN_T:
            if microfacet.is_singular(L[k, AX], L[k, AY]):
                delta = True
            else:
                rough = True
            transmits = transmits or t != L_GGX
        else:
            diffuse = True
            transmits = transmits or t == L_TRANSLUCENT
            non_lambert = non_lambert or t != L_LAMBERT
            diffuse_transmits = diffuse_transmits or t == L_TRANSLUCENT
    return diffuse, rough, delta, transmits, non_lambert, diffuse_transmits


LOBE_MASKS = ("diffuse", "rough", "delta", "transmits", "non_lambert", "diffuse_transmits")
"""The keys of ``lobe_masks``, in ``lobe_presence``'s order."""


def anisotropic_rows(tab: ClosureTable, rows=None) -> np.ndarray:
    """(N,) bool per row of ``rows``: the row of ``tab.first`` has a closure whose lobes
    depend on the tangent, by the tests ``hit_lobes`` makes (Glossy with |ANISOTROPIC| >
    1e-4, Metallic or Principled with ANISOTROPIC > 0; every other lobe is isotropic
    about the shading normal). rows: (N,) int the rows to test (only their closures are
    read, not a whole per-batch table's at every call), or None: every row (N = R)."""
    if rows is None:
        rows = np.arange(tab.first.shape[0])
    first, count = tab.first[rows].astype(np.int64), tab.count[rows]
    out = np.zeros(first.shape[0], bool)
    for j in range(int(count.max()) if count.size else 0):  # closures per row
        has = np.flatnonzero(j < count)
        c = first[has] + j
        kind, an = tab.kind[c], tab.params[c, cl.ANISOTROPIC]
        # two comparisons, not np.isin (its sort)
        out[has] |= (((kind == cl.CLOSURE_GLOSSY) & (np.abs(an) > 1e-4))
                     | (((kind == cl.CLOSURE_METALLIC) | (kind == cl.CLOSURE_PRINCIPLED))
                        & (an > 0.0)))
    return out


def lobe_masks(tab: ClosureTable) -> dict[str, np.ndarray]:
    """``lobe_presence`` for every material: (M,) bool arrays named by LOBE_MASKS."""
    m = tab.first.shape[0]
    out = {k: np.zeros(m, bool) for k in LOBE_MASKS}
    for i in range(m):
        for k, v in zip(LOBE_MASKS, lobe_presence(tab, i)):
            out[k][i] = v
    return out

# --- one lobe: f, pdf, sample in its own frame ---------------------------------------------------

@njit(cache=True, error_model="numpy")
def _rot(L, k, x, y):
    c, s = L[k, ROT_C], L[k, ROT_S]
    return c * x + s * y, -s * x + c * y


@njit(cache=True, error_model="numpy")
def _unrot(L, k, x, y):
    c, s = L[k, ROT_C], L[k, ROT_S]
    return c * x - s * y, s * x + c * y


@njit(cache=True, error_model="numpy")
def _ggx_fresnel(L, k, cos_ho):
    mode = int(L[k, MODE])
    if mode == FR_NONE:
        return 1.0, 1.0, 1.0
    if mode == FR_DIELECTRIC:
        f, _ = fresnel.fresnel_dielectric(min(max(cos_ho, 0.0), 1.0), L[k, ETA])
        return f, f, f
    if mode == FR_SCHLICK:
        s, _, _ = fresnel.schlick_real(cos_ho, L[k, ETA])
        return (L[k, P0] + (1.0 - L[k, P0]) * s, L[k, P0 + 1] + (1.0 - L[k, P0 + 1]) * s,
                L[k, P0 + 2] + (1.0 - L[k, P0 + 2]) * s)
    if mode == FR_F82:
        return (fresnel.f82(cos_ho, L[k, P0], L[k, Q0]),
                fresnel.f82(cos_ho, L[k, P0 + 1], L[k, Q0 + 1]),
                fresnel.f82(cos_ho, L[k, P0 + 2], L[k, Q0 + 2]))
    return (fresnel.conductor(cos_ho, L[k, P0], L[k, Q0]),
            fresnel.conductor(cos_ho, L[k, P0 + 1], L[k, Q0 + 1]),
            fresnel.conductor(cos_ho, L[k, P0 + 2], L[k, Q0 + 2]))


@njit(cache=True, error_model="numpy")
def _own_frame(L, k):
    """Lobe k's own frame (t, b about its normal CN; isotropic lobes only, so any
    tangent): tx, ty, tz, bx, by, bz, nx, ny, nz in the local frame."""
    nx, ny, nz = L[k, CN], L[k, CN + 1], L[k, CN + 2]
    tx, ty, tz, bx, by, bz = sampling.basis(nx, ny, nz)
    return tx, ty, tz, bx, by, bz, nx, ny, nz


@njit(cache=True, error_model="numpy")
def _into_frame(nx, ny, nz, x, y, z):
    """A local-frame vector in the frame (``sampling.basis``) about the unit normal n."""
    tx, ty, tz, bx, by, bz = sampling.basis(nx, ny, nz)
    return x * tx + y * ty + z * tz, x * bx + y * by + z * bz, x * nx + y * ny + z * nz


@njit(cache=True, error_model="numpy")
def _into_own(L, k, x, y, z):
    """A local-frame vector in lobe k's own frame (``OWN``)."""
    return _into_frame(L[k, CN], L[k, CN + 1], L[k, CN + 2], x, y, z)


@njit(cache=True, error_model="numpy")
def _out_of_own(L, k, x, y, z):
    """A vector of lobe k's own frame back in the local frame."""
    tx, ty, tz, bx, by, bz, nx, ny, nz = _own_frame(L, k)
    return x * tx + y * bx + z * nx, x * ty + y * by + z * ny, x * tz + y * bz + z * nz


@njit(cache=True, error_model="numpy")
def _lobe_cos(L, k, wix, wiy, wiz):
    """|cos| of wi (local frame) about lobe k's normal (its own, or z)."""
    if L[k, OWN] > 0.5:
        return abs(wix * L[k, CN] + wiy * L[k, CN + 1] + wiz * L[k, CN + 2])
    return abs(wiz)


@njit(cache=True, error_model="numpy")
def _lobe_side(L, k, wix, wiy, wiz):
    """wi's (local frame) height above lobe k's normal (its own, or z): its sign is the
    side the lobe sent wi to."""
    if L[k, OWN] > 0.5:
        return wix * L[k, CN] + wiy * L[k, CN + 1] + wiz * L[k, CN + 2]
    return wiz


@njit(cache=True, error_model="numpy", inline="always")
def lobe_eval(L, k, wox, woy, woz, wix, wiy, wiz):
    """Lobe k's f (RGB, 1/sr, without the cosine, weight NOT applied) and pdf at (wo, wi),
    local frame (a lobe with a normal of its own, ``OWN``, sees them in its frame)."""
    if L[k, OWN] > 0.5:
        wox, woy, woz = _into_own(L, k, wox, woy, woz)
        wix, wiy, wiz = _into_own(L, k, wix, wiy, wiz)
    t = int(L[k, T])
    if t == L_LAMBERT:
        v = lambert.eval(wiz)
        return v, v, v, lambert.pdf(wiz)
    if t == L_TRANSLUCENT:
        v = lambert.translucent_eval(wiz)
        return v, v, v, lambert.translucent_pdf(wiz)
    if t == L_OREN_NAYAR:
        f0, f1, f2 = oren_nayar.eval(L[k, AX], L[k, P0], L[k, P0 + 1], L[k, P0 + 2],
                                     wox, woy, woz, wix, wiy, wiz)
        return f0, f1, f2, oren_nayar.pdf(wiz)
    if t == L_SHEEN:
        x, y = _rot(L, k, wix, wiy)
        v = sheen.eval(L[k, AX], L[k, AY], x, y, wiz)
        return v, v, v, sheen.pdf(L[k, AX], L[k, AY], x, y, wiz)
    if t == L_GGX or t == L_THIN_T:
        if t == L_THIN_T:
            wiz = -wiz  # the far side mirrored back: straight-through transmission
        ox, oy = _rot(L, k, wox, woy)
        ix, iy = _rot(L, k, wix, wiy)
        beck = L[k, BECK] > 0.5
        f, c = microfacet.reflect_eval(L[k, AX], L[k, AY], ox, oy, woz, ix, iy, wiz, beck)
        if f <= 0.0:
            return 0.0, 0.0, 0.0, 0.0
        pdf = microfacet.reflect_pdf(L[k, AX], L[k, AY], ox, oy, woz, ix, iy, wiz, beck)
        if t == L_THIN_T:
            return f, f, f, pdf
        g0, g1, g2 = _ggx_fresnel(L, k, c)
        return f * g0, f * g1, f * g2, pdf
    # L_DIELECTRIC
    return microfacet.dielectric_eval_pdf(
        L[k, AX], L[k, ETA], L[k, MODE] > 0.5, L[k, P0], L[k, P0 + 1], L[k, P0 + 2],
        L[k, RT], L[k, RT + 1], L[k, RT + 2], L[k, TT], L[k, TT + 1], L[k, TT + 2],
        wox, woy, woz, wix, wiy, wiz, L[k, BECK] > 0.5)


@njit(cache=True, error_model="numpy")
def lobe_sample(L, k, wox, woy, woz, u1, u2, u3):
    """Sample lobe k (local frame): (wix, wiy, wiz, v0, v1, v2, pdf, delta, ok); for a delta
    lobe v is the path weight f cos / probability (weight NOT applied), else unused. A lobe
    with a normal of its own (``OWN``) samples in its frame; wi is returned in the local
    frame."""
    if L[k, OWN] > 0.5:
        ox, oy, oz = _into_own(L, k, wox, woy, woz)
        r = _lobe_sample_local(L, k, ox, oy, oz, u1, u2, u3)
        x, y, z = _out_of_own(L, k, r[0], r[1], r[2])
        return x, y, z, r[3], r[4], r[5], r[6], r[7], r[8]
    return _lobe_sample_local(L, k, wox, woy, woz, u1, u2, u3)


@njit(cache=True, error_model="numpy")
def _lobe_sample_local(L, k, wox, woy, woz, u1, u2, u3):
    """``lobe_sample`` in the lobe's own frame."""
    t = int(L[k, T])
    if t == L_LAMBERT:
        x, y, z, _, p = lambert.sample(u1, u2)
        return x, y, z, 1.0, 1.0, 1.0, p, False, True
    if t == L_OREN_NAYAR:
        x, y, z, _, p = lambert.sample(u1, u2)
        return x, y, z, 1.0, 1.0, 1.0, p, False, True
    if t == L_TRANSLUCENT:
        x, y, z, _, p = lambert.translucent_sample(u1, u2)
        return x, y, z, 1.0, 1.0, 1.0, p, False, True
    if t == L_SHEEN:
        x, y, z, w, p = sheen.sample(L[k, AX], L[k, AY], u1, u2)
        x, y = _unrot(L, k, x, y)
        return x, y, z, 1.0, 1.0, 1.0, p, False, w > 0.0
    if t == L_GGX or t == L_THIN_T:
        ox, oy = _rot(L, k, wox, woy)
        x, y, z, w, p, c = microfacet.reflect_sample(L[k, AX], L[k, AY], ox, oy, woz, u1, u2,
                                                     L[k, BECK] > 0.5)
        x, y = _unrot(L, k, x, y)
        if t == L_THIN_T:
            z = -z
        if w <= 0.0:
            return x, y, z, 0.0, 0.0, 0.0, 0.0, False, False
        if p > 0.0:
            return x, y, z, 1.0, 1.0, 1.0, p, False, True
        if t == L_THIN_T:
            return x, y, z, 1.0, 1.0, 1.0, 0.0, True, True
        g0, g1, g2 = _ggx_fresnel(L, k, c)
        return x, y, z, g0, g1, g2, 0.0, True, True
    r = microfacet.dielectric_sample(
        L[k, AX], L[k, ETA], L[k, MODE] > 0.5, L[k, P0], L[k, P0 + 1], L[k, P0 + 2],
        L[k, RT], L[k, RT + 1], L[k, RT + 2], L[k, TT], L[k, TT + 1], L[k, TT + 2],
        wox, woy, woz, u1, u2, u3, L[k, BECK] > 0.5)
    return r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[6] <= 0.0, r[8]


@njit(cache=True, error_model="numpy")
def _lobe_flags(L, k):
    t = int(L[k, T])
    if t == L_GGX or t == L_DIELECTRIC or t == L_THIN_T:
        return LOBE_GLOSSY
    return LOBE_DIFFUSE


@njit(cache=True, error_model="numpy")
def lobes_eval(L, wox, woy, woz, wix, wiy, wiz):
    """Sum over the lobe rows: (f |cos| RGB, pdf) in the local frame."""
    f0 = f1 = f2 = 0.0
    pdf = 0.0
    total = 0.0
    for k in range(L.shape[0]):
        total += L[k, SW]
    if total <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    for k in range(L.shape[0]):
        g0, g1, g2, pk = lobe_eval(L, k, wox, woy, woz, wix, wiy, wiz)
        ac = _lobe_cos(L, k, wix, wiy, wiz)
        f0 += L[k, W] * g0 * ac
        f1 += L[k, W + 1] * g1 * ac
        f2 += L[k, W + 2] * g2 * ac
        pdf += L[k, SW] / total * pk
    return f0, f1, f2, pdf


@njit(cache=True, error_model="numpy", inline="always")
def lobes_eval_parts(L, wox, woy, woz, wix, wiy, wiz, cosine, side=0.0):
    """``lobes_eval`` split by lobe kind: (diffuse-like f |cos| RGB, glossy f |cos| RGB,
    pdf), local frame; without the |cos| factor (f alone, 1/sr) unless ``cosine``. The
    diffuse-like part (Lambert, Oren-Nayar, translucent, sheen) is what the photon maps and
    final gathering carry; the glossy part (rough microfacet lobes) is what camera paths
    reach by sampling the BSDF. side: 0 every lobe; else wi's side of the true surface (1
    above, -1 below) and only the lobes whose own normal puts wi on that side count
    (``parts_at``)."""
    d0 = d1 = d2 = g0 = g1 = g2 = 0.0
    pdf = 0.0
    total = 0.0
    for k in range(L.shape[0]):
        total += L[k, SW]
    if total <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for k in range(L.shape[0]):
        if side != 0.0 and (_lobe_side(L, k, wix, wiy, wiz) < 0.0) != (side < 0.0):
            continue
        v0, v1, v2, pk = lobe_eval(L, k, wox, woy, woz, wix, wiy, wiz)
        ac = _lobe_cos(L, k, wix, wiy, wiz) if cosine else 1.0
        v0, v1, v2 = L[k, W] * v0 * ac, L[k, W + 1] * v1 * ac, L[k, W + 2] * v2 * ac
        if _lobe_flags(L, k) == LOBE_DIFFUSE:
            d0 += v0
            d1 += v1
            d2 += v2
        else:
            g0 += v0
            g1 += v1
            g2 += v2
        pdf += L[k, SW] / total * pk
    return d0, d1, d2, g0, g1, g2, pdf


# --- the public kernels ------------------------------------------------------------------------

@njit(cache=True, error_model="numpy")
def _local(nsx, nsy, nsz, ngx, ngy, ngz, tx, ty, tz, wox, woy, woz):
    """The shading frame (n flipped to ng's side; ng itself where wo is below ns)."""
    if nsx * ngx + nsy * ngy + nsz * ngz < 0.0:
        nsx, nsy, nsz = -nsx, -nsy, -nsz
    if nsx * wox + nsy * woy + nsz * woz <= 1e-7:
        nsx, nsy, nsz = ngx, ngy, ngz
    ux, uy, uz, bx, by, bz = frame(nsx, nsy, nsz, tx, ty, tz)
    return ux, uy, uz, bx, by, bz, nsx, nsy, nsz


@njit(cache=True, error_model="numpy")
def eval_bsdf(tab, m, c0, c1, c2, wox, woy, woz, wix, wiy, wiz, nsx, nsy, nsz,
              ngx, ngy, ngz, tx, ty, tz, entering):
    """f * |cos(ns, wi)| over material m's non-delta lobes (RGB) and the solid-angle pdf
    ``sample_bsdf`` gives wi: (f0, f1, f2, pdf). ``entering`` as for ``sample_bsdf`` (the
    side of the mesh wo is on: a dielectric's eta, so the transmission's value)."""
    ux, uy, uz, bx, by, bz, nx, ny, nz = _local(nsx, nsy, nsz, ngx, ngy, ngz, tx, ty, tz,
                                                wox, woy, woz)
    lox, loy, loz = wox * ux + woy * uy + woz * uz, wox * bx + woy * by + woz * bz, \
        wox * nx + woy * ny + woz * nz
    lix, liy, liz = wix * ux + wiy * uy + wiz * uz, wix * bx + wiy * by + wiz * bz, \
        wix * nx + wiy * ny + wiz * nz
    if loz <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    L = _lobes(tab, m, c0, c1, c2, lox, loy, loz, entering, 0.0, ux, uy, uz, bx, by, bz,
               nx, ny, nz)
    return lobes_eval(L, lox, loy, loz, lix, liy, liz)


@njit(cache=True, error_model="numpy", inline="always")
def _adjoint_lobes(buffer, tab, m, c0, c1, c2, wox, woy, woz, wix, wiy, wiz, nsx, nsy, nsz,
                   ngx, ngy, ngz, tx, ty, tz, entering, lam):
    """Material m's lobes with the viewer at wi (``adjoint_weight``'s doc), built in
    ``buffer``: (L, lix, liy, liz, lox, loy, loz) in their frame, L empty where wi or wo
    lies on the wrong side of the shading normal."""
    transmit = (wix * ngx + wiy * ngy + wiz * ngz) * (wox * ngx + woy * ngy + woz * ngz) < 0.0
    if transmit:  # the frame and the dielectric's side of the viewer, wi
        nsx, nsy, nsz, ngx, ngy, ngz = -nsx, -nsy, -nsz, -ngx, -ngy, -ngz
        entering = not entering
    ux, uy, uz, bx, by, bz, nx, ny, nz = _local(nsx, nsy, nsz, ngx, ngy, ngz, tx, ty, tz,
                                                wix, wiy, wiz)
    liz = wix * nx + wiy * ny + wiz * nz
    lix, liy = wix * ux + wiy * uy + wiz * uz, wix * bx + wiy * by + wiz * bz
    lox, loy, loz = wox * ux + woy * uy + woz * uz, wox * bx + woy * by + woz * bz, \
        wox * nx + woy * ny + woz * nz
    if liz <= 0.0 or ((loz >= 0.0) if transmit else (loz <= 0.0)):
        return buffer[:0], lix, liy, liz, lox, loy, loz
    n = _lobes_into(buffer, tab, m, c0, c1, c2, lix, liy, liz, entering, lam, ux, uy, uz, bx,
                    by, bz, nx, ny, nz)
    L = buffer[:n]
    if transmit:
        for k in range(n):
            if int(L[k, T]) == L_DIELECTRIC:
                e2 = L[k, ETA] * L[k, ETA]
                L[k, W] /= e2
                L[k, W + 1] /= e2
                L[k, W + 2] /= e2
    return L, lix, liy, liz, lox, loy, loz


@njit(cache=True, error_model="numpy", inline="always")
def adjoint_weight(buffer, tab, m, c0, c1, c2, wox, woy, woz, wix, wiy, wiz, nsx, nsy, nsz,
                   ngx, ngy, ngz, tx, ty, tz, entering, pdf, lam):
    """A photon's weight for a direction it sampled with ``sample_bsdf_into`` (wo toward
    where it came from, wi where it goes, the sample's solid-angle pdf > 0):
    f(wi, wo) |cos(ns, wi)| / pdf, the BSDF with the viewer on the photon's outgoing side
    (RGB; 0, 0, 0 where wi or wo lies on the wrong side of the shading normal). Cycles'
    BSDFs are not reciprocal: a Principled layer scales the lobes below by 1 - its albedo
    toward the VIEWER, and the multiscatter GGX compensation is a function of the viewer's
    angle (and, through a dielectric, of its side's eta) too, so the light a surface sends
    toward wi is f(wi, wo), not the f(wo, wi) the sampler weighs (the camera's).

    A transmission (wi on the far side of ng): the viewer's side is wi's, so the mesh's
    other side (``entering`` flips, a dielectric's eta inverts). A rough dielectric's
    BTDF seen from the other side is the same microfacet term over eta_wi^2 (eta_wi = its
    eta from wi's side; camera paths drop the eta^2 of radiance, Cycles' convention, and
    a photon's flux carries none): its rows are divided by eta_wi^2, so that without
    multiscatter compensation the weight is the sampler's. ``buffer``: a ``lobe_buffer``."""
    L, lix, liy, liz, lox, loy, loz = _adjoint_lobes(
        buffer, tab, m, c0, c1, c2, wox, woy, woz, wix, wiy, wiz, nsx, nsy, nsz, ngx, ngy,
        ngz, tx, ty, tz, entering, lam)
    if L.shape[0] == 0:
        return 0.0, 0.0, 0.0
    f0, f1, f2, _ = lobes_eval(L, lix, liy, liz, lox, loy, loz)
    q = liz / (abs(loz) * pdf)  # f |cos wo| -> f |cos wi| / pdf
    return f0 * q, f1 * q, f2 * q


@njit(cache=True, error_model="numpy", inline="always")
def class_weight(buffer, tab, m, c0, c1, c2, wox, woy, woz, wix, wiy, wiz, nsx, nsy, nsz,
                 ngx, ngy, ngz, tx, ty, tz, entering, diffuse, lam):
    """A photon's weight at a material with both diffuse-like and other lobes, for a
    direction wi it sampled from one of its non-delta lobes (``sample_bsdf_into``, wo toward
    where it came from): f_c(wi, wo) |cos(ns, wi)| / p_c(wi), c the class of the lobe it
    sampled (the diffuse-like lobes when ``diffuse``, else the others), f_c that class's
    lobes with the viewer on the photon's outgoing side (``adjoint_weight``) and p_c the
    probability density of picking a lobe of that class and sampling wi from it.

    Why not ``adjoint_weight``'s f / p over all lobes: photon paths are told apart by the
    class of their bounces (the caustic map keeps light -> glossy / specular+ -> diffuse,
    final gathering and the preview's global map the rest), and f / p weighs a glossy-class
    bounce with the diffuse lobes' f too. A Principled wall's glossy-class photons then carried
    part of its diffuse reflection into the caustic map, which final gathering also counts
    (a red coated object's caustics on the floor came out 10x Cycles' in red). Per class,
    each map holds its own light and the two classes still sum to the whole BSDF (the class
    picked with probability S_c, then wi from its lobes: E = the integral of f_c |cos|).
    RGB; 0, 0, 0 where no lobe of the class reaches wi. ``buffer``: a ``lobe_buffer``."""
    ux, uy, uz, bx, by, bz, nx, ny, nz = _local(nsx, nsy, nsz, ngx, ngy, ngz, tx, ty, tz,
                                                wox, woy, woz)
    lox, loy, loz = wox * ux + woy * uy + woz * uz, wox * bx + woy * by + woz * bz, \
        wox * nx + woy * ny + woz * nz
    if loz <= 0.0:
        return 0.0, 0.0, 0.0
    L = buffer[:_lobes_into(buffer, tab, m, c0, c1, c2, lox, loy, loz, entering, lam, ux, uy,
                            uz, bx, by, bz, nx, ny, nz)]
    lix, liy, liz = wix * ux + wiy * uy + wiz * uz, wix * bx + wiy * by + wiz * bz, \
        wix * nx + wiy * ny + wiz * nz
    total = 0.0
    for k in range(L.shape[0]):
        total += L[k, SW]
    pdf = 0.0
    for k in range(L.shape[0]):
        if (_lobe_flags(L, k) == LOBE_DIFFUSE) == diffuse:
            pdf += L[k, SW] / total * lobe_eval(L, k, lox, loy, loz, lix, liy, liz)[3]
    if not pdf > 0.0:
        return 0.0, 0.0, 0.0
    L, lix, liy, liz, lox, loy, loz = _adjoint_lobes(
        buffer, tab, m, c0, c1, c2, wox, woy, woz, wix, wiy, wiz, nsx, nsy, nsz, ngx, ngy,
        ngz, tx, ty, tz, entering, lam)
    if L.shape[0] == 0:
        return 0.0, 0.0, 0.0
    d0, d1, d2, g0, g1, g2, _ = lobes_eval_parts(L, lix, liy, liz, lox, loy, loz, True)
    q = liz / (abs(loz) * pdf)  # f |cos wo| -> f |cos wi| / p_c
    if diffuse:
        return d0 * q, d1 * q, d2 * q
    return g0 * q, g1 * q, g2 * q


@njit(cache=True, error_model="numpy", inline="always")
def hit_lobes(tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz, ngx, ngy, ngz, tx, ty, tz,
              entering, lam=0.0):
    """Material m's lobe rows at one hit and its shading frame, to evaluate many wi at the
    same wo (``parts_at``; photon gathering): (L (n, NL) float64, F (12,) float64: t, b, n
    and wo in the local frame). No rows where wo is below the surface. lam: the path's
    wavelength in nm, 0 for an RGB path (``transmission_ior``). A kernel over many hits
    writes them into a ``lobe_buffer`` of its own instead (``hit_lobes_into``).

    Inlined into its callers (``inline="always"``), as ``parts_at``, ``lobes_eval_parts``
    and ``lobe_eval``: numba increfs and decrefs every array a function takes at each call
    it cannot prune, and these run per hit and per light sample (issue 13)."""
    L = _material_buffer(tab, m)
    F = np.empty(12)
    n = hit_lobes_into(L, F, tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz, ngx, ngy, ngz,
                       tx, ty, tz, entering, lam)
    return L[:n], F


@njit(cache=True, error_model="numpy", inline="always")
def hit_lobes_into(L, F, tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz, ngx, ngy, ngz,
                   tx, ty, tz, entering, lam):
    """``hit_lobes`` written into L (a ``lobe_buffer``) and F (12,) float64; returns the
    number of rows n (``L[:n]`` are the lobes; 0 where wo is below the surface)."""
    ux, uy, uz, bx, by, bz, nx, ny, nz = _local(nsx, nsy, nsz, ngx, ngy, ngz, tx, ty, tz,
                                                wox, woy, woz)
    F[0], F[1], F[2], F[3], F[4], F[5], F[6], F[7], F[8] = ux, uy, uz, bx, by, bz, nx, ny, nz
    F[9] = wox * ux + woy * uy + woz * uz
    F[10] = wox * bx + woy * by + woz * bz
    F[11] = wox * nx + woy * ny + woz * nz
    if F[11] <= 0.0:
        return 0
    return _lobes_into(L, tab, m, c0, c1, c2, F[9], F[10], F[11], entering, lam, ux, uy, uz,
                       bx, by, bz, nx, ny, nz)


@njit(cache=True, error_model="numpy", inline="always")
def parts_at(L, F, wix, wiy, wiz, ngx, ngy, ngz, sided, cosine):
    """``lobes_eval_parts`` of ``hit_lobes``' (L, F) at the world direction wi: (d0, d1,
    d2, g0, g1, g2, pdf). With ``sided`` (photons gathered from both sides) a lobe counts
    only where wi's side of the true surface (wi . ng < 0: transmitted) agrees with its
    side of that lobe's own normal (``_lobe_side``: the shading normal, or the coat's /
    sheen's normal of its own), as ``sample_bsdf`` refuses a sample of lobe k that the two
    put on different sides and as Cycles evaluates each closure by its own N: so only
    transmitting lobes see the far side, and a coat whose normal keeps wi above it still
    reflects where a bumped base normal puts wi below."""
    if L.shape[0] == 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    lix = wix * F[0] + wiy * F[1] + wiz * F[2]
    liy = wix * F[3] + wiy * F[4] + wiz * F[5]
    liz = wix * F[6] + wiy * F[7] + wiz * F[8]
    side = 0.0
    if sided:
        side = -1.0 if wix * ngx + wiy * ngy + wiz * ngz < 0.0 else 1.0
    return lobes_eval_parts(L, F[9], F[10], F[11], lix, liy, liz, cosine, side)


@njit(cache=True, error_model="numpy")
def eval_parts(tab, m, c0, c1, c2, wox, woy, woz, wix, wiy, wiz, nsx, nsy, nsz,
               ngx, ngy, ngz, tx, ty, tz, entering, sided, lam=0.0):
    """``eval_bsdf`` split into material m's diffuse-like part and glossy part:
    (d0, d1, d2, g0, g1, g2, pdf), f |cos(ns, wi)| RGB (1/sr) and the pdf ``sample_bsdf``
    gives wi; ``sided`` as ``parts_at``; lam the path's wavelength in nm (0: RGB), as for
    ``sample_bsdf``, so that light sampling and BSDF sampling see the same IOR (MIS)."""
    L, F = hit_lobes(tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz, ngx, ngy, ngz,
                     tx, ty, tz, entering, lam)
    return parts_at(L, F, wix, wiy, wiz, ngx, ngy, ngz, sided, True)


@njit(cache=True, error_model="numpy")
def sample_bsdf(tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz, ngx, ngy, ngz,
                tx, ty, tz, entering, u_lobe, u1, u2, lam=0.0):
    """Sample wi for material m: (wix, wiy, wiz, w0, w1, w2, pdf, flags), w = f |cos| / pdf
    (path weight, RGB), pdf 0 for a delta lobe, flags LOBE_* (0: no direction). u_lobe
    picks the lobe (and, rescaled, a dielectric's reflection vs refraction). lam: the
    path's wavelength in nm, 0 for an RGB path (``transmission_ior``). A kernel over many
    hits builds the lobes in a ``lobe_buffer`` of its own (``sample_bsdf_into``)."""
    L = _material_buffer(tab, m)
    return sample_bsdf_into(L, tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz, ngx, ngy,
                            ngz, tx, ty, tz, entering, u_lobe, u1, u2, lam)


@njit(cache=True, error_model="numpy", inline="always")
def sample_bsdf_into(buffer, tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz, ngx, ngy, ngz,
                     tx, ty, tz, entering, u_lobe, u1, u2, lam):
    """``sample_bsdf`` with material m's lobes built in ``buffer`` (a ``lobe_buffer``);
    inlined (per photon bounce: its array arguments' reference counts, issue 13)."""
    ux, uy, uz, bx, by, bz, nx, ny, nz = _local(nsx, nsy, nsz, ngx, ngy, ngz, tx, ty, tz,
                                                wox, woy, woz)
    lox, loy, loz = wox * ux + woy * uy + woz * uz, wox * bx + woy * by + woz * bz, \
        wox * nx + woy * ny + woz * nz
    if loz <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    L = buffer[:_lobes_into(buffer, tab, m, c0, c1, c2, lox, loy, loz, entering, lam, ux, uy,
                            uz, bx, by, bz, nx, ny, nz)]
    return _sample_built(L, ux, uy, uz, bx, by, bz, nx, ny, nz, lox, loy, loz, ngx, ngy, ngz,
                         u_lobe, u1, u2)


@njit(cache=True, error_model="numpy", inline="always")
def sample_lobes(L, F, ngx, ngy, ngz, u_lobe, u1, u2):
    """``sample_bsdf`` from the lobes L and frame F that ``hit_lobes_into`` built at the
    hit (the same rows ``sample_bsdf`` would build), so that a kernel which then evaluates
    the sampled direction (``parts_at``) builds them once."""
    return _sample_built(L, F[0], F[1], F[2], F[3], F[4], F[5], F[6], F[7], F[8], F[9], F[10],
                         F[11], ngx, ngy, ngz, u_lobe, u1, u2)


@njit(cache=True, error_model="numpy", inline="always")
def _sample_built(L, ux, uy, uz, bx, by, bz, nx, ny, nz, lox, loy, loz, ngx, ngy, ngz, u_lobe,
                  u1, u2):
    """The sampling half of ``sample_bsdf_into``: pick a lobe of L (rows built in the frame
    u, b, n with wo's local coordinates lo) by the sample weights and sample it."""
    total = 0.0
    for k in range(L.shape[0]):
        total += L[k, SW]
    if total <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    target = u_lobe * total
    acc = 0.0
    k = L.shape[0] - 1
    for j in range(L.shape[0]):
        if target < acc + L[j, SW]:
            k = j
            break
        acc += L[j, SW]
    swk = L[k, SW]
    if swk <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    u3 = min(max((target - acc) / swk, 0.0), 1.0 - 1e-12)
    lx, ly, lz, v0, v1, v2, pk, delta, ok = lobe_sample(L, k, lox, loy, loz, u1, u2, u3)
    if not ok:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    wix = lx * ux + ly * bx + lz * nx
    wiy = lx * uy + ly * by + lz * ny
    wiz = lx * uz + ly * bz + lz * nz
    ln = np.sqrt(wix * wix + wiy * wiy + wiz * wiz)
    wix, wiy, wiz = wix / ln, wiy / ln, wiz / ln
    # The geometric side must agree with the lobe's (as Cycles' samplers check ng).
    below = wix * ngx + wiy * ngy + wiz * ngz < 0.0
    if below != (_lobe_side(L, k, lx, ly, lz) < 0.0):
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    flags = LOBE_TRANSMIT if below else 0
    if delta:
        q = total / swk
        return (wix, wiy, wiz, L[k, W] * v0 * q, L[k, W + 1] * v1 * q, L[k, W + 2] * v2 * q,
                0.0, flags | LOBE_DELTA)
    f0, f1, f2, pdf = lobes_eval(L, lox, loy, loz, lx, ly, lz)
    if not pdf > 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    return wix, wiy, wiz, f0 / pdf, f1 / pdf, f2 / pdf, pdf, flags | _lobe_flags(L, k)


@njit(cache=True, error_model="numpy")
def sample_delta(tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz, ngx, ngy, ngz,
                 tx, ty, tz, entering, u_lobe, u1, u2, lam=0.0):
    """Sample one of material m's singular lobes (mirror, smooth glass) by their sample
    weights: (wix, wiy, wiz, w0, w1, w2, share, flags). w is the path weight of the delta
    lobes as a whole (the chosen lobe's weight over the probability of choosing it among
    them: E[w] = the sum of their weights); share = their sample weight over the
    material's, all lobes (the probability ``sample_bsdf`` would follow one of them: the
    progressive mode's visible points stop at the others with probability 1 - share);
    flags LOBE_DELTA (| LOBE_TRANSMIT), 0 when no direction (no singular lobe, or the
    sample failed). Arguments as ``sample_bsdf``; lam the path's wavelength in nm (0: RGB)."""
    ux, uy, uz, bx, by, bz, nx, ny, nz = _local(nsx, nsy, nsz, ngx, ngy, ngz, tx, ty, tz,
                                                wox, woy, woz)
    lox, loy, loz = wox * ux + woy * uy + woz * uz, wox * bx + woy * by + woz * bz, \
        wox * nx + woy * ny + woz * nz
    if loz <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    L = _lobes(tab, m, c0, c1, c2, lox, loy, loz, entering, lam, ux, uy, uz, bx, by, bz,
               nx, ny, nz)
    total = 0.0
    singular = 0.0
    for k in range(L.shape[0]):
        total += L[k, SW]
        t = int(L[k, T])
        if ((t == L_GGX or t == L_DIELECTRIC or t == L_THIN_T)
                and microfacet.is_singular(L[k, AX], L[k, AY])):
            singular += L[k, SW]
    if not (singular > 0.0 and total > 0.0):
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0
    share = min(singular / total, 1.0)
    target = u_lobe * singular
    acc = 0.0
    k = -1
    for j in range(L.shape[0]):
        t = int(L[j, T])
        if not ((t == L_GGX or t == L_DIELECTRIC or t == L_THIN_T)
                and microfacet.is_singular(L[j, AX], L[j, AY])) or L[j, SW] <= 0.0:
            continue
        k = j
        if target < acc + L[j, SW]:
            break
        acc += L[j, SW]
    swk = L[k, SW]
    u3 = min(max((target - acc) / swk, 0.0), 1.0 - 1e-12)
    lx, ly, lz, v0, v1, v2, _, delta, ok = lobe_sample(L, k, lox, loy, loz, u1, u2, u3)
    if not ok or not delta:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, share, 0
    wix = lx * ux + ly * bx + lz * nx
    wiy = lx * uy + ly * by + lz * ny
    wiz = lx * uz + ly * bz + lz * nz
    ln = np.sqrt(wix * wix + wiy * wiy + wiz * wiz)
    wix, wiy, wiz = wix / ln, wiy / ln, wiz / ln
    below = wix * ngx + wiy * ngy + wiz * ngz < 0.0
    if below != (_lobe_side(L, k, lx, ly, lz) < 0.0):  # as sample_bsdf: the geometric side must agree with the lobe's
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, share, 0
    q = singular / swk
    return (wix, wiy, wiz, L[k, W] * v0 * q, L[k, W + 1] * v1 * q, L[k, W + 2] * v2 * q,
            share, (LOBE_TRANSMIT if below else 0) | LOBE_DELTA)


@njit(cache=True, error_model="numpy")
def albedo(tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz):
    """Directional albedo at wo: (d0, d1, d2, a0, a1, a2): the diffuse-like lobes' part
    (Lambert, Oren-Nayar, translucent, sheen; 0 when material m has none: no photon is
    stored there) and the whole material's (RGB, estimates from the albedo tables). A
    kernel over many hits builds the lobes in a ``lobe_buffer`` of its own
    (``albedo_into``)."""
    return albedo_into(_material_buffer(tab, m), tab, m, c0, c1, c2, wox, woy, woz, nsx,
                       nsy, nsz)


@njit(cache=True, error_model="numpy", inline="always")
def albedo_into(buffer, tab, m, c0, c1, c2, wox, woy, woz, nsx, nsy, nsz):
    """``albedo`` with material m's lobes built in ``buffer`` (a ``lobe_buffer``)."""
    cz = nsx * wox + nsy * woy + nsz * woz
    if cz < 0.0:
        nsx, nsy, nsz = -nsx, -nsy, -nsz
        cz = -cz
    ux, uy, uz, bx, by, bz = frame(nsx, nsy, nsz, 1.0, 0.0, 0.0)
    lox = wox * ux + woy * uy + woz * uz
    loy = wox * bx + woy * by + woz * bz
    L = buffer[:_lobes_into(buffer, tab, m, c0, c1, c2, lox, loy, max(cz, 1e-7), True, 0.0,
                            ux, uy, uz, bx, by, bz, nsx, nsy, nsz)]
    d0 = d1 = d2 = a0 = a1 = a2 = 0.0
    for k in range(L.shape[0]):
        e = L[k, EST]
        if int(L[k, T]) == L_GGX:
            # the Fresnel estimate at wo (about the lobe's own normal) times the
            # single-scattering albedo
            g0, g1, g2 = _ggx_fresnel(L, k, _lobe_side(L, k, lox, loy, max(cz, 1e-7))
                                      if L[k, OWN] > 0.5 else cz)
        else:
            g0 = g1 = g2 = 1.0
        v0, v1, v2 = L[k, W] * e * g0, L[k, W + 1] * e * g1, L[k, W + 2] * e * g2
        a0 += v0
        a1 += v1
        a2 += v2
        if _lobe_flags(L, k) == LOBE_DIFFUSE:
            d0 += v0
            d1 += v1
            d2 += v2
    return d0, d1, d2, a0, a1, a2


@njit(cache=True, parallel=True, error_model="numpy")
def _diffuse_albedo_kernel(tab, rows, texel, d, ns, out):
    n = rows.shape[0]
    for block in prange((n + LOBE_BLOCK - 1) // LOBE_BLOCK):
        lobes = lobe_buffer(tab)  # the block's scratch: no allocation per hit
        for i in range(block * LOBE_BLOCK, min(n, (block + 1) * LOBE_BLOCK)):
            a0, a1, a2, _, _, _ = albedo_into(lobes, tab, rows[i], texel[i, 0], texel[i, 1],
                                              texel[i, 2], -d[i, 0], -d[i, 1], -d[i, 2],
                                              ns[i, 0], ns[i, 1], ns[i, 2])
            out[i, 0], out[i, 1], out[i, 2] = a0, a1, a2


def diffuse_albedo(tab: ClosureTable, rows, texel, d, ns) -> np.ndarray:
    """``albedo``'s diffuse part at N hits: (N, 3) float64 RGB. rows (N,) int32 material
    rows of ``tab``, texel (N, 3) the texel colours, d (N, 3) the arriving unit
    directions (wo = -d), ns (N, 3) unit shading normals."""
    n = rows.shape[0]
    out = np.empty((n, 3))
    if n:
        _diffuse_albedo_kernel(tab, np.ascontiguousarray(rows, np.int32),
                               np.ascontiguousarray(texel, np.float64),
                               np.ascontiguousarray(d, np.float64),
                               np.ascontiguousarray(ns, np.float64), out)
    return out


# --- vectorised wrappers (tests, tools) ----------------------------------------------------------

@njit(cache=True, error_model="numpy")
def _vec_sample(tab, m, wo, ns, ng, t, entering, u, lam, out):
    for i in range(u.shape[0]):
        r = sample_bsdf(tab, m, 1.0, 1.0, 1.0, wo[0], wo[1], wo[2], ns[0], ns[1], ns[2],
                        ng[0], ng[1], ng[2], t[0], t[1], t[2], entering, u[i, 0], u[i, 1],
                        u[i, 2], lam)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = r[0], r[1], r[2], r[3]
        out[i, 4], out[i, 5], out[i, 6], out[i, 7] = r[4], r[5], r[6], r[7]


def sample_many(tab: ClosureTable, m: int, wo, ns, ng, t, entering: bool, u,
                lam: float = 0.0) -> np.ndarray:
    """``sample_bsdf`` for uniforms u (N, 3) (u_lobe, u1, u2) at one hit (texel colour 1)
    of a path of wavelength lam nm (0: RGB): (N, 8) float64 rows wi (3), w (3), pdf, flags."""
    u = np.ascontiguousarray(u, np.float64).reshape(-1, 3)
    out = np.empty((u.shape[0], 8))
    _vec_sample(tab, int(m), *(np.asarray(v, np.float64) for v in (wo, ns, ng, t)),
                bool(entering), u, float(lam), out)
    return out


@njit(cache=True, error_model="numpy")
def _vec_eval(tab, m, wo, wi, ns, ng, t, entering, out):
    for i in range(wi.shape[0]):
        r = eval_bsdf(tab, m, 1.0, 1.0, 1.0, wo[0], wo[1], wo[2], wi[i, 0], wi[i, 1],
                      wi[i, 2], ns[0], ns[1], ns[2], ng[0], ng[1], ng[2], t[0], t[1], t[2],
                      entering)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = r[0], r[1], r[2], r[3]


def eval_many(tab: ClosureTable, m: int, wo, wi, ns, ng, t, entering: bool) -> np.ndarray:
    """``eval_bsdf`` for directions wi (N, 3) at one hit (texel colour 1): (N, 4) float64
    rows f |cos| (3), pdf."""
    wi = np.ascontiguousarray(wi, np.float64).reshape(-1, 3)
    out = np.empty((wi.shape[0], 4))
    _vec_eval(tab, int(m), np.asarray(wo, np.float64), wi,
              *(np.asarray(v, np.float64) for v in (ns, ng, t)), bool(entering), out)
    return out


@njit(cache=True, error_model="numpy")
def _vec_photon(tab, m, wo, wi, pdf, diffuse, by_class, ns, ng, t, entering, out):
    buffer = lobe_buffer(tab)
    for i in range(wi.shape[0]):
        if by_class:
            r = class_weight(buffer, tab, m, 1.0, 1.0, 1.0, wo[0], wo[1], wo[2], wi[i, 0],
                             wi[i, 1], wi[i, 2], ns[0], ns[1], ns[2], ng[0], ng[1], ng[2],
                             t[0], t[1], t[2], entering, diffuse[i], 0.0)
        else:
            r = adjoint_weight(buffer, tab, m, 1.0, 1.0, 1.0, wo[0], wo[1], wo[2], wi[i, 0],
                               wi[i, 1], wi[i, 2], ns[0], ns[1], ns[2], ng[0], ng[1], ng[2],
                               t[0], t[1], t[2], entering, pdf[i], 0.0)
        out[i, 0], out[i, 1], out[i, 2] = r[0], r[1], r[2]


def photon_weight_many(tab: ClosureTable, m: int, wo, wi, ns, ng, t, entering: bool, *,
                       pdf=None, diffuse=None) -> np.ndarray:
    """A photon's weight for sampled directions wi (N, 3) at one hit (texel colour 1, RGB
    path): ``adjoint_weight`` with the samples' pdfs ``pdf`` (N,), or ``class_weight`` with
    ``diffuse`` (N,) bool, the classes of the lobes they were sampled from (give one of
    the two): (N, 3) float64."""
    if (pdf is None) == (diffuse is None):
        raise ValueError("photon_weight_many needs exactly one of pdf= or diffuse=")
    wi = np.ascontiguousarray(wi, np.float64).reshape(-1, 3)
    n = wi.shape[0]
    out = np.empty((n, 3))
    _vec_photon(tab, int(m), np.asarray(wo, np.float64), wi,
                np.zeros(n) if pdf is None else np.ascontiguousarray(pdf, np.float64).reshape(-1),
                np.zeros(n, np.bool_) if diffuse is None
                else np.ascontiguousarray(diffuse, np.bool_).reshape(-1),
                diffuse is not None, *(np.asarray(v, np.float64) for v in (ns, ng, t)),
                bool(entering), out)
    return out


@njit(cache=True, error_model="numpy")
def _vec_parts(tab, m, wo, wi, ns, ng, t, entering, sided, out):
    for i in range(wi.shape[0]):
        r = eval_parts(tab, m, 1.0, 1.0, 1.0, wo[0], wo[1], wo[2], wi[i, 0], wi[i, 1],
                       wi[i, 2], ns[0], ns[1], ns[2], ng[0], ng[1], ng[2], t[0], t[1], t[2],
                       entering, sided)
        for c in range(7):
            out[i, c] = r[c]


def parts_many(tab: ClosureTable, m: int, wo, wi, ns, ng, t, entering: bool,
               sided: bool) -> np.ndarray:
    """``eval_parts`` for directions wi (N, 3) at one hit (texel colour 1): (N, 7) float64
    rows diffuse-like f |cos| (3), glossy f |cos| (3), pdf. With ``sided`` the pdf is the
    density ``sample_bsdf``'s accepted directions have (each lobe's where its side agrees
    with the true surface's)."""
    wi = np.ascontiguousarray(wi, np.float64).reshape(-1, 3)
    out = np.empty((wi.shape[0], 7))
    _vec_parts(tab, int(m), np.asarray(wo, np.float64), wi,
               *(np.asarray(v, np.float64) for v in (ns, ng, t)), bool(entering),
               bool(sided), out)
    return out


def albedo_at(tab: ClosureTable, m: int, wo, ns, color=(1.0, 1.0, 1.0)) -> np.ndarray:
    """``albedo`` at one hit: (6,) float64 (diffuse part RGB, total RGB)."""
    return np.array(albedo(tab, int(m), float(color[0]), float(color[1]), float(color[2]),
                           *map(float, wo), *map(float, ns)))
