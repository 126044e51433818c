"""Fresnel terms (core/materials/fresnel.py) against closed forms."""

import numpy as np
import pytest

from core.materials import fresnel


@pytest.mark.parametrize("f0, tint", [(0.9, 1.0), (0.5, 0.3), (0.04, 0.8), (1.0, 0.5)])
def test_f82_tint_is_schlick_times_tint_at_82_degrees(f0, tint):
    cos82 = 1.0 / 7.0
    schlick = f0 + (1 - f0) * (1 - cos82) ** 5
    got = fresnel.f82_curve([cos82, 1.0, 0.0], f0, tint)
    np.testing.assert_allclose(got[0], min(schlick * tint, 1.0), rtol=1e-9)
    np.testing.assert_allclose(got[1], f0, rtol=1e-12)     # normal incidence: F0
    np.testing.assert_allclose(got[2], 1.0, rtol=1e-12)    # grazing: 1


def test_f82_tint_one_is_schlick():
    c = np.linspace(0, 1, 101)
    np.testing.assert_allclose(fresnel.f82_curve(c, 0.3, 1.0), 0.3 + 0.7 * (1 - c) ** 5,
                               rtol=1e-12)


@pytest.mark.parametrize("f0, tint", [(0.9, 1.0), (0.5, 0.3), (0.95, 0.7)])
def test_f82_fss_is_the_cosine_weighted_average(f0, tint):
    c = (np.arange(200_000) + 0.5) / 200_000
    avg = 2 * np.mean(fresnel.f82_curve(c, f0, tint) * c)
    assert abs(fresnel.f82_fss(f0, fresnel.f82_b(f0, tint)) - avg) < 1e-6


@pytest.mark.parametrize("n, k", [(0.2, 3.0), (1.5, 0.0), (2.757, 3.867)])
def test_conductor_at_normal_incidence(n, k):
    ref = ((n - 1) ** 2 + k * k) / ((n + 1) ** 2 + k * k)
    np.testing.assert_allclose(fresnel.conductor_curve([1.0], n, k), ref, rtol=1e-12)


def test_conductor_with_k_zero_is_the_dielectric():
    from core.materials import bsdf
    c = np.linspace(0.05, 1, 50)
    f, _ = bsdf.fresnel(c, 1.6)
    np.testing.assert_allclose(fresnel.conductor_curve(c, 1.6, 0.0), f, rtol=1e-9)


def test_specular_ior_level_round_trip():
    """F0 -> IOR -> F0 (Specular IOR Level rescales F0 through these)."""
    for ior in (1.1, 1.45, 2.0):
        f0 = fresnel.f0_from_ior(ior)
        assert abs(fresnel.ior_from_f0(f0) - ior) < 1e-12


def test_dielectric_fss_fit_is_close_to_the_average():
    from core.materials import bsdf
    c = (np.arange(100_000) + 0.5) / 100_000
    for eta in (1.33, 1.5, 2.0):
        f, _ = bsdf.fresnel(c, eta)
        assert abs(fresnel.dielectric_fss(eta) - 2 * np.mean(f * c)) < 0.006  # Cycles' fit
