"""The closure evaluator (core/materials/closure.py) against its own contract and physics:

- chi-square of every closure kind's sampler against the pdf ``eval_bsdf`` reports (Mitsuba
  3's habit: a histogram of sampled directions in (cos theta, phi) bins against the pdf
  integrated per bin, failed samples as one more bin; p > 0.01), for several wo;
- pdf > 0 (and the same pdf) wherever a sample lands;
- white furnace: the directional albedo (Monte Carlo of the path weights) is 1 within 2 %
  for multiscatter GGX at colour 1 and for Lambert / Oren-Nayar, and never above 1;
- energy conservation of the Principled layering with base colour 1 and every layer on;
- reciprocity where it holds; the legacy lobes (Materials without closures) unchanged.
"""

import zlib

import numpy as np
import pytest
from scipy import stats

from core.materials import bsdf, closure
from core.scene import closures as cl
from core.scene import contract

N_UP = np.array([0.0, 0.0, 1.0])
TANGENT = np.array([1.0, 0.0, 0.0])

# (name, closure rows): one material each
CASES = {
    "lambert": [dict(kind=cl.CLOSURE_DIFFUSE, params=dict(color=1.0, roughness=0.0))],
    "oren_nayar": [dict(kind=cl.CLOSURE_DIFFUSE, params=dict(color=1.0, roughness=0.8))],
    "translucent": [dict(kind=cl.CLOSURE_TRANSLUCENT, params=dict(color=1.0))],
    "sheen": [dict(kind=cl.CLOSURE_SHEEN, params=dict(color=1.0, roughness=0.5))],
    "glossy_ggx_0.3": [dict(kind=cl.CLOSURE_GLOSSY, params=dict(
        color=1.0, roughness=0.3, distribution=cl.DISTRIBUTION_GGX))],
    "glossy_multi_0.6": [dict(kind=cl.CLOSURE_GLOSSY, params=dict(
        color=1.0, roughness=0.6, distribution=cl.DISTRIBUTION_MULTI_GGX))],
    "glossy_aniso": [dict(kind=cl.CLOSURE_GLOSSY, params=dict(
        color=1.0, roughness=0.5, anisotropic=0.6, anisotropic_rotation=0.1))],
    "metal_f82_0.4": [dict(kind=cl.CLOSURE_METALLIC, params=dict(
        color=(0.9, 0.6, 0.3), specular_tint=(0.8, 0.9, 1.0), roughness=0.4))],
    "metal_conductor_aniso": [dict(kind=cl.CLOSURE_METALLIC, params=dict(
        fresnel_type=cl.FRESNEL_CONDUCTOR, roughness=0.5, anisotropic=0.5))],
    "glass_0.3": [dict(kind=cl.CLOSURE_GLASS, params=dict(color=1.0, roughness=0.3, ior=1.5))],
    "glass_0.6": [dict(kind=cl.CLOSURE_GLASS, params=dict(color=1.0, roughness=0.6, ior=1.45))],
    "refraction_0.4": [dict(kind=cl.CLOSURE_REFRACTION, params=dict(
        color=1.0, roughness=0.4, ior=1.5))],
    "glossy_beckmann_0.4": [dict(kind=cl.CLOSURE_GLOSSY, params=dict(
        color=1.0, roughness=0.4, distribution=cl.DISTRIBUTION_BECKMANN))],
    "glass_beckmann_0.4": [dict(kind=cl.CLOSURE_GLASS, params=dict(
        color=1.0, roughness=0.4, ior=1.5, distribution=cl.DISTRIBUTION_BECKMANN))],
    "refraction_beckmann_0.3": [dict(kind=cl.CLOSURE_REFRACTION, params=dict(
        color=1.0, roughness=0.3, ior=1.45, distribution=cl.DISTRIBUTION_BECKMANN))],
    "principled_default": [dict(kind=cl.CLOSURE_PRINCIPLED)],
    "principled_metal": [dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
        metallic=1.0, roughness=0.3, color=(0.95, 0.64, 0.54)))],
    "principled_layers": [dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
        roughness=0.5, transmission=0.5, coat_weight=0.7, coat_roughness=0.3,
        coat_tint=(0.9, 0.7, 0.6), sheen_weight=0.8, sheen_roughness=0.4,
        diffuse_roughness=0.5, anisotropic=0.4))],
    "principled_coat_normal": [dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
        roughness=0.5, coat_weight=1.0, coat_roughness=0.3, coat_tint=(0.9, 0.8, 0.7),
        coat_normal=(0.3, -0.2, 0.93)))],
    "principled_sheen_coat_normal": [dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
        roughness=0.5, sheen_weight=1.0, sheen_roughness=0.4, coat_weight=0.6,
        coat_roughness=0.3, coat_normal=(0.3, -0.2, 0.93)))],
    "principled_thin_wall": [dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
        roughness=0.5, transmission=1.0, thin_wall=1.0))],
    "mix": [dict(kind=cl.CLOSURE_DIFFUSE, weight=0.4, params=dict(color=(0.8, 0.2, 0.2))),
            dict(kind=cl.CLOSURE_GLOSSY, weight=0.6, params=dict(color=1.0, roughness=0.4))],
}
NAMES = list(CASES)


@pytest.fixture(scope="module")
def tab():
    mats = contract.Materials.from_list([{"closures": CASES[k]} for k in NAMES])
    return closure.table(mats)


def _wo(theta_deg, phi_deg=20.0):
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def _samples(tab, name, wo, entering, n, seed):
    u = np.random.default_rng(seed).random((n, 3))
    return closure.sample_many(tab, NAMES.index(name), wo, N_UP, N_UP, TANGENT, entering, u)


def _chi2_pvalue(tab, name, wo, entering, n=120_000, n_theta=16, n_phi=32, sub=20):
    """p-value of the sampled directions' histogram against the integrated pdf."""
    m = NAMES.index(name)
    s = _samples(tab, name, wo, entering, n, seed=zlib.crc32(f"{name}{wo}{entering}".encode()))
    ok = (s[:, 7] > 0) & (s[:, 6] > 0)          # rough lobes (pdf > 0); delta lobes aside
    assert not np.any((s[:, 7] > 0) & (s[:, 6] <= 0)), "a delta in a rough-only material"
    d = s[ok, :3]
    ct = np.clip(d[:, 2], -1, 1)
    ph = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi)
    obs, _, _ = np.histogram2d(ct, ph, [n_theta, n_phi], [[-1, 1], [0, 2 * np.pi]])
    # expected: the pdf integrated over each bin (midpoint rule on a sub x sub grid per bin)
    cc = -1 + (np.arange(n_theta * sub) + 0.5) * 2 / (n_theta * sub)
    pc = (np.arange(n_phi * sub) + 0.5) * 2 * np.pi / (n_phi * sub)
    C, P = np.meshgrid(cc, pc, indexing="ij")
    st = np.sqrt(1 - C ** 2)
    wi = np.stack([st * np.cos(P), st * np.sin(P), C], -1).reshape(-1, 3)
    # the density of the accepted samples: each lobe's pdf where the true surface's side
    # agrees with the lobe's own (a lobe with a normal of its own, tilted from ng, sends
    # some samples below the surface, which the sampler refuses as Cycles' does)
    pdf = closure.parts_many(tab, m, wo, wi, N_UP, N_UP, TANGENT, entering, True)[:, 6]
    cell = (2 / (n_theta * sub)) * (2 * np.pi / (n_phi * sub))
    exp = (pdf.reshape(n_theta, sub, n_phi, sub).sum(axis=(1, 3)) * cell * n)
    obs = np.append(obs.ravel(), n - ok.sum())
    exp = np.append(exp.ravel(), max(n - exp.sum(), 0.0))
    # pool the bins expecting fewer than 5 samples
    small = exp < 5
    o = np.append(obs[~small], obs[small].sum())
    e = np.append(exp[~small], exp[small].sum())
    keep = e > 0
    assert np.all(o[~keep] == 0), "samples where the pdf is 0"
    o, e = o[keep], e[keep]
    chi2 = np.sum((o - e) ** 2 / e)
    return stats.chi2.sf(chi2, len(o) - 1)


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("theta", [35.0, 72.0])
def test_sampler_matches_pdf_chi2(tab, name, theta):
    p = _chi2_pvalue(tab, name, _wo(theta), True)
    assert p > 0.01, f"{name} at {theta} deg: chi-square p = {p:.2e}"


@pytest.mark.parametrize("name", ["glass_0.3", "glass_0.6", "refraction_0.4",
                                  "glass_beckmann_0.4", "refraction_beckmann_0.3"])
def test_sampler_matches_pdf_chi2_leaving_glass(tab, name):
    """From inside (eta = 1 / IOR): total internal reflection and the widened lobe."""
    p = _chi2_pvalue(tab, name, _wo(40.0), False)
    assert p > 0.01, f"{name} leaving: chi-square p = {p:.2e}"


@pytest.mark.parametrize("name", NAMES)
def test_pdf_positive_and_equal_where_samples_land(tab, name):
    m = NAMES.index(name)
    for theta in (10.0, 60.0, 85.0):
        wo = _wo(theta)
        s = _samples(tab, name, wo, True, 4000, seed=7)
        ok = (s[:, 7] > 0) & (s[:, 6] > 0)
        ev = closure.eval_many(tab, m, wo, s[ok, :3], N_UP, N_UP, TANGENT, True)
        assert np.all(ev[:, 3] > 0), f"{name}: pdf 0 where a sample landed"
        np.testing.assert_allclose(ev[:, 3], s[ok, 6], rtol=1e-9)
        # the path weight is f |cos| / pdf
        np.testing.assert_allclose(ev[:, :3] / ev[:, 3:4], s[ok, 3:6], rtol=1e-9)
        assert np.all(np.isfinite(s)) and np.all(s[:, 3:7] >= 0)


def _albedo(tab, name, wo, entering=True, n=200_000, seed=3):
    s = _samples(tab, name, wo, entering, n, seed)
    w = np.where(s[:, 7:8] > 0, s[:, 3:6], 0.0)
    return w.mean(axis=0), w.std(axis=0) / np.sqrt(n)


FURNACE_ONE = ["lambert", "oren_nayar", "translucent", "glossy_multi_0.6"]


@pytest.mark.parametrize("name", FURNACE_ONE)
@pytest.mark.parametrize("theta", [15.0, 50.0, 80.0])
def test_white_furnace_is_one(tab, name, theta):
    mean, err = _albedo(tab, name, _wo(theta))
    assert np.all(np.abs(mean - 1) < 0.02), f"{name} at {theta}: albedo {mean} +- {err}"


@pytest.mark.parametrize("roughness", [0.2, 0.5, 0.8, 1.0])
@pytest.mark.parametrize("theta", [15.0, 50.0, 80.0])
def test_white_furnace_multiscatter_metal(roughness, theta):
    """Metallic (F82, colour 1) and Principled metal with multiscatter GGX: a rough white
    metal reflects everything (a single-scattering GGX one is grey: checked too)."""
    rows = [{"closures": [dict(kind=cl.CLOSURE_METALLIC, params=dict(color=1.0, roughness=roughness))]},
            {"closures": [dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
                color=1.0, metallic=1.0, roughness=roughness))]},
            {"closures": [dict(kind=cl.CLOSURE_METALLIC, params=dict(
                color=1.0, roughness=roughness, distribution=cl.DISTRIBUTION_GGX))]}]
    t = closure.table(contract.Materials.from_list(rows))
    u = np.random.default_rng(11).random((200_000, 3))
    for m in (0, 1, 2):
        s = closure.sample_many(t, m, _wo(theta), N_UP, N_UP, TANGENT, True, u)
        mean = np.where(s[:, 7:8] > 0, s[:, 3:6], 0.0).mean(axis=0)
        if m < 2:
            assert np.all(np.abs(mean - 1) < 0.02), (m, roughness, theta, mean)
        else:
            assert np.all(mean < 1.0 + 0.005), (roughness, theta, mean)
            if roughness >= 0.5:
                assert np.all(mean < 0.97), "single scattering loses energy"


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("theta", [5.0, 45.0, 75.0, 88.0])
def test_white_furnace_never_above_one(tab, name, theta):
    mean, err = _albedo(tab, name, _wo(theta), n=100_000)
    assert np.all(mean <= 1 + 0.01 + 3 * err), f"{name} at {theta}: albedo {mean} +- {err}"


@pytest.mark.parametrize("entering", [True, False])
def test_white_furnace_rough_glass_multiscatter(entering):
    """Multiscatter rough glass at colour 1 loses no energy: R + T = 1 within 2 %."""
    t = closure.table(contract.Materials.from_list([{"closures": [dict(
        kind=cl.CLOSURE_GLASS, params=dict(color=1.0, roughness=0.5, ior=1.5))]}]))
    for theta in (20.0, 60.0):
        u = np.random.default_rng(5).random((200_000, 3))
        s = closure.sample_many(t, 0, _wo(theta), N_UP, N_UP, TANGENT, entering, u)
        mean = np.where(s[:, 7:8] > 0, s[:, 3:6], 0.0).mean(axis=0)
        assert np.all(np.abs(mean - 1) < 0.02), (entering, theta, mean)


def _uniform_sphere(rng, n):
    """(n, 3) unit directions uniform over the sphere (pdf 1 / 4 pi)."""
    z = rng.uniform(-1, 1, n)
    ph = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(ph), r * np.sin(ph), z], -1)


def test_furnace_independent_of_the_sampler(tab):
    """The same albedo by uniform sphere sampling of eval_bsdf (not the lobe samplers)."""
    n = 400_000
    wi = _uniform_sphere(np.random.default_rng(9), n)
    for name in ["lambert", "oren_nayar", "glossy_multi_0.6", "glass_0.6", "principled_layers"]:
        m = NAMES.index(name)
        wo = _wo(40.0)
        f = closure.eval_many(tab, m, wo, wi, N_UP, N_UP, TANGENT, True)[:, :3] * 4 * np.pi
        mean, err = f.mean(axis=0), f.std(axis=0) / np.sqrt(n)
        ref, rerr = _albedo(tab, name, wo)
        assert np.all(np.abs(mean - ref) < 4 * np.hypot(err, rerr) + 0.005), (name, mean, ref)


@pytest.mark.parametrize("entering", [True, False])
@pytest.mark.parametrize("theta", [70.0, 85.0])
def test_rough_glass_eval_holds_only_what_its_sampler_reaches(entering, theta):
    """Single-scattering rough glass (roughness 0.6) from outside and from inside, at
    steep and grazing angles: eval integrated over the sphere (uniform directions) equals
    the sampler's albedo. A refraction is only evaluated where a microfacet relates the two
    directions (h . wo > 0 > h . wi); Cycles' eval omits that check (its own TODO) and so
    holds light its sampler never reaches: measured with that form, 1.11 / 1.42 from
    outside at 70 / 85 degrees against the sampler's 0.91 / 0.89 (docs/materials.md,
    "Rough glass and Cycles' back-facing microfacets")."""
    t = closure.table(contract.Materials.from_list([{"closures": [dict(
        kind=cl.CLOSURE_GLASS, params=dict(color=1.0, roughness=0.6, ior=1.5,
                                           distribution=cl.DISTRIBUTION_GGX))]}]))
    rng = np.random.default_rng(12)
    n = 600_000
    wi = _uniform_sphere(rng, n)
    wo = _wo(theta)
    f = closure.eval_many(t, 0, wo, wi, N_UP, N_UP, TANGENT, entering)[:, 0] * 4 * np.pi
    s = closure.sample_many(t, 0, wo, N_UP, N_UP, TANGENT, entering, rng.random((n, 3)))
    w = np.where(s[:, 7] > 0, s[:, 3], 0.0)
    err = np.hypot(f.std(), w.std()) / np.sqrt(n)
    assert abs(f.mean() - w.mean()) < 4 * err + 0.005, (f.mean(), w.mean(), err)
    assert w.mean() < 1.0


@pytest.mark.parametrize("metallic", [0.0, 0.5])
@pytest.mark.parametrize("spec_level", [0.5, 1.0])
def test_principled_layering_conserves_energy(metallic, spec_level):
    """Base colour 1, every layer on: the directional albedo never exceeds 1."""
    p = dict(color=1.0, metallic=metallic, roughness=0.4, transmission=0.3,
             specular_level=spec_level, coat_weight=1.0, coat_roughness=0.2,
             sheen_weight=1.0, sheen_roughness=0.3, diffuse_roughness=0.3,
             subsurface_weight=0.2)
    t = closure.table(contract.Materials.from_list(
        [{"closures": [dict(kind=cl.CLOSURE_PRINCIPLED, params=p)]}]))
    u = np.random.default_rng(2).random((100_000, 3))
    for theta in (0.0, 30.0, 60.0, 80.0, 88.0):
        s = closure.sample_many(t, 0, _wo(theta), N_UP, N_UP, TANGENT, True, u)
        w = np.where(s[:, 7:8] > 0, s[:, 3:6], 0.0)
        mean, err = w.mean(axis=0), w.std(axis=0) / np.sqrt(len(w))
        # At grazing view the coat's albedo estimate (Cycles' generalized-Schlick table,
        # the same estimator Cycles layers with) falls short of the compensated lobe's
        # true albedo, so the layers below keep a little too much: measured +2 % at 88 deg
        # with a coat, within 0.5 % elsewhere.
        slack = 0.005 if theta <= 80.0 else 0.03
        assert np.all(mean <= 1 + 3 * err + slack), (theta, mean)
        assert np.all(mean > 0.5), "most of the light comes back from a white material"


@pytest.mark.parametrize("name", ["lambert", "oren_nayar", "glossy_ggx_0.3", "metal_f82_0.4",
                                  "glossy_aniso"])
def test_reciprocity(tab, name):
    """f(wo, wi) = f(wi, wo) for the reflection lobes without wo-dependent energy terms."""
    if name in ("metal_f82_0.4", "glossy_aniso"):  # make them single-scattering GGX
        row = dict(CASES[name][0])
        row["params"] = dict(row["params"], distribution=cl.DISTRIBUTION_GGX)
        t = closure.table(contract.Materials.from_list([{"closures": [row]}]))
        m = 0
    else:
        t, m = tab, NAMES.index(name)
    rng = np.random.default_rng(4)
    for _ in range(50):
        a, b = rng.normal(size=(2, 3))
        a[2], b[2] = abs(a[2]) + 0.05, abs(b[2]) + 0.05
        a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
        fab = closure.eval_many(t, m, a, b[None], N_UP, N_UP, TANGENT, True)[0, :3] / b[2]
        fba = closure.eval_many(t, m, b, a[None], N_UP, N_UP, TANGENT, True)[0, :3] / a[2]
        np.testing.assert_allclose(fab, fba, rtol=1e-9, atol=1e-12)


def test_lambert_and_legacy_lobes_unchanged():
    """Materials without closures (the legacy lobes) evaluate as bsdf.eval_reflection: the
    old renders map onto the new model."""
    mats = contract.Materials.from_list([dict(diffuse=(0.5, 0.4, 0.3), specular=(0.2, 0.2, 0.2),
                                              roughness=0.35)])
    t = closure.table(mats)
    rng = np.random.default_rng(6)
    wo = _wo(30.0)
    wi = rng.normal(size=(200, 3))
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    got = closure.eval_many(t, 0, wo, wi, N_UP, N_UP, TANGENT, True)[:, :3]
    alpha = 0.35 ** 2
    ks = bsdf.ggx_brdf(alpha, np.tile(N_UP, (200, 1)), np.tile(wo, (200, 1)), wi)
    ref = (np.array([0.5, 0.4, 0.3]) / np.pi + 0.2 * ks[:, None]) * wi[:, 2:3]
    np.testing.assert_allclose(got, ref, rtol=1e-6)  # float32 weights


def test_smooth_glass_is_a_delta_with_fresnel_weights():
    """Roughness 0: delta reflection / refraction, weights F / P and (1 - F) / (1 - P) summing
    to the unbiased 1 (colour 1), no eval."""
    t = closure.table(contract.Materials.from_list([{"closures": [dict(
        kind=cl.CLOSURE_GLASS, params=dict(color=1.0, roughness=0.0, ior=1.5))]}]))
    u = np.random.default_rng(1).random((20_000, 3))
    wo = _wo(50.0)
    s = closure.sample_many(t, 0, wo, N_UP, N_UP, TANGENT, True, u)
    assert np.all(s[:, 7].astype(int) & closure.LOBE_DELTA)
    assert np.all(s[:, 6] == 0)
    refl = (s[:, 7].astype(int) & closure.LOBE_TRANSMIT) == 0
    np.testing.assert_allclose(s[refl, :3], np.tile([-wo[0], -wo[1], wo[2]], (refl.sum(), 1)),
                               atol=1e-12)
    f, _ = bsdf.fresnel(np.cos(np.radians(50.0)), 1.5)
    assert abs(refl.mean() - f[0]) < 0.01
    np.testing.assert_allclose(s[:, 3:6].mean(axis=0), 1.0, atol=0.02)
    # Snell's law for the refracted ones
    sin_t = np.hypot(s[~refl, 0], s[~refl, 1])
    np.testing.assert_allclose(sin_t, np.sin(np.radians(50.0)) / 1.5, rtol=1e-9)
    assert np.all(closure.eval_many(t, 0, wo, s[:, :3], N_UP, N_UP, TANGENT, True) == 0)


def test_albedo_splits_diffuse_and_total(tab):
    """albedo(): the diffuse part is 0 for a metal or glass (no photon stored), the total
    tracks the sampled directional albedo."""
    wo = _wo(40.0)
    for name in NAMES:
        m = NAMES.index(name)
        a = closure.albedo_at(tab, m, wo, N_UP)
        assert np.all(np.isfinite(a)) and np.all(a >= 0)
        mean, _ = _albedo(tab, name, wo, n=60_000)
        diffuse_like = name in ("lambert", "oren_nayar", "translucent", "sheen")
        if name.startswith(("glossy", "metal", "glass", "refraction")) or name == "principled_metal":
            assert np.all(a[:3] == 0), name
        if diffuse_like:
            np.testing.assert_allclose(a[:3], a[3:], rtol=1e-12)
        if name in ("glossy_aniso", "metal_conductor_aniso"):
            # the compensation tables are isotropic (sqrt(alpha_x alpha_y)), like Cycles':
            # an anisotropic multiscatter lobe keeps ~82 % where the estimate says ~1
            continue
        np.testing.assert_allclose(a[3:], mean, rtol=0.08, atol=0.02, err_msg=name)


def test_texel_colour_multiplies_textured_closures_only():
    mats = contract.Materials.from_list([{"closures": [
        dict(kind=cl.CLOSURE_DIFFUSE, params=dict(color=0.5, roughness=0.0), texture=0),
        dict(kind=cl.CLOSURE_DIFFUSE, params=dict(color=0.5, roughness=0.0))]}])
    t = closure.table(mats)
    wo = _wo(0.0)
    f = closure.eval_bsdf(t, 0, 0.2, 1.0, 0.0, *wo, *wo, *N_UP, *N_UP, *TANGENT, True)
    np.testing.assert_allclose(f[:3], np.array([0.5 * 0.2 + 0.5, 0.5 + 0.5, 0.5]) / np.pi,
                               rtol=1e-6)


def test_random_materials_give_finite_non_negative_values():
    """Fuzz: random closures (every slot within Blender's UI ranges, IOR below 1 included),
    random wo / wi, shading normals bent away from the geometric one: eval, sample and
    albedo stay finite and non-negative, and the pdf of a sampled rough direction is > 0."""
    rng = np.random.default_rng(21)
    rows = []
    kinds = list(cl.CLOSURE_KIND_NAMES)
    for _ in range(60):
        cs = []
        for _ in range(rng.integers(1, 4)):
            p = dict(color=rng.random(3), roughness=rng.choice([0.0, rng.random()]),
                     metallic=rng.random(), ior=rng.choice([1.0, 0.8, 1.0 + 2 * rng.random()]),
                     specular_level=2 * rng.random(), specular_tint=rng.random(3),
                     transmission=rng.random(), coat_weight=rng.random(),
                     coat_roughness=rng.random(), coat_ior=1 + rng.random(),
                     coat_tint=rng.random(3), sheen_weight=rng.random(),
                     sheen_roughness=rng.random(), sheen_tint=rng.random(3),
                     anisotropic=rng.uniform(-1, 1), anisotropic_rotation=rng.random(),
                     diffuse_roughness=rng.random(), subsurface_weight=rng.random(),
                     thin_wall=float(rng.integers(0, 2)),
                     distribution=float(rng.integers(0, 4)),
                     fresnel_type=float(rng.integers(0, 2)),
                     metal_n=3 * rng.random(3), metal_k=5 * rng.random(3))
            cs.append(dict(kind=int(rng.choice(kinds)), weight=rng.random(3), params=p,
                           texture=int(rng.integers(-1, 1))))
        rows.append({"closures": cs})
    t = closure.table(contract.Materials.from_list(rows))
    for m in range(len(rows)):
        ng = rng.normal(size=3)
        ng /= np.linalg.norm(ng)
        ns = ng + 0.3 * rng.normal(size=3)
        ns /= np.linalg.norm(ns)
        wo = rng.normal(size=3)
        wo *= np.sign(wo @ ng) / np.linalg.norm(wo)
        tg = rng.normal(size=3)
        tg /= np.linalg.norm(tg)
        entering = bool(rng.integers(0, 2))
        u = rng.random((300, 3))
        s = closure.sample_many(t, m, wo, ns, ng, tg, entering, u)
        assert np.all(np.isfinite(s)) and np.all(s[:, 3:7] >= 0), m
        wi = rng.normal(size=(300, 3))
        wi /= np.linalg.norm(wi, axis=1, keepdims=True)
        e = closure.eval_many(t, m, wo, wi, ns, ng, tg, entering)
        assert np.all(np.isfinite(e)) and np.all(e >= 0), m
        a = closure.albedo_at(t, m, wo, ns, rng.random(3))
        assert np.all(np.isfinite(a)) and np.all(a >= 0), m
        rough = (s[:, 7] > 0) & (s[:, 6] > 0)
        e2 = closure.eval_many(t, m, wo, s[rough, :3], ns, ng, tg, entering)
        assert np.all(e2[:, 3] > 0), m


@pytest.mark.parametrize("name", NAMES)
def test_eval_parts_split_the_bsdf_by_lobe_kind(tab, name):
    """eval_parts: diffuse-like part + glossy part = eval_bsdf, the same pdf; a material of
    diffuse-like lobes only has no glossy part and a microfacet one no diffuse part (the
    direct light and the camera paths' continuation read the split, issue 13: Oren-Nayar
    and sheen used to be split as d / pi, which overshot)."""
    m = NAMES.index(name)
    rng = np.random.default_rng(11)
    wo = _wo(50.0)
    wi = rng.normal(size=(64, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    whole = closure.eval_many(tab, m, wo, wi, N_UP, N_UP, TANGENT, True)
    for w, (f0, f1, f2, pdf) in zip(wi, whole):
        d0, d1, d2, g0, g1, g2, p = closure.eval_parts(tab, m, 1.0, 1.0, 1.0, *wo, *w, *N_UP,
                                                       *N_UP, *TANGENT, True, False)
        np.testing.assert_allclose([d0 + g0, d1 + g1, d2 + g2, p], [f0, f1, f2, pdf],
                                   rtol=1e-12, atol=1e-15)
        if name in ("lambert", "oren_nayar", "translucent", "sheen"):
            assert g0 == g1 == g2 == 0.0
        if name.startswith(("glossy", "metal", "glass", "refraction")):
            assert d0 == d1 == d2 == 0.0
        # sided: the geometric side decides (here ng = ns): reflection lobes see nothing
        # below, Translucent nothing above; a coat (and sheen) with a normal of its own
        # sees nothing from below the surface either, even where that normal has it above
        s = closure.eval_parts(tab, m, 1.0, 1.0, 1.0, *wo, *w, *N_UP, *N_UP, *TANGENT, True,
                               True)
        if name.endswith("coat_normal") and w[2] < 0.0:
            np.testing.assert_array_equal(s, np.zeros(7))
        else:
            np.testing.assert_allclose(s, (d0, d1, d2, g0, g1, g2, p), rtol=1e-12,
                                       atol=1e-15)


def test_lobe_masks_name_the_non_lambert_diffuse_lobes(tab):
    """non_lambert: the photon terms evaluate the BSDF per photon there; diffuse_transmits:
    Translucent (photons and gather rays of the far side count)."""
    masks = closure.lobe_masks(tab)
    non_lambert = {n for n, v in zip(NAMES, masks["non_lambert"]) if v}
    # principled_layers: Diffuse Roughness and sheen; mix: its Diffuse row keeps the
    # default roughness 0.5 (Oren-Nayar); the thin wall's base is all transmission
    assert non_lambert == {"oren_nayar", "translucent", "sheen", "principled_layers",
                           "principled_sheen_coat_normal", "mix"}
    assert {n for n, v in zip(NAMES, masks["diffuse_transmits"]) if v} == {"translucent"}


@pytest.mark.parametrize("kind", ["glossy", "principled"])
def test_anisotropic_rotation_quarter_turn_swaps_the_roughness_axes(kind):
    """Anisotropic Rotation 0.25 turns the lobe's frame by 90 degrees about n: the same as
    swapping alpha_x and alpha_y (Glossy: Anisotropy -a at rotation 0; any lobe: the
    tangent turned to the bitangent), for eval and pdf at every direction."""
    if kind == "glossy":
        rows = [dict(kind=cl.CLOSURE_GLOSSY, params=dict(color=1.0, roughness=0.4,
                                                         anisotropic=a, anisotropic_rotation=r))
                for a, r in ((0.6, 0.25), (-0.6, 0.0), (0.6, 0.0))]
    else:
        rows = [dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
            metallic=1.0, roughness=0.4, anisotropic=0.7, anisotropic_rotation=r))
            for r in (0.25, 0.25, 0.0)]
    t = closure.table(contract.Materials.from_list([{"closures": [r]} for r in rows]))
    rng = np.random.default_rng(2)
    wo = _wo(55.0, 30.0)
    wi = rng.normal(size=(400, 3))
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    turned = closure.eval_many(t, 0, wo, wi, N_UP, N_UP, TANGENT, True)
    plain = closure.eval_many(t, 2, wo, wi, N_UP, N_UP, TANGENT, True)
    # the tangent turned by the same quarter turn, at rotation 0
    by_tangent = closure.eval_many(t, 2, wo, wi, N_UP, N_UP, np.array([0.0, 1.0, 0.0]), True)
    np.testing.assert_allclose(turned, by_tangent, rtol=1e-9, atol=1e-12)
    if kind == "glossy":  # alpha_x and alpha_y swapped by the sign of Anisotropy
        swapped = closure.eval_many(t, 1, wo, wi, N_UP, N_UP, TANGENT, True)
        np.testing.assert_allclose(turned, swapped, rtol=1e-9, atol=1e-12)
    assert np.abs(turned[:, 0] / np.maximum(plain[:, 0], 1e-12) - 1.0).max() > 0.05


def _coat_only(coat_normal=(0.0, 0.0, 0.0), roughness=0.3):
    """A Principled BSDF that is its coat alone (black base, Specular IOR Level 0)."""
    return dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
        color=0.0, specular_level=0.0, coat_weight=1.0, coat_roughness=roughness,
        coat_tint=(0.9, 0.6, 0.3), coat_normal=coat_normal))


@pytest.mark.parametrize("roughness", [0.3, 0.05])
def test_a_coat_normal_shades_the_coat_as_that_shading_normal_would(roughness):
    """Coat Normal n' (Cycles: the coat closure's own N): a coat-only Principled BSDF
    shaded about N_UP with coat normal n' is, for eval and pdf at every direction, the
    same BSDF with no coat normal shaded about n' (the coat's frame, its cosine and its
    albedo go by n'); sampling it gives the pdf and path weights eval reports."""
    n2 = np.array([0.35, -0.25, 0.9])
    n2 /= np.linalg.norm(n2)
    mats = contract.Materials.from_list([{"closures": [_coat_only(tuple(n2), roughness)]},
                                         {"closures": [_coat_only(roughness=roughness)]}])
    t = closure.table(mats)
    rng = np.random.default_rng(3)
    wi = rng.normal(size=(400, 3))
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    tested = 0
    for wo in (_wo(10.0), _wo(50.0, 120.0), _wo(70.0, 250.0), _wo(40.0, 300.0)):
        if (2.0 * (wo @ n2) * n2 - wo) @ N_UP < 0.1:
            continue  # its mirror about n' is below the surface (the shader makes it valid)
        tested += 1
        own = closure.eval_many(t, 0, wo, wi, N_UP, N_UP, TANGENT, True)
        about = closure.eval_many(t, 1, wo, wi, n2, N_UP, TANGENT, True)
        # directions below the true surface: neither (the shading side rule of eval)
        keep = (wi @ N_UP > 0) & (wi @ n2 > 0)
        # (the coat normal is stored float32: equal to its rounding)
        np.testing.assert_allclose(own[keep], about[keep], rtol=1e-5, atol=1e-12)
        assert own[keep, 0].max() > 0.0
        u = rng.random((2000, 3))
        s = closure.sample_many(t, 0, wo, N_UP, N_UP, TANGENT, True, u)
        ok = s[:, 7] > 0
        # as many land above the true surface as from the coat shaded about n'
        s2 = closure.sample_many(t, 1, wo, n2, N_UP, TANGENT, True, u)
        assert ok.mean() > 0.2 and ok.mean() == pytest.approx((s2[:, 7] > 0).mean(), abs=0.01)
        back = closure.eval_many(t, 0, wo, s[ok, :3], N_UP, N_UP, TANGENT, True)
        np.testing.assert_allclose(s[ok, 6], back[:, 3], rtol=1e-6)
        np.testing.assert_allclose(s[ok, 3:6], back[:, :3] / back[:, 3:4], rtol=1e-6)
        # the albedo estimate (layering, Russian roulette) by n' too
        np.testing.assert_allclose(closure.albedo_at(t, 0, wo, N_UP),
                                   closure.albedo_at(t, 1, wo, n2), rtol=1e-5, atol=1e-12)
    assert tested >= 2


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


@pytest.mark.parametrize("coat_weight", [0.6, 1.0, 0.0])
def test_the_sheen_under_a_coat_normal_shades_about_their_mix(coat_weight):
    """Cycles' Principled sheen closure: N = normalize(mix(N, coat normal, saturate(coat
    weight))) (svm/closure.h, since 4.0): a Principled BSDF of its sheen alone (black base,
    Specular IOR Level 0) with a coat normal cn and a coat of weight w, shaded about ns,
    has for diffuse-like part (eval and the albedo its layering reads) the Sheen BSDF of
    the same roughness shaded about that mix (about ns for w = 0; neither about ns nor cn
    for w = 0.6: the test would fail for either)."""
    ns, cn = _unit([0.25, 0.1, 1.0]), _unit([-0.35, 0.2, 0.9])
    mix = _unit(ns + min(coat_weight, 1.0) * (cn - ns))
    rows = [{"closures": [dict(kind=cl.CLOSURE_PRINCIPLED, params=dict(
                color=0.0, specular_level=0.0, sheen_weight=1.0, sheen_roughness=0.4,
                coat_weight=coat_weight, coat_roughness=0.3, coat_normal=tuple(cn)))]},
            {"closures": [dict(kind=cl.CLOSURE_SHEEN, params=dict(color=1.0,
                                                                  roughness=0.4))]}]
    t = closure.table(contract.Materials.from_list(rows))
    rng = np.random.default_rng(8)
    wi = rng.normal(size=(300, 3))
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    for wo in (_wo(20.0), _wo(55.0, 140.0), _wo(60.0, 40.0)):
        assert wo @ ns > 0 and wo @ cn > 0
        keep = (wi @ ns > 0) & (wi @ mix > 0) & (wi @ N_UP > 0)
        d = closure.parts_many(t, 0, wo, wi[keep], ns, N_UP, TANGENT, True, False)[:, :3]
        ref = closure.eval_many(t, 1, wo, wi[keep], mix, N_UP, TANGENT, True)[:, :3]
        assert ref.max() > 0.0
        # (the coat normal is stored float32: equal to its rounding)
        np.testing.assert_allclose(d, ref, rtol=2e-5, atol=1e-9)
        a_principled = closure.albedo_at(t, 0, wo, ns)
        np.testing.assert_allclose(a_principled[:3], closure.albedo_at(t, 1, wo, mix)[:3],
                                   rtol=2e-5)


def test_the_gathered_side_is_each_lobes_own():
    """parts_at(sided): a lobe sees a photon's direction wi only where wi's side of the
    true surface (ng) agrees with its side of the lobe's own normal, as Cycles evaluates
    each closure by its own N. A coat whose normal is the true one (z) over a base bumped
    40 degrees towards +x: wi 30 degrees above the surface on the -x side is below the
    bumped normal but above the coat's, so the coat reflects it (near its mirror direction)
    where the shading normal's side used to reject the whole closure; wi from below the
    surface on the +x side is above the bumped normal: the base's lobes must not see it
    (nothing transmits)."""
    ng = N_UP
    ns = np.array([np.sin(np.radians(40.0)), 0.0, np.cos(np.radians(40.0))])
    t = closure.table(contract.Materials.from_list([{"closures": [dict(
        kind=cl.CLOSURE_PRINCIPLED, params=dict(color=0.8, roughness=0.5, coat_weight=1.0,
                                                coat_roughness=0.3,
                                                coat_normal=(0.0, 0.0, 1.0)))]}]))
    wo = _unit([np.cos(np.radians(35.0)), 0.0, np.sin(np.radians(35.0))])
    args = (t, 0, 1.0, 1.0, 1.0, *wo)
    frame = (*ns, *ng, *TANGENT, True)
    above = _unit([-np.cos(np.radians(30.0)), 0.0, np.sin(np.radians(30.0))])
    assert above @ ns < 0 < above @ ng
    sided = np.array(closure.eval_parts(*args, *above, *frame, True))
    free = np.array(closure.eval_parts(*args, *above, *frame, False))
    assert sided[3] > 0.1 and sided[6] > 0.0  # the coat's glossy reflection and its pdf
    np.testing.assert_array_equal(sided, free)  # the base lobes see nothing below ns
    behind = _unit([0.5, 0.0, -0.2])
    assert behind @ ns > 0 > behind @ ng
    assert closure.eval_parts(*args, *behind, *frame, False)[0] > 0.0  # base: ns side
    np.testing.assert_array_equal(closure.eval_parts(*args, *behind, *frame, True),
                                  np.zeros(7))


def _adjoint_albedo(tab, m, wo, n_theta=96, n_phi=96):
    """Brute force: the light a surface lit from wo sends into the hemisphere,
    integral of f(view = w, light = wo) cos(w) dw (midpoint rule in (cos theta, phi))."""
    c = (np.arange(n_theta) + 0.5) / n_theta
    p = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    total = np.zeros(3)
    for ct in c:
        st = np.sqrt(1 - ct * ct)
        for ph in p:
            w = np.array([st * np.cos(ph), st * np.sin(ph), ct])
            f_cos = closure.eval_many(tab, m, w, wo[None], N_UP, N_UP, TANGENT, True)[0, :3]
            total += f_cos / wo[2] * ct
    return total * (1.0 / n_theta) * (2 * np.pi / n_phi)


@pytest.mark.parametrize("name", ["principled_default", "glossy_multi_0.6"])
def test_photon_reflection_weight_is_the_adjoint_bsdf(tab, name):
    """A photon reflected by ``adjoint_weight`` carries on average the light the surface
    sends out when lit from wo, integral of f(w, wo) cos(w) dw, with the viewer on the
    outgoing side (Cycles' layering and multiscatter terms depend on the viewer's angle):
    brute-force quadrature, within 1 %. At grazing light the camera's weight (the
    sampler's f(wo, w) |cos| / pdf, what photons carried before) differs from it by more
    than that for the Principled BSDF, so the test tells the two apart."""
    m = NAMES.index(name)
    for theta in (20.0, 80.0):
        wo = _wo(theta)
        s = _samples(tab, name, wo, True, 200_000, seed=11)
        refl = (s[:, 7] > 0) & (s[:, 6] > 0) & (s[:, 2] > 0)
        w = np.zeros((s.shape[0], 3))
        w[refl] = closure.photon_weight_many(tab, m, wo, s[refl, :3], N_UP, N_UP, TANGENT,
                                             True, pdf=s[refl, 6])
        expected = _adjoint_albedo(tab, m, wo)
        np.testing.assert_allclose(w.mean(axis=0), expected, rtol=0.01, err_msg=f"{theta}")
        if name == "principled_default" and theta == 80.0:
            forward = np.where(refl[:, None], s[:, 3:6], 0.0).mean(axis=0)
            assert np.all(np.abs(forward / expected - 1) > 0.02), (forward, expected)


def _adjoint_parts(tab, m, wo, n_theta=64, n_phi=64):
    """Brute force, per class: the light a surface lit from wo sends into the hemisphere
    through its diffuse-like lobes and through the others, integrals of f_c(view = w,
    light = wo) cos(w) dw: (diffuse RGB, other RGB)."""
    c = (np.arange(n_theta) + 0.5) / n_theta
    p = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    st = np.sqrt(1 - c * c)
    total = np.zeros(6)
    for ct, s_ in zip(c, st):
        for ph in p:
            w = np.array([s_ * np.cos(ph), s_ * np.sin(ph), ct])
            part = closure.parts_many(tab, m, w, wo[None], N_UP, N_UP, TANGENT, True, False)
            total += part[0, :6] / wo[2] * ct
    return total * (1.0 / n_theta) * (2 * np.pi / n_phi)


@pytest.mark.parametrize("name", ["mix", "principled_default"])
def test_photon_class_weights_keep_diffuse_and_glossy_light_apart(tab, name):
    """At a material with diffuse-like and glossy lobes a photon's weight is that of the
    class of lobe it sampled (``closure.class_weight``): the diffuse-class photons carry on
    average the light the diffuse lobes send out, the glossy-class ones the glossy lobes'
    (brute-force quadrature of the adjoint parts, within 2 % + 4 sigma). The caustic map
    keeps the glossy class only and final gathering counts the diffuse light, so a
    glossy-class photon carrying the whole BSDF's f / p (``adjoint_weight``, which photons
    carried before) double-counted part of the diffuse reflection and weighed the glossy
    light by the share of the pdf its lobes have: the test measures that too (at the Mix
    of a red Diffuse and a rough Glossy, off by more than 5 % in some channel)."""
    m = NAMES.index(name)
    for theta in (30.0, 75.0):
        wo = _wo(theta)
        s = _samples(tab, name, wo, True, 200_000, seed=5)
        refl = (s[:, 7] > 0) & (s[:, 6] > 0) & (s[:, 2] > 0)
        diffuse = (s[:, 7].astype(np.int64) & closure.LOBE_DIFFUSE) != 0
        expected = _adjoint_parts(tab, m, wo)
        whole = np.zeros((s.shape[0], 3))
        whole[refl] = closure.photon_weight_many(tab, m, wo, s[refl, :3], N_UP, N_UP,
                                                 TANGENT, True, pdf=s[refl, 6])
        for part, mask, want in ((0, diffuse, expected[:3]), (1, ~diffuse, expected[3:])):
            w = np.zeros((s.shape[0], 3))
            sel = refl & mask
            w[sel] = closure.photon_weight_many(tab, m, wo, s[sel, :3], N_UP, N_UP, TANGENT,
                                                True, diffuse=diffuse[sel])
            err = w.std(axis=0) / np.sqrt(len(w))
            assert np.all(np.abs(w.mean(axis=0) - want) < 0.02 * want + 4 * err), \
                (theta, part, w.mean(axis=0), want)
        leak = np.where((refl & ~diffuse)[:, None], whole, 0.0).mean(axis=0) / expected[3:]
        if name == "mix":  # measured at 30 deg: red +11 %, green and blue -8 %
            assert np.abs(leak - 1.0).max() > 0.05, (theta, leak)


@pytest.mark.parametrize("entering", [True, False])
def test_photon_transmission_weight_is_the_adjoint_bsdf(entering):
    """Through a rough dielectric the adjoint weight sees the BTDF from the photon's
    outgoing side (the mesh's other side: eta inverted) over eta_out^2. Without
    multiscatter compensation that is the sampler's weight to rounding (the microfacet
    BTDF without radiance's eta^2 is what flux carries); with it the weights differ, as
    Cycles' compensation depends on the viewer's side: from outside the adjoint sends more
    light in than the sampler (the inside view's albedo is the lower one)."""
    wo = _wo(40.0)
    u = np.random.default_rng(8).random((100_000, 3))
    means = {}
    for dist in (cl.DISTRIBUTION_GGX, cl.DISTRIBUTION_MULTI_GGX):
        t = closure.table(contract.Materials.from_list([{"closures": [dict(
            kind=cl.CLOSURE_GLASS, params=dict(color=1.0, roughness=0.5, ior=1.5,
                                               distribution=dist))]}]))
        s = closure.sample_many(t, 0, wo, N_UP, N_UP, TANGENT, entering, u)
        through = (s[:, 7] > 0) & (s[:, 6] > 0) & (s[:, 2] < 0)
        w = closure.photon_weight_many(t, 0, wo, s[through, :3], N_UP, N_UP, TANGENT,
                                       entering, pdf=s[through, 6])
        if dist == cl.DISTRIBUTION_GGX:
            np.testing.assert_allclose(w, s[through, 3:6], rtol=1e-9)
        means[dist] = (w[:, 0].sum() / u.shape[0], s[through, 3].sum() / u.shape[0])
    adjoint, sampler = means[cl.DISTRIBUTION_MULTI_GGX]
    assert (adjoint > 1.03 * sampler) if entering else (adjoint < 0.97 * sampler), means
