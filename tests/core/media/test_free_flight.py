"""Homogeneous transmittance and spectral free-flight sampling (core/media/free_flight.py)."""

import math

import numpy as np
from scipy import stats

from core.media import free_flight

SIGMA_A = np.array([0.2, 0.5, 1.5])
SIGMA_S = np.array([1.0, 0.6, 0.1])
SIGMA_T = SIGMA_A + SIGMA_S


def test_transmittance_is_exp_minus_sigma_t_d():
    for d in (0.0, 0.37, 2.5):
        got = free_flight.transmittance(*SIGMA_T, d)
        np.testing.assert_allclose(got, np.exp(-SIGMA_T * d), rtol=1e-15)


def _flights(n, t_max, seed=1):
    rng = np.random.default_rng(seed)
    return free_flight.sample_distances(SIGMA_A, SIGMA_S, t_max, rng.random(n), rng.random(n))


def test_distances_follow_the_mean_channel_pdf_chi2():
    t_max = 1.7
    t, scattered, _ = _flights(200_000, t_max)
    assert np.all(t[~scattered] == t_max) and np.all(t[scattered] < t_max)
    edges = np.linspace(0, t_max, 33)
    # Expected counts: integral of the pdf over each bin (closed form), the rest passes.
    cdf = 1 - np.mean(np.exp(-np.outer(edges, SIGMA_T)), axis=1)
    expected = np.append(np.diff(cdf), 1 - cdf[-1]) * t.size
    observed = np.append(np.histogram(t[scattered], edges)[0], np.sum(~scattered))
    assert stats.chisquare(observed, expected).pvalue > 1e-3
    np.testing.assert_allclose(free_flight.pass_probability(*SIGMA_T, t_max), 1 - cdf[-1])


def test_weights_are_unbiased_per_channel():
    t_max = 1.3
    n = 400_000
    t, scattered, w = _flights(n, t_max, seed=2)
    # Passing: E[w 1{pass}] = exp(-sigma_t t_max) in every channel.
    passing = np.where(~scattered[:, None], w, 0).mean(axis=0)
    np.testing.assert_allclose(passing, np.exp(-SIGMA_T * t_max), rtol=0.01)
    # Scattering with f(t) = cos(t): E[w f 1{scatter}] = integral of sigma_s e^{-sigma_t t} cos t.
    f = np.cos(t)
    got = np.where(scattered[:, None], w * f[:, None], 0).mean(axis=0)
    s = SIGMA_T
    want = SIGMA_S * (s + np.exp(-s * t_max) * (np.sin(t_max) - s * np.cos(t_max))) / (s * s + 1)
    np.testing.assert_allclose(got, want, rtol=0.01)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)


def test_a_clear_channel_passes_and_an_empty_medium_never_scatters():
    t, scattered, w = free_flight.sample_distances([0, 0, 0], [0, 0, 0], math.inf,
                                                  [0.1, 0.5, 0.9], [0.3, 0.6, 0.99])
    assert not scattered.any() and np.all(w == 1) and np.all(t == math.inf)
    # Channel 1 clear, others dense, infinite segment: only channel 1 can pass.
    t, scattered, w = free_flight.sample_distances([1, 0, 1], [1, 0, 1], math.inf,
                                                  np.full(3000, 0.5), np.linspace(0, 0.999, 3000))
    assert not scattered.any() and np.all(w == [0, 1, 0])
    t, scattered, w = free_flight.sample_distances([1, 0, 1], [1, 0, 1], math.inf,
                                                  np.full(3000, 0.1), np.linspace(0, 0.999, 3000))
    assert scattered.all() and np.all(np.isfinite(w)) and np.all(w[:, 1] == 0)
