"""The material model: a mixture of lobes per material (see ``scene.Materials``).

f = diffuse / pi                                  (Lambert)
  + specular * [mirror delta      if alpha^2 <= 1e-7, alpha = roughness^2
                GGX(alpha)        otherwise]       (Glossy BSDF: no Fresnel, like Cycles)
  + transmission * [F reflection + (1 - F) refraction, smooth dielectric with ``ior``]

Conventions: ``wo`` points from the surface to the viewer, ``wi`` from the surface to the
light; normals are unit and already flipped to the viewer's side of the geometric normal.
Which side is "inside" for the dielectric is decided by the geometric normal (the mesh
winding): a ray with d . n_g < 0 enters, eta = ior; otherwise it leaves, eta = 1 / ior.

Like Cycles for camera paths, refraction does not scale radiance by eta^2 (Cycles'
singular refraction returns weight (1 - F) / pick-probability, ``bsdf_microfacet.h``).

The renderer samples and evaluates materials through their closures
(core/materials/closure.py, which reads these lobes as closures); what is left here are the
dielectric Fresnel and refraction formulas, GGX and their vectorised wrappers for tests,
and ``material_table`` (the per-material arrays the integrators still read: diffuse albedo,
emission, IOR).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)

# Cycles treats a microfacet lobe as a perfect mirror below this alpha_x * alpha_y.
SINGULAR_ALPHA2 = 1e-7


@njit(cache=True, error_model="numpy")
def fresnel_dielectric(cos_i, eta):
    """Exact unpolarised Fresnel reflectance and the refracted cosine.

    cos_i: cosine of incidence in [0, 1]; eta = n_transmitted / n_incident.
    Returns (F, cos_t); total internal reflection gives (1, 0).
    """
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    if sin2_t >= 1.0:
        return 1.0, 0.0
    cos_t = np.sqrt(1.0 - sin2_t)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp), cos_t


@njit(cache=True, error_model="numpy")
def reflect(dx, dy, dz, nx, ny, nz):
    """Mirror a ray direction d about the unit normal n."""
    k = 2.0 * (dx * nx + dy * ny + dz * nz)
    return dx - k * nx, dy - k * ny, dz - k * nz


@njit(cache=True, error_model="numpy")
def refract(dx, dy, dz, nx, ny, nz, eta, cos_i, cos_t):
    """Refract ray direction d through a surface whose unit normal n faces the ray
    (d . n = -cos_i), with eta = n_t / n_i and cos_t from ``fresnel_dielectric``."""
    a = 1.0 / eta
    b = cos_i / eta - cos_t
    return a * dx + b * nx, a * dy + b * ny, a * dz + b * nz


@njit(cache=True, error_model="numpy")
def ggx_lambda(alpha2, cos_t):
    """Smith's Lambda for GGX: G1 = 1 / (1 + Lambda)."""
    c2 = cos_t * cos_t
    tan2 = max(0.0, 1.0 - c2) / c2
    return 0.5 * (np.sqrt(1.0 + alpha2 * tan2) - 1.0)


@njit(cache=True, error_model="numpy")
def ggx_distribution(alpha, cos_h):
    """GGX normal distribution D(h), 1/sr, zero below the surface."""
    if cos_h <= 0.0:
        return 0.0
    a2 = alpha * alpha
    den = 1.0 + (a2 - 1.0) * cos_h * cos_h
    return a2 / (np.pi * den * den)


@njit(cache=True, error_model="numpy")
def ggx_reflection(alpha, cos_o, cos_i, cos_h):
    """GGX microfacet BRDF value (no Fresnel, no tint), height-correlated Smith G like
    Cycles: D / (4 cos_o cos_i (1 + Lambda_o + Lambda_i)). Cosines w.r.t. the normal."""
    if cos_o <= 0.0 or cos_i <= 0.0:
        return 0.0
    a2 = alpha * alpha
    d = ggx_distribution(alpha, cos_h)
    return d / (4.0 * cos_o * cos_i * (1.0 + ggx_lambda(a2, cos_o) + ggx_lambda(a2, cos_i)))


@njit(cache=True, error_model="numpy")
def eval_reflection(diffuse, specular, alpha, nx, ny, nz, wox, woy, woz, wix, wiy, wiz):
    """Non-delta reflection lobes for one point: (diffuse factor, glossy factor).

    Returns scalars kd, ks such that f = diffuse * kd + specular * ks (kd = 1/pi when wi
    is above the surface). The cosine at wi is NOT included.
    """
    cos_i = nx * wix + ny * wiy + nz * wiz
    if cos_i <= 0.0:
        return 0.0, 0.0
    kd = 1.0 / np.pi
    ks = 0.0
    if alpha * alpha > SINGULAR_ALPHA2:
        cos_o = nx * wox + ny * woy + nz * woz
        hx, hy, hz = wox + wix, woy + wiy, woz + wiz
        hl = np.sqrt(hx * hx + hy * hy + hz * hz)
        if hl > 0.0 and cos_o > 0.0:
            cos_h = (nx * hx + ny * hy + nz * hz) / hl
            ks = ggx_reflection(alpha, cos_o, cos_i, cos_h)
    return kd, ks


# --- vectorised wrappers for tests ----------------------------------------------------------

@njit(cache=True, error_model="numpy")
def _vec_fresnel(cos_i, eta, f_out, ct_out):
    for i in range(cos_i.shape[0]):
        f_out[i], ct_out[i] = fresnel_dielectric(cos_i[i], eta[i])


def fresnel(cos_i, eta) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised ``fresnel_dielectric``: (F, cos_t) float64 arrays."""
    c, e = np.broadcast_arrays(np.asarray(cos_i, np.float64), np.asarray(eta, np.float64))
    c = np.ascontiguousarray(c).ravel()
    e = np.ascontiguousarray(e).ravel()
    f = np.empty_like(c)
    ct = np.empty_like(c)
    _vec_fresnel(c, e, f, ct)
    return f, ct


@njit(cache=True, error_model="numpy")
def _vec_refract(d, n, eta, out, tir):
    for i in range(d.shape[0]):
        cos_i = -(d[i, 0] * n[i, 0] + d[i, 1] * n[i, 1] + d[i, 2] * n[i, 2])
        f, cos_t = fresnel_dielectric(cos_i, eta[i])
        tir[i] = f >= 1.0
        out[i, 0], out[i, 1], out[i, 2] = refract(d[i, 0], d[i, 1], d[i, 2], n[i, 0], n[i, 1],
                                                  n[i, 2], eta[i], cos_i, cos_t)


def refract_directions(d, n, eta) -> tuple[np.ndarray, np.ndarray]:
    """Refracted unit directions (N, 3) and a TIR mask (N,), for d . n < 0, eta = n_t/n_i."""
    d = np.ascontiguousarray(d, np.float64).reshape(-1, 3)
    n = np.ascontiguousarray(n, np.float64).reshape(-1, 3)
    eta = np.ascontiguousarray(np.broadcast_to(np.asarray(eta, np.float64), (d.shape[0],)))
    out = np.empty_like(d)
    tir = np.empty(d.shape[0], bool)
    _vec_refract(d, n, eta, out, tir)
    return out, tir


@njit(cache=True, error_model="numpy")
def _vec_ggx(alpha, n, wo, wi, out):
    for i in range(n.shape[0]):
        _, out[i] = eval_reflection(0.0, 0.0, alpha[i], n[i, 0], n[i, 1], n[i, 2], wo[i, 0],
                                    wo[i, 1], wo[i, 2], wi[i, 0], wi[i, 1], wi[i, 2])


def ggx_brdf(alpha, normals, wo, wi) -> np.ndarray:
    """GGX BRDF values (N,) float64 (tint 1, no Fresnel) for unit vectors (N, 3)."""
    n = np.ascontiguousarray(normals, np.float64).reshape(-1, 3)
    a = np.ascontiguousarray(np.broadcast_to(np.asarray(alpha, np.float64), (n.shape[0],)))
    out = np.empty(n.shape[0])
    _vec_ggx(a, n, np.ascontiguousarray(wo, np.float64).reshape(-1, 3),
             np.ascontiguousarray(wi, np.float64).reshape(-1, 3), out)
    return out


@njit(cache=True, error_model="numpy")
def _vec_distribution(alpha, cos_h, out):
    for i in range(cos_h.shape[0]):
        out[i] = ggx_distribution(alpha, cos_h[i])


def ggx_d(alpha: float, cos_h) -> np.ndarray:
    """Vectorised ``ggx_distribution``: D for cosines (N,), 1/sr."""
    c = np.ascontiguousarray(cos_h, np.float64).ravel()
    out = np.empty_like(c)
    _vec_distribution(float(alpha), c, out)
    return out


def material_table(materials) -> dict[str, np.ndarray]:
    """float64 copies of the lobe arrays the kernels read, plus alpha = roughness^2."""
    r = materials.roughness.astype(np.float64)
    return {
        "diffuse": materials.diffuse.astype(np.float64).reshape(-1, 3),
        "specular": materials.specular.astype(np.float64).reshape(-1, 3),
        "transmission": materials.transmission.astype(np.float64).reshape(-1, 3),
        "alpha": np.minimum(r, 1.0) ** 2,
        "ior": materials.ior.astype(np.float64),
        "emission": materials.emission.astype(np.float64).reshape(-1, 3),
    }
