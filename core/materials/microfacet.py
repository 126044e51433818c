"""GGX and Beckmann microfacet lobes in the local shading frame (z = the shading normal).

Two lobes, each with ``eval`` (f, without the cosine), ``sample`` and ``pdf``:

- reflection (``reflect_*``): anisotropic GGX (alpha_x along local x, alpha_y along y),
  height-correlated Smith masking-shadowing, visible-normal sampling (Heitz 2018), no
  Fresnel (the caller multiplies by the Fresnel term of ``h . wo``, ``reflect_eval``
  returns that cosine); Glossy, Metallic, Principled's specular, metal and coat layers;
- rough dielectric (``dielectric_*``, Walter et al. 2007 as Cycles writes it): reflection and
  refraction picked by the Fresnel-weighted probability avg(R) / avg(R + T) at the sampled
  microfacet, isotropic alpha, eta = n_far / n_near. Fresnel (RGB) is Cycles' generalized
  Schlick in its "real curve" form (``fresnel.schlick_real``): F = mix(F0, 1, s), R = F *
  r_tint, T = (1 - F) * t_tint; ``refract_only`` gives the Refraction BSDF (R = 0, T = 1
  but under total internal reflection).

Every lobe function takes ``beck`` (default False): True gives the Beckmann distribution
(Cycles' Beckmann closures, the Glossy / Glass / Refraction / Metallic nodes' "Beckmann"; the
Refraction node's default): its D, Cycles' rational approximation of its Smith Lambda
(bsdf_microfacet.h, ``bsdf_lambda_from_sqr_alpha_tan_n``), and microfacet normals sampled
from D(h) cos(h) (``sample_beckmann``, not the visible normals; the pdfs say so: one value
per direction whatever the sampler, so MIS and the chi-square tests hold). Beckmann and GGX
differ most in their tails: rendered as GGX, a Beckmann Refraction sphere of roughness 0.2
came out 3 % dark, its rim up to 22 % (the Cycles test's refraction scene).

Below ``bsdf.SINGULAR_ALPHA2`` (alpha_x * alpha_y) a lobe is a delta: ``*_sample`` returns
the mirror / refracted direction with pdf 0 and weight = the Fresnel factor over the choice
probability, ``*_eval`` and ``*_pdf`` return 0. wo is on the +z side (the caller ensures
it); directions are unit tuples.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from . import fresnel
from .bsdf import SINGULAR_ALPHA2, fresnel_dielectric


@njit(cache=True, error_model="numpy")
def is_singular(ax, ay):
    """A lobe this smooth is a delta (the legacy lobes' threshold, bsdf.SINGULAR_ALPHA2)."""
    return ax * ay <= SINGULAR_ALPHA2


@njit(cache=True, error_model="numpy")
def ggx_d(ax, ay, hx, hy, hz):
    """Anisotropic GGX normal distribution D(h), 1/sr (symmetric in the sign of h.z)."""
    x = hx / ax
    y = hy / ay
    l2 = x * x + y * y + hz * hz
    return 1.0 / (np.pi * ax * ay * l2 * l2)


@njit(cache=True, error_model="numpy")
def ggx_lambda(ax, ay, vx, vy, vz):
    """Smith's Lambda of direction v: G1 = 1 / (1 + Lambda)."""
    if vz == 0.0:
        return 1e30
    s = ((ax * vx) ** 2 + (ay * vy) ** 2) / (vz * vz)
    return 0.5 * (np.sqrt(1.0 + s) - 1.0)


@njit(cache=True, error_model="numpy")
def beckmann_d(ax, ay, hx, hy, hz):
    """Anisotropic Beckmann normal distribution D(h), 1/sr (h.z > 0)."""
    c2 = hz * hz
    if c2 <= 0.0:
        return 0.0
    x = hx / ax
    y = hy / ay
    return np.exp(-(x * x + y * y) / c2) / (np.pi * ax * ay * c2 * c2)


@njit(cache=True, error_model="numpy")
def beckmann_lambda(ax, ay, vx, vy, vz):
    """Smith's Lambda of the Beckmann distribution, Cycles' rational approximation (exact
    within about 0.4 %; 0 when 1 / (alpha tan theta) >= 1.6)."""
    if vz == 0.0:
        return 1e30
    s = ((ax * vx) ** 2 + (ay * vy) ** 2) / (vz * vz)
    if s < 0.39:
        return 0.0
    a = 1.0 / np.sqrt(s)
    return ((0.396 * a - 1.259) * a + 1.0) / ((2.181 * a + 3.535) * a)


@njit(cache=True, error_model="numpy")
def ndf(beck, ax, ay, hx, hy, hz):
    """D(h) of GGX or (beck) Beckmann."""
    return beckmann_d(ax, ay, hx, hy, hz) if beck else ggx_d(ax, ay, hx, hy, hz)


@njit(cache=True, error_model="numpy")
def smith_lambda(beck, ax, ay, vx, vy, vz):
    """Smith's Lambda of GGX or (beck) Beckmann."""
    return beckmann_lambda(ax, ay, vx, vy, vz) if beck else ggx_lambda(ax, ay, vx, vy, vz)


@njit(cache=True, error_model="numpy")
def sample_beckmann(ax, ay, u1, u2):
    """A Beckmann microfacet normal distributed as D(h) h.z (slopes Gaussian of deviations
    alpha / sqrt(2) per axis): (hx, hy, hz)."""
    r = np.sqrt(-np.log(max(1.0 - u1, 1e-300)))
    phi = 2.0 * np.pi * u2
    sx, sy = ax * r * np.cos(phi), ay * r * np.sin(phi)
    hl = np.sqrt(sx * sx + sy * sy + 1.0)
    return -sx / hl, -sy / hl, 1.0 / hl


@njit(cache=True, error_model="numpy")
def sample_normal(beck, ax, ay, wox, woy, woz, u1, u2):
    """A microfacet normal h: GGX's visible normals (density G1(wo) max(0, wo . h) D(h) /
    wo.z) or (beck) Beckmann's D(h) h.z (``sample_beckmann``). Returns (hx, hy, hz)."""
    if beck:
        return sample_beckmann(ax, ay, u1, u2)
    return sample_vndf(ax, ay, wox, woy, woz, u1, u2)


@njit(cache=True, error_model="numpy")
def sample_vndf(ax, ay, wox, woy, woz, u1, u2):
    """A microfacet normal h distributed as the visible normals seen from wo (Heitz 2018):
    pdf(h) = G1(wo) max(0, wo . h) D(h) / wo.z. Returns (hx, hy, hz)."""
    vx, vy, vz = ax * wox, ay * woy, woz
    vl = np.sqrt(vx * vx + vy * vy + vz * vz)
    vx, vy, vz = vx / vl, vy / vl, vz / vl
    lensq = vx * vx + vy * vy
    if lensq > 1e-7:
        inv = 1.0 / np.sqrt(lensq)
        t1x, t1y, t1z = -vy * inv, vx * inv, 0.0
    else:
        t1x, t1y, t1z = 1.0, 0.0, 0.0
    t2x = vy * t1z - vz * t1y
    t2y = vz * t1x - vx * t1z
    t2z = vx * t1y - vy * t1x
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    p1 = r * np.cos(phi)
    p2 = r * np.sin(phi)
    s = 0.5 * (1.0 + vz)
    p2 = (1.0 - s) * np.sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2
    p3 = np.sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2))
    hx = p1 * t1x + p2 * t2x + p3 * vx
    hy = p1 * t1y + p2 * t2y + p3 * vy
    hz = p1 * t1z + p2 * t2z + p3 * vz
    hx, hy, hz = ax * hx, ay * hy, max(0.0, hz)
    hl = np.sqrt(hx * hx + hy * hy + hz * hz)
    return hx / hl, hy / hl, hz / hl


# --- reflection ------------------------------------------------------------------------------

@njit(cache=True, error_model="numpy")
def reflect_eval(ax, ay, wox, woy, woz, wix, wiy, wiz, beck=False):
    """GGX (or Beckmann) reflection without Fresnel: (f, cos(h, wo)); f in 1/sr, without
    the cosine."""
    if woz <= 0.0 or wiz <= 0.0 or is_singular(ax, ay):
        return 0.0, 1.0
    hx, hy, hz = wox + wix, woy + wiy, woz + wiz
    hl = np.sqrt(hx * hx + hy * hy + hz * hz)
    hx, hy, hz = hx / hl, hy / hl, hz / hl
    d = ndf(beck, ax, ay, hx, hy, hz)
    g = 1.0 / (1.0 + smith_lambda(beck, ax, ay, wox, woy, woz)
               + smith_lambda(beck, ax, ay, wix, wiy, wiz))
    return d * g / (4.0 * woz * wiz), hx * wox + hy * woy + hz * woz


@njit(cache=True, error_model="numpy")
def reflect_pdf(ax, ay, wox, woy, woz, wix, wiy, wiz, beck=False):
    """Solid-angle pdf of ``reflect_sample``: the sampled normal's density / (4 wo . h),
    GGX: D(h) G1(wo) / (4 wo.z), Beckmann: D(h) h.z / (4 wo . h)."""
    if woz <= 0.0 or wiz <= 0.0 or is_singular(ax, ay):
        return 0.0
    hx, hy, hz = wox + wix, woy + wiy, woz + wiz
    hl = np.sqrt(hx * hx + hy * hy + hz * hz)
    hx, hy, hz = hx / hl, hy / hl, hz / hl
    if beck:
        c = hx * wox + hy * woy + hz * woz
        return beckmann_d(ax, ay, hx, hy, hz) * hz / (4.0 * c) if c > 0.0 else 0.0
    return ggx_d(ax, ay, hx, hy, hz) / (4.0 * woz * (1.0 + ggx_lambda(ax, ay, wox, woy, woz)))


@njit(cache=True, error_model="numpy")
def reflect_sample(ax, ay, wox, woy, woz, u1, u2, beck=False):
    """Sample GGX (or Beckmann) reflection: (wix, wiy, wiz, weight, pdf, cos(h, wo));
    weight = f cos / pdf without Fresnel (GGX: G2 / G1), pdf = 0 for the delta limit
    (weight 1), weight 0 when the reflected direction falls below the surface."""
    if is_singular(ax, ay):
        return -wox, -woy, woz, 1.0, 0.0, woz
    hx, hy, hz = sample_normal(beck, ax, ay, wox, woy, woz, u1, u2)
    c = hx * wox + hy * woy + hz * woz
    wix, wiy, wiz = 2.0 * c * hx - wox, 2.0 * c * hy - woy, 2.0 * c * hz - woz
    if wiz <= 0.0 or (beck and c <= 0.0):
        return wix, wiy, wiz, 0.0, 0.0, c
    lo = smith_lambda(beck, ax, ay, wox, woy, woz)
    li = smith_lambda(beck, ax, ay, wix, wiy, wiz)
    if beck:
        pdf = beckmann_d(ax, ay, hx, hy, hz) * hz / (4.0 * c)
        f = beckmann_d(ax, ay, hx, hy, hz) / ((1.0 + lo + li) * 4.0 * woz * wiz)
        return wix, wiy, wiz, f * wiz / pdf if pdf > 0.0 else 0.0, pdf, c
    pdf = ggx_d(ax, ay, hx, hy, hz) / (4.0 * woz * (1.0 + lo))
    return wix, wiy, wiz, (1.0 + lo) / (1.0 + lo + li), pdf, c


# --- rough dielectric ------------------------------------------------------------------------

@njit(cache=True, error_model="numpy")
def dielectric_fresnel(cos_ho, eta, refract_only, f00, f01, f02, r0, r1, r2, t0, t1, t2):
    """(R0, R1, R2, T0, T1, T2, cos_t) at a microfacet: generalized Schlick "real curve"
    (F = mix(F0, 1, s)), R = F r_tint, T = (1 - F) t_tint; Refraction BSDF: R = 0, T = 1."""
    s, cos_t, _ = fresnel.schlick_real(cos_ho, eta)
    if refract_only:
        tt = 0.0 if cos_t <= 0.0 and s >= 1.0 else 1.0
        return 0.0, 0.0, 0.0, tt * t0, tt * t1, tt * t2, cos_t
    if cos_t <= 0.0 and s >= 1.0:  # total internal reflection
        return r0, r1, r2, 0.0, 0.0, 0.0, 0.0
    fa = f00 + (1.0 - f00) * s
    fb = f01 + (1.0 - f01) * s
    fc = f02 + (1.0 - f02) * s
    return (fa * r0, fb * r1, fc * r2, (1.0 - fa) * t0, (1.0 - fb) * t1, (1.0 - fc) * t2,
            cos_t)


@njit(cache=True, error_model="numpy")
def _pick_reflect(r0, r1, r2, t0, t1, t2):
    rr = r0 + r1 + r2
    tot = rr + t0 + t1 + t2
    if tot <= 0.0:
        return -1.0
    return rr / tot


@njit(cache=True, error_model="numpy")
def _half_vector(eta, wox, woy, woz, wix, wiy, wiz):
    """Microfacet normal (on wo's side) of a reflection (wi.z > 0) or a refraction; ok False
    when no microfacet relates the two directions (refraction back to the same side)."""
    if wiz > 0.0:
        hx, hy, hz = wox + wix, woy + wiy, woz + wiz
    else:
        hx, hy, hz = -(eta * wix + wox), -(eta * wiy + woy), -(eta * wiz + woz)
    hl = np.sqrt(hx * hx + hy * hy + hz * hz)
    if hl <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, False
    hx, hy, hz = hx / hl, hy / hl, hz / hl
    if hz < 0.0:
        hx, hy, hz = -hx, -hy, -hz
    ok = (hx * wox + hy * woy + hz * woz) > 0.0
    if wiz <= 0.0:
        ok = ok and (hx * wix + hy * wiy + hz * wiz) < 0.0
    return hx, hy, hz, hl, ok


@njit(cache=True, error_model="numpy")
def dielectric_eval_pdf(alpha, eta, refract_only, f00, f01, f02, r0, r1, r2, t0, t1, t2,
                        wox, woy, woz, wix, wiy, wiz, beck=False):
    """Rough dielectric: (f0, f1, f2, pdf), f without the cosine (1/sr, RGB), pdf the
    solid-angle pdf of ``dielectric_sample``."""
    if woz <= 0.0 or wiz == 0.0 or is_singular(alpha, alpha):
        return 0.0, 0.0, 0.0, 0.0
    hx, hy, hz, hl, ok = _half_vector(eta, wox, woy, woz, wix, wiy, wiz)
    if not ok:
        return 0.0, 0.0, 0.0, 0.0
    cho = hx * wox + hy * woy + hz * woz
    R0, R1, R2, T0, T1, T2, _ = dielectric_fresnel(cho, eta, refract_only, f00, f01, f02,
                                                   r0, r1, r2, t0, t1, t2)
    pr = _pick_reflect(R0, R1, R2, T0, T1, T2)
    if pr < 0.0:
        return 0.0, 0.0, 0.0, 0.0
    d = ndf(beck, alpha, alpha, hx, hy, hz)
    lo = smith_lambda(beck, alpha, alpha, wox, woy, woz)
    li = smith_lambda(beck, alpha, alpha, wix, wiy, -wiz if wiz < 0.0 else wiz)
    # pdf: the normal's density times the Jacobian of h -> wi (GGX's density is
    # D G1 (wo . h) / wo.z, which gives the common factor below over 1 + lo)
    if wiz > 0.0:
        common = d / woz * 0.25
        pdf = pr * (beckmann_d(alpha, alpha, hx, hy, hz) * hz * 0.25 / cho if beck
                    else common / (1.0 + lo))
        v = common / (1.0 + lo + li) / wiz
        return R0 * v, R1 * v, R2 * v, pdf
    if abs(eta - 1.0) < 1e-4:
        return 0.0, 0.0, 0.0, 0.0
    chi = hx * wix + hy * wiy + hz * wiz
    den = chi + cho / eta
    common = d / woz * abs(cho * chi) / (den * den)
    pdf = (1.0 - pr) * (d * hz * abs(chi) / (den * den) if beck else common / (1.0 + lo))
    v = common / (1.0 + lo + li) / (-wiz)
    return T0 * v, T1 * v, T2 * v, pdf


@njit(cache=True, error_model="numpy")
def dielectric_sample(alpha, eta, refract_only, f00, f01, f02, r0, r1, r2, t0, t1, t2,
                      wox, woy, woz, u1, u2, u3, beck=False):
    """Sample the rough dielectric: (wix, wiy, wiz, w0, w1, w2, pdf, transmitted, ok);
    w = f cos / pdf (RGB), pdf 0 for the smooth (delta) limit, ok False: no direction."""
    if is_singular(alpha, alpha):
        hx, hy, hz = 0.0, 0.0, 1.0
    else:
        hx, hy, hz = sample_normal(beck, alpha, alpha, wox, woy, woz, u1, u2)
    cho = hx * wox + hy * woy + hz * woz
    if beck and cho <= 0.0:  # a Beckmann normal facing away from wo (visible ones never do)
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, False, False
    R0, R1, R2, T0, T1, T2, cos_t = dielectric_fresnel(cho, eta, refract_only, f00, f01, f02,
                                                       r0, r1, r2, t0, t1, t2)
    pr = _pick_reflect(R0, R1, R2, T0, T1, T2)
    if pr < 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, False, False
    if u3 < pr:
        wix, wiy, wiz = 2.0 * cho * hx - wox, 2.0 * cho * hy - woy, 2.0 * cho * hz - woz
        if wiz <= 0.0:
            return wix, wiy, wiz, 0.0, 0.0, 0.0, 0.0, False, False
        if is_singular(alpha, alpha):
            return wix, wiy, wiz, R0 / pr, R1 / pr, R2 / pr, 0.0, False, True
        tr = False
    else:
        # refract -wo about h: wi = -wo / eta + (cos_ho / eta - cos_t) h
        a = cho / eta - cos_t
        wix, wiy, wiz = -wox / eta + a * hx, -woy / eta + a * hy, -woz / eta + a * hz
        wl = np.sqrt(wix * wix + wiy * wiy + wiz * wiz)
        wix, wiy, wiz = wix / wl, wiy / wl, wiz / wl
        if wiz >= 0.0:
            return wix, wiy, wiz, 0.0, 0.0, 0.0, 0.0, True, False
        if is_singular(alpha, alpha):
            q = 1.0 - pr
            return wix, wiy, wiz, T0 / q, T1 / q, T2 / q, 0.0, True, True
        if abs(eta - 1.0) < 1e-4:
            # An index-matched interface does not bend the ray: a delta, as in Cycles.
            q = 1.0 - pr
            return -wox, -woy, -woz, T0 / q, T1 / q, T2 / q, 0.0, True, True
        tr = True
    # The value from the sampled microfacet (as Cycles does): recovering h from the two
    # directions is ill-conditioned when eta is near 1.
    d = ndf(beck, alpha, alpha, hx, hy, hz)
    lo = smith_lambda(beck, alpha, alpha, wox, woy, woz)
    li = smith_lambda(beck, alpha, alpha, wix, wiy, wiz)
    if tr:
        chi = hx * wix + hy * wiy + hz * wiz
        den = chi + cho / eta
        common = d / woz * abs(cho * chi) / (den * den)
        pdf = (1.0 - pr) * (d * hz * abs(chi) / (den * den) if beck else common / (1.0 + lo))
        v0, v1, v2 = T0, T1, T2
    else:
        common = d / woz * 0.25
        pdf = pr * (d * hz * 0.25 / cho if beck else common / (1.0 + lo))
        v0, v1, v2 = R0, R1, R2
    if not pdf > 0.0:
        return wix, wiy, wiz, 0.0, 0.0, 0.0, 0.0, tr, False
    c = common / (1.0 + lo + li) / pdf
    return wix, wiy, wiz, v0 * c, v1 * c, v2 * c, pdf, tr, True


# --- vectorised wrappers for tests -----------------------------------------------------------

@njit(cache=True, error_model="numpy")
def _vec_reflect(ax, ay, wo, u, beck, out):
    for i in range(u.shape[0]):
        wix, wiy, wiz, w, pdf, _ = reflect_sample(ax, ay, wo[0], wo[1], wo[2], u[i, 0], u[i, 1],
                                                  beck)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4] = wix, wiy, wiz, w, pdf


def reflect_samples(ax: float, ay: float, wo, u, beck: bool = False) -> np.ndarray:
    """(N, 5) float64 rows (wi, weight, pdf) of ``reflect_sample`` for uniforms u (N, 2)
    (``beck``: Beckmann)."""
    u = np.ascontiguousarray(u, np.float64)
    out = np.empty((u.shape[0], 5))
    _vec_reflect(float(ax), float(ay), np.asarray(wo, np.float64), u, bool(beck), out)
    return out


@njit(cache=True, error_model="numpy")
def _vec_reflect_pdf(ax, ay, wo, wi, beck, out_f, out_pdf):
    for i in range(wi.shape[0]):
        out_f[i], _ = reflect_eval(ax, ay, wo[0], wo[1], wo[2], wi[i, 0], wi[i, 1], wi[i, 2],
                                   beck)
        out_pdf[i] = reflect_pdf(ax, ay, wo[0], wo[1], wo[2], wi[i, 0], wi[i, 1], wi[i, 2],
                                 beck)


def reflect_values(ax: float, ay: float, wo, wi,
                   beck: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(f, pdf) (N,) float64 of the GGX (``beck``: Beckmann) reflection lobe for
    directions wi (N, 3)."""
    wi = np.ascontiguousarray(wi, np.float64).reshape(-1, 3)
    f = np.empty(wi.shape[0])
    pdf = np.empty(wi.shape[0])
    _vec_reflect_pdf(float(ax), float(ay), np.asarray(wo, np.float64), wi, bool(beck), f, pdf)
    return f, pdf
