"""Henyey-Greenstein phase function (core/media/phase.py): normalisation, isotropy, the
sampler against the pdf (chi-square), stability as |g| -> 1."""

import math

import numpy as np
import pytest
from scipy import stats
from scipy.integrate import trapezoid

from core.media import phase


@pytest.mark.parametrize("g", [-0.9, -0.3, 0.0, 0.5, 0.95, 0.999])
def test_integrates_to_one_over_the_sphere(g):
    # 2 pi integral of p(cos) dcos by the trapezoid rule on a grid geometric in 1 - cos and
    # in 1 + cos, which resolves both peaks (width (1 - |g|)^2 in cos).
    s = np.geomspace(1e-14, 1.0, 200_001)
    c = np.concatenate([-1 + s, (1 - s)[::-1]])
    total = 2 * math.pi * trapezoid(phase.phase_values(g, c), c)
    assert total == pytest.approx(1.0, rel=1e-6)


def test_g_zero_is_isotropic():
    c = np.linspace(-1, 1, 11)
    np.testing.assert_allclose(phase.phase_values(0.0, c), 1 / (4 * math.pi), rtol=1e-12)


@pytest.mark.parametrize("g", [0.7, -0.4])
def test_forward_and_backward_peaks(g):
    fwd, back = phase.phase_values(g, [1.0, -1.0])
    assert (fwd > back) == (g > 0)
    assert fwd == pytest.approx((1 - g * g) / (4 * math.pi * (1 - g) ** 3))


@pytest.mark.parametrize("g", [-0.8, -0.2, 0.0, 0.3, 0.9, 0.999])
def test_sampler_matches_the_pdf_chi2(g):
    rng = np.random.default_rng(int(abs(g) * 1000) + (g < 0))
    n = 200_000
    d = np.tile([0.3, -0.5, math.sqrt(1 - 0.34)], (n, 1))
    wi, pdf = phase.sample_directions(g, d, rng.random(n), rng.random(n))
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1, atol=1e-9)
    cos = wi @ d[0]
    np.testing.assert_allclose(pdf, phase.phase_values(g, cos), rtol=1e-9)
    # Bins equal in probability under the analytic CDF of cos (exact for HG), plus the
    # azimuth around d, uniform.
    bins = 40
    u_edges = np.linspace(0, 1, bins + 1)
    c_edges = np.sort([phase_cdf_inverse(g, u) for u in u_edges])
    c_edges[0], c_edges[-1] = -1.0 - 1e-12, 1.0 + 1e-12
    observed, _ = np.histogram(cos, c_edges)
    expected = np.full(bins, n / bins)
    assert stats.chisquare(observed, expected).pvalue > 1e-3
    t, b = _frame(d[0])
    phi = np.arctan2(wi @ b, wi @ t)
    assert stats.chisquare(np.histogram(phi, 24, (-math.pi, math.pi))[0]).pvalue > 1e-3


def phase_cdf_inverse(g, u):
    """cos with P(cos' <= cos) = u for HG, by bisection of the closed-form CDF
    F(c) = (1 - g^2) / (2 g) (1 / sqrt(1 + g^2 - 2 g c) - 1 / (1 + g)) (g != 0)."""
    if abs(g) < 1e-12:
        return 2 * u - 1
    def cdf(c):
        return (1 - g * g) / (2 * g) * (1 / math.sqrt(1 + g * g - 2 * g * c) - 1 / (1 + g))
    lo, hi = -1.0, 1.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if cdf(mid) < u else (lo, mid)
    return 0.5 * (lo + hi)


def _frame(d):
    t = np.cross(d, [1.0, 0, 0])
    t /= np.linalg.norm(t)
    return t, np.cross(d, t)


@pytest.mark.parametrize("g", [1.0, -1.0, 0.99999, 1e-9, -1e-9])
def test_extreme_g_is_finite(g):
    rng = np.random.default_rng(3)
    n = 10_000
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    u = np.concatenate([[0.0, 1 - 2**-53], rng.random(n - 2)])
    wi, pdf = phase.sample_directions(g, d, u, rng.random(n))
    assert np.all(np.isfinite(wi)) and np.all(np.isfinite(pdf)) and np.all(pdf > 0)
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1, atol=1e-9)
    values = phase.phase_values(g, np.linspace(-1, 1, 1001))
    assert np.all(np.isfinite(values)) and np.all(values > 0)
    if abs(g) >= 0.999:  # clamped to MAX_ANISOTROPY: nearly all mass in the peak
        assert np.mean(np.sign(g) * wi[:, 2] > 0.9) > 0.95
