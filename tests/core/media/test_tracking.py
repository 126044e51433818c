"""Ratio and spectral delta tracking through a varying density (core/media/tracking.py)
against the analytic optical depth of rho(x) = (1 + sin(k x)) / 2."""

import numpy as np
import pytest
from numba import njit
from scipy.integrate import trapezoid

from core.media import tracking


K = 3.0
SIGMA_A = np.array([0.3, 1.0, 0.0])
SIGMA_S = np.array([0.9, 0.4, 2.0])
SIGMA_T = SIGMA_A + SIGMA_S
N = 100_000


@njit
def wave(x, y, z):
    return 0.5 * (1.0 + np.sin(K * x))


@njit
def too_dense(x, y, z):
    return 2.0


def tau(t, sigma):
    """Optical depth from x = 0 to x = t along +x: sigma * integral of rho."""
    return np.multiply.outer(0.5 * (t + (1 - np.cos(K * t)) / K), sigma)


def _rays(t_max):
    return np.zeros((N, 3)), np.tile([1.0, 0.0, 0.0], (N, 1)), np.full(N, t_max)


def _assert_mean(samples, want):
    mean = samples.mean(axis=0)
    se = samples.std(axis=0) / np.sqrt(samples.shape[0])
    assert np.all(np.abs(mean - want) <= 4 * se + 1e-12), (mean, want, se)


@pytest.mark.parametrize("majorant", [1.0, 3.0])
def test_ratio_tracking_estimates_exp_minus_tau(majorant):
    o, d, t_max = _rays(1.6)
    out = tracking.ratio_tracking_rays(wave, o, d, t_max, SIGMA_T, majorant, 11)
    assert np.all(out >= 0) and np.all(out <= 1)
    _assert_mean(out, np.exp(-tau(1.6, SIGMA_T)))


def test_delta_tracking_passes_and_scatters_as_the_analytic_medium():
    t_len = 1.2
    o, d, t_max = _rays(t_len)
    t, scattered, w = tracking.delta_tracking_rays(wave, o, d, t_max, SIGMA_A, SIGMA_S, 1.0, 5)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    assert np.all(t[~scattered] == t_len) and np.all(t[scattered] < t_len)
    # Passing: E[w 1{pass}] = exp(-tau(t_max)).
    _assert_mean(np.where(~scattered[:, None], w, 0), np.exp(-tau(t_len, SIGMA_T)))
    # Scattering, f(t) = t: integral of sigma_s rho(t) exp(-tau(t)) t dt (fine trapezoid).
    s = np.linspace(0, t_len, 200_001)
    rho = 0.5 * (1 + np.sin(K * s))
    want = trapezoid((rho * s)[:, None] * SIGMA_S * np.exp(-tau(s, SIGMA_T)), s, axis=0)
    _assert_mean(np.where(scattered[:, None], w * t[:, None], 0), want)


def test_a_density_above_the_majorant_raises():
    o, d, t_max = _rays(1.0)
    with pytest.raises(ValueError, match="ray 0 met a density outside"):
        tracking.ratio_tracking_rays(too_dense, o[:10], d[:10], t_max[:10], SIGMA_T, 1.0, 1)
    with pytest.raises(ValueError, match="delta tracking of ray 0"):
        tracking.delta_tracking_rays(too_dense, o[:10], d[:10], 1.0, SIGMA_A, SIGMA_S, 1.0, 1)
