"""GGX and Beckmann lobes (core/materials/microfacet.py): the distributions' normalisation,
the samplers against their pdfs (chi-square, several wo and alphas; GGX's anisotropic
visible normals, Beckmann's D cos), Beckmann's Lambda approximation against the exact
erf form."""

import math

import numpy as np
import pytest
from scipy import stats

from core.materials import microfacet


@pytest.mark.parametrize("beck", [False, True])
@pytest.mark.parametrize("ax, ay", [(0.1, 0.1), (0.5, 0.5), (0.2, 0.8)])
def test_projected_ndf_integrates_to_one(ax, ay, beck):
    """int D(h) cos theta_h dh = 1 over the hemisphere (midpoint quadrature)."""
    nt, npp = 600, 120
    ct = (np.arange(nt) + 0.5) / nt
    ph = (np.arange(npp) + 0.5) * 2 * np.pi / npp
    C, P = np.meshgrid(ct, ph, indexing="ij")
    s = np.sqrt(1 - C * C)
    d = np.vectorize(microfacet.ndf)(beck, ax, ay, s * np.cos(P), s * np.sin(P), C)
    integral = np.sum(d * C) * (1 / nt) * (2 * np.pi / npp)
    assert abs(integral - 1) < 0.01, integral


@pytest.mark.parametrize("beck", [False, True])
@pytest.mark.parametrize("ax, ay", [(0.3, 0.3), (0.15, 0.6), (0.7, 0.7)])
@pytest.mark.parametrize("theta", [10.0, 55.0, 80.0])
def test_reflect_sampler_chi2(ax, ay, theta, beck):
    t = np.radians(theta)
    wo = np.array([np.sin(t) * 0.8, np.sin(t) * 0.6, np.cos(t)])
    n = 100_000
    u = np.random.default_rng(int(theta * 100 + ax * 10)).random((n, 2))
    s = microfacet.reflect_samples(ax, ay, wo, u, beck)
    ok = s[:, 3] > 0
    assert np.all(s[ok, 4] > 0)
    d = s[ok, :3]
    nth, nph, sub = 12, 24, 10
    obs, _, _ = np.histogram2d(d[:, 2], np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi),
                               [nth, nph], [[0, 1], [0, 2 * np.pi]])
    cc = (np.arange(nth * sub) + 0.5) / (nth * sub)
    pc = (np.arange(nph * sub) + 0.5) * 2 * np.pi / (nph * sub)
    C, P = np.meshgrid(cc, pc, indexing="ij")
    st = np.sqrt(1 - C * C)
    wi = np.stack([st * np.cos(P), st * np.sin(P), C], -1).reshape(-1, 3)
    _, pdf = microfacet.reflect_values(ax, ay, wo, wi, beck)
    exp = pdf.reshape(nth, sub, nph, sub).sum(axis=(1, 3)) * (1 / (nth * sub)) * \
        (2 * np.pi / (nph * sub)) * n
    o = np.append(obs.ravel(), n - ok.sum())
    e = np.append(exp.ravel(), n - exp.sum())
    small = e < 5
    o = np.append(o[~small], o[small].sum())
    e = np.append(e[~small], e[small].sum())
    assert np.all(o[e <= 0] == 0), "samples where the pdf is 0"
    o, e = o[e > 0], e[e > 0]
    p = stats.chi2.sf(np.sum((o - e) ** 2 / e), len(o) - 1)
    assert p > 0.01, p


@pytest.mark.parametrize("alpha", [0.05, 0.3, 0.8])
def test_beckmann_lambda_approximation_is_the_erf_form(alpha):
    """Cycles' rational Lambda is within 0.5 % of G1 = 1 / (1 + Lambda) with the exact
    Lambda(a) = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)), a = 1 / (alpha tan theta)."""
    for theta in np.radians([20.0, 50.0, 70.0, 80.0, 85.0, 89.0]):
        a = 1.0 / (alpha * np.tan(theta))
        exact = (math.erf(a) - 1.0) / 2.0 + math.exp(-a * a) / (2.0 * a * math.sqrt(math.pi))
        approx = microfacet.beckmann_lambda(alpha, alpha, np.sin(theta), 0.0, np.cos(theta))
        assert abs((1 + exact) / (1 + approx) - 1) < 0.005, (alpha, np.degrees(theta))
