"""The closure evaluator's interface over the legacy lobes (``bsdf.eval_bsdf`` /
``sample_bsdf`` / ``albedo``, what the light transport calls until closure.py's lobes land):
the GGX visible-normal sampler against its pdf (chi-square, Mitsuba's habit), sampled weights
against the integral of eval, the flags, and the constants shared with closure.py."""

import numpy as np
import pytest
from numba import njit
from scipy import stats

from core.materials import bsdf, closure
from core.scene import closures as cl
from core.scene.contract import Materials


def _table(rows):
    return closure.table(Materials.from_list(rows))


@njit(cache=False)
def _sample_many(tab, m, wo, u, out_dir, out_w, out_pdf, out_flags):
    for i in range(u.shape[0]):
        ix, iy, iz, w0, w1, w2, pdf, flags = bsdf.sample_bsdf(
            tab, m, 1.0, 1.0, 1.0, wo[0], wo[1], wo[2], 0.0, 0.0, 1.0, 0.0, 0.0, 1.0,
            1.0, 0.0, 0.0, True, u[i, 0], u[i, 1], u[i, 2])
        out_dir[i, 0], out_dir[i, 1], out_dir[i, 2] = ix, iy, iz
        out_w[i, 0], out_w[i, 1], out_w[i, 2] = w0, w1, w2
        out_pdf[i] = pdf
        out_flags[i] = flags


@njit(cache=False)
def _eval_many(tab, m, wo, wi, out_f, out_pdf):
    for i in range(wi.shape[0]):
        f0, f1, f2, pdf = bsdf.eval_bsdf(tab, m, 1.0, 1.0, 1.0, wo[0], wo[1], wo[2],
                                         wi[i, 0], wi[i, 1], wi[i, 2], 0.0, 0.0, 1.0,
                                         0.0, 0.0, 1.0, 1.0, 0.0, 0.0)
        out_f[i, 0], out_f[i, 1], out_f[i, 2] = f0, f1, f2
        out_pdf[i] = pdf


def _sample(tab, m, wo, n, seed):
    u = np.random.default_rng(seed).random((n, 3))
    d, w, pdf, flags = np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty(n, np.int64)
    _sample_many(tab, m, np.asarray(wo, np.float64), u, d, w, pdf, flags)
    return d, w, pdf, flags


def _eval(tab, m, wo, wi):
    f, pdf = np.empty((wi.shape[0], 3)), np.empty(wi.shape[0])
    _eval_many(tab, m, np.asarray(wo, np.float64), np.ascontiguousarray(wi, np.float64), f, pdf)
    return f, pdf


def _wo(theta_deg):
    t = np.radians(theta_deg)
    return np.array([np.sin(t), 0.0, np.cos(t)])


def test_flag_constants_are_closure_pys():
    assert (bsdf.LOBE_DELTA, bsdf.LOBE_GLOSSY, bsdf.LOBE_DIFFUSE, bsdf.LOBE_TRANSMIT) == (
        closure.LOBE_DELTA, closure.LOBE_GLOSSY, closure.LOBE_DIFFUSE, closure.LOBE_TRANSMIT)
    assert (bsdf._DIFFUSE, bsdf._GLOSSY, bsdf._GLASS, bsdf._REFRACTION) == (
        cl.CLOSURE_DIFFUSE, cl.CLOSURE_GLOSSY, cl.CLOSURE_GLASS, cl.CLOSURE_REFRACTION)
    assert (bsdf._COLOR, bsdf._ROUGHNESS, bsdf._IOR) == (cl.COLOR, cl.ROUGHNESS, cl.IOR)


@pytest.mark.parametrize("roughness, theta", [(0.3, 20.0), (0.6, 60.0), (0.25, 70.0)])
def test_ggx_sampler_matches_its_pdf_chi_square(roughness, theta):
    """Histogram of sampled directions over (cos theta, phi) bins against the pdf eval_bsdf
    returns, integrated over each bin (midpoint rule on a finer grid)."""
    tab = _table([{"specular": [1, 1, 1], "roughness": roughness}])
    wo = _wo(theta)
    n = 200_000
    d, w, pdf, flags = _sample(tab, 0, wo, n, seed=int(roughness * 100 + theta))
    ok = flags != 0
    assert np.all(flags[ok] == bsdf.LOBE_GLOSSY)
    # pdf > 0 wherever a sample lands, and the weight is f |cos| / pdf of that direction.
    f, p = _eval(tab, 0, wo, d[ok])
    assert np.all(p > 0)
    np.testing.assert_allclose(p, pdf[ok], rtol=1e-9)
    np.testing.assert_allclose(w[ok], f / p[:, None], rtol=1e-9)
    nc, nphi, sub = 16, 32, 24
    z = np.clip(d[ok, 2], 0, 1)
    phi = np.mod(np.arctan2(d[ok, 1], d[ok, 0]), 2 * np.pi)
    hist, _, _ = np.histogram2d(z, phi, bins=[nc, nphi], range=[[0, 1], [0, 2 * np.pi]])
    zc = (np.arange(nc * sub) + 0.5) / (nc * sub)
    pc = (np.arange(nphi * sub) + 0.5) / (nphi * sub) * 2 * np.pi
    zz, pp = np.meshgrid(zc, pc, indexing="ij")
    r = np.sqrt(1 - zz ** 2)
    grid = np.stack([r * np.cos(pp), r * np.sin(pp), zz], -1).reshape(-1, 3)
    _, pg = _eval(tab, 0, wo, grid)
    cell = (1.0 / (nc * sub)) * (2 * np.pi / (nphi * sub))  # dz dphi = solid angle
    expected = (pg.reshape(nc, sub, nphi, sub) * cell).sum(axis=(1, 3)) * n
    keep = expected > 5
    # The pdf's mass above the horizon is the fraction of samples that gave a direction.
    np.testing.assert_allclose(expected.sum(), ok.sum(), rtol=0.01)
    chi2 = float((((hist - expected) ** 2)[keep] / expected[keep]).sum())
    dof = int(keep.sum()) - 1
    assert stats.chi2.sf(chi2, dof) > 0.01, (chi2, dof)


@pytest.mark.parametrize("rows", [
    [{"specular": [0.9, 0.6, 0.3], "roughness": 0.4}],
    [{"diffuse": [0.5, 0.4, 0.3], "specular": [0.3, 0.3, 0.3], "roughness": 0.25}],
])
def test_mean_sampled_weight_is_the_integral_of_eval(rows):
    """E[w] = int f |cos| dw (estimated independently by uniform hemisphere directions)."""
    tab = _table(rows)
    wo = _wo(40.0)
    _, w, _, _ = _sample(tab, 0, wo, 400_000, seed=3)
    u = np.random.default_rng(9).random((400_000, 2))
    z = u[:, 0]
    r = np.sqrt(1 - z * z)
    wi = np.stack([r * np.cos(2 * np.pi * u[:, 1]), r * np.sin(2 * np.pi * u[:, 1]), z], 1)
    f, _ = _eval(tab, 0, wo, wi)
    integral = f.mean(axis=0) * 2 * np.pi
    np.testing.assert_allclose(w.mean(axis=0), integral, rtol=0.02)


def test_mirror_and_glass_are_delta_lobes():
    tab = _table([{"specular": [0.8, 0.8, 0.8], "roughness": 0.0},
                  {"transmission": [1, 1, 1], "ior": 1.5}])
    wo = _wo(30.0)
    d, w, pdf, flags = _sample(tab, 0, wo, 100, seed=1)
    assert np.all(flags == bsdf.LOBE_DELTA) and np.all(pdf == 0)
    np.testing.assert_allclose(d, np.tile([-wo[0], 0, wo[2]], (100, 1)), atol=1e-12)
    np.testing.assert_allclose(w, 0.8)
    d, w, pdf, flags = _sample(tab, 1, wo, 2000, seed=2)
    assert np.all(flags & bsdf.LOBE_DELTA) and np.all(pdf == 0)
    refracted = (flags & bsdf.LOBE_TRANSMIT) != 0
    assert 0.5 < refracted.mean() < 0.95 and np.all(d[refracted, 2] < 0)
    f, p = _eval(tab, 1, wo, d)
    assert np.all(f == 0) and np.all(p == 0)


def test_albedo_splits_diffuse_from_the_whole():
    tab = _table([{"diffuse": [0.5, 0.4, 0.3], "specular": [0.3, 0.3, 0.3], "roughness": 0.2},
                  {"specular": [0.9, 0.9, 0.9]}])
    np.testing.assert_allclose(bsdf.albedo(tab, 0, 1.0, 1.0, 1.0, 0, 0, 1, 0, 0, 1),
                               [0.5, 0.4, 0.3, 0.8, 0.7, 0.6])
    np.testing.assert_allclose(bsdf.albedo(tab, 1, 1.0, 1.0, 1.0, 0, 0, 1, 0, 0, 1),
                               [0, 0, 0, 0.9, 0.9, 0.9])
