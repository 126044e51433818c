"""Equiangular sampling towards a point light (core/media/equiangular.py): the sampler
against its pdf (chi-square), the pdf's normalisation."""


import numpy as np
import pytest
from scipy import stats

from core.media import equiangular

CASES = [  # origin, direction, light, t0, t1
    ((0, 0, 0), (1, 0, 0), (2.0, 0.3, 0.0), 0.0, 5.0),     # light beside the middle
    ((0, 0, 0), (0, 0, 1), (0.5, -0.2, -1.0), 0.5, 3.0),   # light behind the segment
    ((1, 1, 1), (0, 1, 0), (1.0, 8.0, 1.01), 0.0, 4.0),    # light beyond the end, close
]


@pytest.mark.parametrize("origin, direction, light, t0, t1", CASES)
def test_sampler_matches_the_pdf_chi2(origin, direction, light, t0, t1):
    rng = np.random.default_rng(7)
    n = 200_000
    t, pdf = equiangular.sample_segment(origin, direction, light, t0, t1, rng.random(n))
    assert np.all((t >= t0 - 1e-12) & (t <= t1 + 1e-12))
    np.testing.assert_allclose(pdf, equiangular.segment_pdf(origin, direction, light, t0, t1, t),
                               rtol=1e-12)
    edges = np.linspace(t0, t1, 41)
    # Expected bin probabilities: the pdf integrated by a fine trapezoid (not the sampler's
    # inverse CDF, so the test checks the sampling formula against the density).
    fine = np.linspace(t0, t1, 400_001)
    dens = equiangular.segment_pdf(origin, direction, light, t0, t1, fine)
    cdf = np.concatenate([[0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(fine))])
    assert cdf[-1] == pytest.approx(1.0, rel=1e-6)
    expected = np.diff(np.interp(edges, fine, cdf)) * n
    observed = np.histogram(t, edges)[0]
    assert stats.chisquare(observed, expected * n / expected.sum()).pvalue > 1e-3


def test_light_on_the_line_stays_finite():
    t, pdf = equiangular.sample_segment((0, 0, 0), (1, 0, 0), (-1.0, 0, 0), 0.0, 2.0,
                                        np.linspace(0, 0.999, 100))
    assert np.all(np.isfinite(t)) and np.all(np.isfinite(pdf)) and np.all(pdf >= 0)
