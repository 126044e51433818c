"""Wavelength sampling and the conversion back to Rec.709 RGB (core/spectral.py)."""

import numpy as np
import pytest
from scipy import stats

from core import spectral

# CIE 1931 2-degree observer, tabulated (CIE 015:2004): (nm, x, y, z).
CIE_1931 = [(450, 0.3362, 0.0380, 1.7721), (500, 0.0049, 0.3230, 0.2720),
            (550, 0.4334, 0.9950, 0.0087), (600, 1.0622, 0.6310, 0.0008),
            (650, 0.2835, 0.1070, 0.0000)]


def test_matching_functions_follow_the_cie_table():
    table = np.array(CIE_1931)
    got = spectral.cie_xyz(table[:, 0])
    # Wyman et al. quote the multi-lobe fit within a few hundredths of the table.
    np.testing.assert_allclose(got, table[:, 1:], atol=0.03)


def test_d65_white_is_rgb_one():
    d65 = np.array([0.95047, 1.0, 1.08883])
    np.testing.assert_allclose(spectral.XYZ_TO_REC709 @ d65, 1.0, atol=1e-4)


def test_white_integrates_to_exactly_one():
    # The tabulated basis: each channel's integral is 1 (float rounding).
    np.testing.assert_allclose(spectral.BASIS.sum(axis=0) * spectral.BIN_WIDTH, 1.0,
                               rtol=1e-12)
    assert np.all(spectral.BASIS >= 0)


def test_white_monte_carlo_integral_is_one_within_one_percent():
    u = np.random.default_rng(5).random(400_000)
    lam, pdf, w = spectral.sample_wavelengths(u)
    assert np.all((lam >= spectral.LAMBDA_MIN) & (lam <= spectral.LAMBDA_MAX))
    assert np.all(pdf > 0) and np.all((w >= 0) & (w <= 3)) and np.all(np.isfinite(w))
    np.testing.assert_allclose(w.mean(axis=0), 1.0, rtol=0.01)
    # The weight is the basis over the pdf at the sampled wavelength.
    np.testing.assert_allclose(w, spectral.basis_at(lam) / pdf[:, None], rtol=1e-12)


def test_sampled_wavelengths_follow_the_pdf():
    u = np.random.default_rng(6).random(200_000)
    lam, pdf, _ = spectral.sample_wavelengths(u)
    edges = np.linspace(spectral.LAMBDA_MIN, spectral.LAMBDA_MAX, 21)
    observed = np.histogram(lam, edges)[0] / lam.size
    per_bin = spectral.BASIS.sum(axis=1) / 3 * spectral.BIN_WIDTH
    expected = per_bin.reshape(20, -1).sum(axis=1)
    np.testing.assert_allclose(observed, expected, atol=4e-3)


@pytest.mark.parametrize("nm, channel", [(450, 2), (540, 1), (620, 0)])
def test_a_wavelength_has_its_hue(nm, channel):
    w = spectral.basis_at([nm])[0]
    assert np.argmax(w) == channel


def test_wavelength_sampling_passes_chi_square_against_its_pdf():
    # Pearson's chi-square over 40 bins of 10 nm (Mitsuba's chi2 test: the sampler against
    # the integral of its own pdf), significance 1 %.
    n = 200_000
    lam, pdf, _ = spectral.sample_wavelengths(np.random.default_rng(11).random(n))
    observed = np.histogram(lam, np.linspace(spectral.LAMBDA_MIN, spectral.LAMBDA_MAX, 41))[0]
    expected = n * (spectral.BASIS.sum(axis=1) / 3 * spectral.BIN_WIDTH).reshape(40, -1).sum(axis=1)
    # Cells expected to hold fewer than 5 samples (the far red) pool into one, as Mitsuba's
    # chi2 test does, so the statistic is chi-square distributed.
    low = expected < 5
    observed = np.append(observed[~low], observed[low].sum())
    expected = np.append(expected[~low], expected[low].sum())
    assert expected[-1] >= 5 and observed.size > 30
    chi2 = np.sum((observed - expected) ** 2 / expected)
    assert stats.chi2.sf(chi2, df=observed.size - 1) > 0.01, chi2
    # And the pdf returned is the density sampled from: its integral over each bin.
    np.testing.assert_allclose(pdf, spectral.BASIS.sum(axis=1)[
        np.minimum(((lam - spectral.LAMBDA_MIN) / spectral.BIN_WIDTH).astype(int),
                   spectral.BINS - 1)] / 3, rtol=1e-12)
