"""Fresnel, refraction, GGX and the delta-lobe sampler against independent formulas."""

import numpy as np
import pytest

from core import sampling
from core.materials import bsdf, closure
from core.scene.contract import Materials


@pytest.mark.parametrize("n", [1.33, 1.5, 2.4])
def test_fresnel_at_normal_incidence(n):
    f, cos_t = bsdf.fresnel([1.0, 1.0], [n, 1.0 / n])
    np.testing.assert_allclose(f, ((n - 1) / (n + 1)) ** 2, rtol=1e-12)
    np.testing.assert_allclose(cos_t, 1.0)


def test_fresnel_matches_the_closed_form_of_cycles():
    """Cycles' fresnel_dielectric_cos: g = sqrt(eta^2 - 1 + c^2), a different algebra."""
    c = np.linspace(0.01, 1.0, 200)
    for eta in (1.2, 1.5, 1.9):
        g = np.sqrt(eta * eta - 1 + c * c)
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1) / (c * (g - c) + 1)
        ref = 0.5 * a * a * (1 + b * b)
        f, _ = bsdf.fresnel(c, eta)
        np.testing.assert_allclose(f, ref, rtol=1e-10)


def test_reflected_plus_transmitted_power_is_one():
    """Energy: F + T = 1 with T from the Fresnel transmission amplitudes."""
    c = np.linspace(0.02, 1.0, 100)
    for eta in (1.5, 1 / 1.5):
        f, ct = bsdf.fresnel(c, eta)
        ok = f < 1
        ci, ct = c[ok], ct[ok]
        ts = 2 * ci / (ci + eta * ct)
        tp = 2 * ci / (eta * ci + ct)
        t = eta * ct / ci * 0.5 * (ts * ts + tp * tp)
        np.testing.assert_allclose(f[ok] + t, 1.0, rtol=1e-12)


def test_total_internal_reflection_beyond_the_critical_angle():
    n = 1.5
    crit = np.arcsin(1 / n)
    f, ct = bsdf.fresnel(np.cos([crit + 1e-3, crit + 0.3, crit - 1e-3]), 1 / n)
    assert f[0] == 1 and f[1] == 1 and ct[0] == 0
    assert f[2] < 1


def test_brewster_angle_has_no_p_reflection():
    n = 1.5
    c = np.cos(np.arctan(n))
    f, ct = bsdf.fresnel([c], n)
    rs = (c - n * ct[0]) / (c + n * ct[0])
    assert f[0] == pytest.approx(0.5 * rs * rs, rel=1e-12)


def test_refraction_obeys_snell_and_stays_in_the_plane(rng):
    n = np.tile([0.0, 0.0, 1.0], (500, 1))
    d = rng.normal(size=(500, 3))
    d[:, 2] = -np.abs(d[:, 2]) - 0.05
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for eta in (1.5, 1 / 1.5):
        t, tir = bsdf.refract_directions(d, n, eta)
        ok = ~tir
        np.testing.assert_allclose(np.linalg.norm(t[ok], axis=1), 1.0, rtol=1e-12)
        sin_i = np.linalg.norm(d[ok, :2], axis=1)
        sin_t = np.linalg.norm(t[ok, :2], axis=1)
        np.testing.assert_allclose(sin_t, sin_i / eta, rtol=1e-9, atol=1e-12)
        assert np.all(t[ok, 2] < 0)
        # Tangential components keep their direction.
        # The z component of the cross product (numpy 2 dropped np.cross of 2-vectors).
        a, b = d[ok, :2], t[ok, :2]
        np.testing.assert_allclose(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], 0.0, atol=1e-12)
        assert np.any(tir) == (eta < 1)


def _hemisphere(n):
    idx = np.arange(n)
    u1 = sampling.uniform(5, idx, np.zeros(n, np.int64), 0)
    u2 = sampling.uniform(5, idx, np.zeros(n, np.int64), 1)
    return sampling.sample_cosine_hemisphere(u1, u2)  # pdf = cos / pi


def test_ggx_is_reciprocal_and_loses_energy_only_with_roughness():
    wi = _hemisphere(100_000)
    n = np.tile([0, 0, 1.0], (wi.shape[0], 1))
    wo = np.tile([np.sin(0.3), 0, np.cos(0.3)], (wi.shape[0], 1))
    albedo = []
    for alpha in (0.1, 0.3, 0.6):
        f = bsdf.ggx_brdf(alpha, n, wo, wi)
        np.testing.assert_allclose(f, bsdf.ggx_brdf(alpha, n, wi, wo), rtol=1e-12)
        albedo.append(np.mean(f * np.pi))  # integral of f cos, pdf = cos / pi
    # Single scattering: below 1, and more is lost (to multiple scattering) when rougher.
    assert 1.0 > albedo[0] > albedo[1] > albedo[2] > 0.4


def _sphere_quadrature(n_theta=1200, n_phi=600):
    th = (np.arange(n_theta) + 0.5) * np.pi / n_theta
    ph = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    t, p = np.meshgrid(th, ph, indexing="ij")
    w = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    dw = (np.pi / n_theta) * (2 * np.pi / n_phi) * np.sin(t).ravel()
    return w, dw


@pytest.mark.parametrize("alpha", [0.2, 0.5, 0.9])
def test_ggx_weak_white_furnace(alpha):
    """Heitz's weak furnace: over ALL wi, D(h) G1(wo) / (4 cos_o) integrates to 1.

    It checks D's normalisation and that Lambda is Smith's for this D."""
    from core.materials.bsdf import ggx_lambda
    wi, dw = _sphere_quadrature()
    for theta_o in (0.0, 0.6, 1.2):
        wo = np.array([np.sin(theta_o), 0.0, np.cos(theta_o)])
        h = wi + wo
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        d = bsdf.ggx_d(alpha, h[:, 2])
        g1 = 1.0 / (1.0 + ggx_lambda(alpha * alpha, wo[2]))
        total = np.sum(d * g1 / (4 * wo[2]) * dw)
        assert total == pytest.approx(1.0, rel=0.01), (alpha, theta_o)


def test_ggx_distribution_is_normalised():
    """D(h) cos(h) integrates to its closed-form cumulative (checked through the BRDF)."""
    wi = _hemisphere(200_000)
    n = np.tile([0, 0, 1.0], (wi.shape[0], 1))
    alpha = 0.3
    f = bsdf.ggx_brdf(alpha, n, n, wi)
    h = (wi + n)
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    # f = D G / (4 cos_o cos_i); with cos_o = 1, G = 1 / (1 + Lambda_i).
    a2 = alpha ** 2
    ci = wi[:, 2]
    lam = 0.5 * (np.sqrt(1 + a2 * (1 - ci ** 2) / ci ** 2) - 1)
    d = 4 * ci * f * (1 + lam)
    # D(h) cos(h) dw_h, with dw_h = dw_i / (4 (h . wi)) and pdf(wi) = cos_i / pi.
    est = np.mean(d * h[:, 2] / (4 * np.sum(h * wi, axis=1)) * np.pi / ci)
    # With wo = n the half vectors only reach 45 degrees, where GGX's cumulative
    # distribution of D cos is tan^2 / (alpha^2 + tan^2) = 1 / (1 + alpha^2).
    assert est == pytest.approx(1.0 / (1.0 + alpha ** 2), rel=0.01)


def _delta(spec, alpha, trans, ior, d, n, entering, u_lobe, u_pick):
    """closure.sample_delta (the camera paths' and gather rays' delta sampler) on a
    material of legacy lobes (specular tint and roughness alpha, transmission tint, ior),
    in the old sampler's return order: (ox, oy, oz, w0, w1, w2, transmitted, ok)."""
    mats = Materials.from_list([{"diffuse": [0, 0, 0], "specular": list(spec),
                                 "roughness": float(np.sqrt(alpha)),
                                 "transmission": list(trans), "ior": ior}])
    tab = closure.table(mats)
    ox, oy, oz, w0, w1, w2, _, flags = closure.sample_delta(
        tab, 0, 1.0, 1.0, 1.0, -d[0], -d[1], -d[2], *n, *n, 1.0, 0.0, 0.0, entering,
        u_lobe, u_pick, u_pick)
    return (ox, oy, oz, w0, w1, w2, bool(flags & closure.LOBE_TRANSMIT),
            flags & closure.LOBE_DELTA != 0)


def test_mirror_reflects_with_its_tint():
    d = np.array([1.0, 0.0, -1.0]) / np.sqrt(2)
    ox, oy, oz, w0, w1, w2, tr, ok = _delta((0.9, 0.5, 0.1), 0.0, (0, 0, 0), 1.5, d, (0, 0, 1.0), True, 0.3, 0.3)
    assert ok and not tr
    np.testing.assert_allclose([ox, oy, oz], [d[0], d[1], -d[2]])
    np.testing.assert_allclose([w0, w1, w2], [0.9, 0.5, 0.1], rtol=1e-6)
    # A rough specular lobe is not a delta lobe: nothing to follow.
    assert not _delta((0.9, 0.5, 0.1), 0.3, (0, 0, 0), 1.5, d, (0, 0, 1.0), True, 0.3, 0.3)[-1]


@pytest.mark.parametrize("cos_i,entering", [(1.0, True), (0.3, True), (0.9, False)])
def test_glass_pick_is_unbiased(cos_i, entering):
    """Averaging the weights over the pick gives F reflected and (1 - F) refracted."""
    sin_i = np.sqrt(1 - cos_i ** 2)
    d = np.array([sin_i, 0.0, -cos_i])
    eta = 1.5 if entering else 1 / 1.5
    f_exact = bsdf.fresnel([cos_i], [eta])[0][0]
    refl = refr = 0.0
    m = 4000
    for u in (np.arange(m) + 0.5) / m:
        ox, oy, oz, w0, _, _, tr, ok = _delta((0, 0, 0), 0.0, (1, 1, 1), 1.5, d, (0, 0, 1.0), entering, u, u)
        assert ok
        if tr:
            refr += w0 / m
            assert oz < 0
        else:
            refl += w0 / m
            np.testing.assert_allclose([ox, oy, oz], [d[0], 0, cos_i], atol=1e-12)
    # The closures pick reflection with probability F (weight 1): over m stratified u the
    # estimate is exact to the stratum width 1 / m.
    assert refl == pytest.approx(f_exact, rel=1e-3, abs=1.0 / m)
    assert refr == pytest.approx(1 - f_exact, rel=1e-3, abs=1.0 / m)


def test_glass_total_internal_reflection_always_reflects():
    d = np.array([np.sin(1.0), 0.0, -np.cos(1.0)])  # 57 degrees, beyond 41.8 from inside
    for u in (0.01, 0.5, 0.99):
        out = _delta((0, 0, 0), 0.0, (1, 1, 1), 1.5, d, (0, 0, 1.0), False, u, u)
        assert out[-1] and not out[-2] and out[3] == pytest.approx(1.0)