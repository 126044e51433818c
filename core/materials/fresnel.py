"""Fresnel terms of the microfacet lobes, as Cycles 4.x/5.x defines them (bsdf_util.h).

- dielectric: the exact unpolarised reflectance (``bsdf.fresnel_dielectric``, reused);
- generalized Schlick in Cycles' "real curve" form (exponent < 0, used by Principled's
  specular layer and transmission and by the Glass BSDF): F = mix(F0, F90, s) with
  s = (F_real - F0_real) / (1 - F0_real), F0 = F0_from_ior(ior) * tint;
- F82 tint (Kutz et al., "Novel aspects of the Adobe Standard Material"): Schlick minus
  b cos (1 - cos)^6, b chosen so that F at cos = 1/7 is Schlick's times the tint;
- conductor: the exact reflectance of a complex IOR n + ik per channel;
- the hemispherical averages Fss that multiscatter GGX uses (``albedo_tables``).

Cosines are between the microfacet normal and the viewer direction, in [0, 1]; eta is
n_far / n_near. Every function returns reflectances in [0, 1].
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from .bsdf import fresnel_dielectric

# acos(1/7) ~ 81.8 deg: where F82's extra term peaks (its name).
_F82_COS = 1.0 / 7.0


@njit(cache=True, error_model="numpy")
def f0_from_ior(ior):
    """Reflectance at normal incidence of a dielectric of relative IOR ``ior``."""
    r = (ior - 1.0) / (ior + 1.0)
    return r * r


@njit(cache=True, error_model="numpy")
def ior_from_f0(f0):
    """The IOR (>= 1) whose normal reflectance is f0 (clamped to [0, 0.99], like Cycles)."""
    s = np.sqrt(min(max(f0, 0.0), 0.99))
    return (1.0 + s) / (1.0 - s)


@njit(cache=True, error_model="numpy")
def schlick_real(cos_i, eta):
    """The interpolation factor s in [0, 1] of Cycles' generalized Schlick with exponent < 0:
    F = mix(F0, 1, s), s = (F_real(cos_i, eta) - F0_real) / (1 - F0_real). Returns (s, cos_t,
    F_real); cos_t = 0 under total internal reflection."""
    f, cos_t = fresnel_dielectric(min(max(cos_i, 0.0), 1.0), eta)
    f0 = f0_from_ior(eta)
    if f0 >= 1.0:
        return 1.0, cos_t, f
    s = (f - f0) / (1.0 - f0)
    return min(max(s, 0.0), 1.0), cos_t, f


@njit(cache=True, error_model="numpy")
def f82_b(f0, tint):
    """F82-tint's b for one channel: F(1/7) = Schlick(1/7) * tint."""
    f = 6.0 / 7.0
    f5 = f * f * f * f * f
    schlick = f0 + (1.0 - f0) * f5
    return schlick * (7.0 / (f5 * f)) * (1.0 - tint)


@njit(cache=True, error_model="numpy")
def f82(cos_i, f0, b):
    """F82-tint reflectance for one channel."""
    s = min(max(1.0 - cos_i, 0.0), 1.0)
    s5 = s * s * s * s * s
    return min(max(f0 + (1.0 - f0) * s5 - b * cos_i * s5 * s, 0.0), 1.0)


@njit(cache=True, error_model="numpy")
def f82_fss(f0, b):
    """Cosine-weighted hemispherical average of ``f82`` (analytic: 2 int F mu dmu)."""
    return f0 + (1.0 - f0) / 21.0 - b / 126.0


@njit(cache=True, error_model="numpy")
def conductor(cos_i, n, k):
    """Exact unpolarised reflectance of a conductor n + ik seen from a medium of IOR 1."""
    c2 = cos_i * cos_i
    t1 = n * n - k * k - (1.0 - c2)
    t2 = np.sqrt(t1 * t1 + 4.0 * n * n * k * k)
    u2 = max(0.5 * (t2 + t1), 0.0)
    v2 = max(0.5 * (t2 - t1), 0.0)
    u = np.sqrt(u2)
    v = np.sqrt(v2)
    den_s = (cos_i + u) ** 2 + v2
    rs = ((cos_i - u) ** 2 + v2) / den_s if den_s > 0.0 else 1.0
    t3 = (n * n - k * k) * cos_i
    t4 = 2.0 * n * k * cos_i
    den_p = (t3 + u) ** 2 + (t4 + v) ** 2
    rp = ((t3 - u) ** 2 + (t4 - v) ** 2) / den_p if den_p > 0.0 else 1.0
    return 0.5 * (rs + rp)


@njit(cache=True, error_model="numpy")
def conductor_fss(n, k):
    """Cycles' estimate of a conductor's average Fresnel: fit F82 through F(1) and F(1/7)."""
    f0 = conductor(1.0, n, k)
    f82v = conductor(_F82_COS, n, k)
    f = 6.0 / 7.0
    f5 = f * f * f * f * f
    b = (7.0 / (f5 * f)) * (f0 + (1.0 - f0) * f5 - f82v)
    return min(max(f82_fss(f0, b), 0.0), 1.0)


@njit(cache=True, error_model="numpy")
def dielectric_fss(eta):
    """Cycles' fit of a dielectric's average Fresnel reflectance (2 int F mu dmu)."""
    if eta < 1.0:
        return 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607))
    return (eta - 1.0) / (4.08567 + 1.00071 * eta)


# --- vectorised wrappers for tests -----------------------------------------------------------

@njit(cache=True, error_model="numpy")
def _vec_f82(cos_i, f0, tint, out):
    for i in range(cos_i.shape[0]):
        out[i] = f82(cos_i[i], f0, f82_b(f0, tint))


def f82_curve(cos_i, f0: float, tint: float) -> np.ndarray:
    """F82-tint reflectance (N,) float64 for cosines (N,) and one channel's F0 and tint."""
    c = np.ascontiguousarray(cos_i, np.float64).ravel()
    out = np.empty_like(c)
    _vec_f82(c, float(f0), float(tint), out)
    return out


@njit(cache=True, error_model="numpy")
def _vec_conductor(cos_i, n, k, out):
    for i in range(cos_i.shape[0]):
        out[i] = conductor(cos_i[i], n, k)


def conductor_curve(cos_i, n: float, k: float) -> np.ndarray:
    """Conductor reflectance (N,) float64 for cosines (N,)."""
    c = np.ascontiguousarray(cos_i, np.float64).ravel()
    out = np.empty_like(c)
    _vec_conductor(c, float(n), float(k), out)
    return out
