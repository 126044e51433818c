"""The albedo tables (core/materials/albedo_tables.npz, made by tools/albedo_tables.py):
a few entries re-estimated independently (uniform sampling of the GGX lobe's eval, not the
visible-normal sampler that made the table), and against Cycles' own tables
(scene/shader.tables, values quoted below) on the same grid."""

import numpy as np
import pytest

from core.materials import albedo_tables, microfacet

TABLES = albedo_tables.load()


def _grid(i, n):
    return min(max(i / (n - 1), 1e-4), 1.0)


@pytest.mark.parametrize("j, i", [(4, 8), (16, 16), (31, 31), (10, 25), (24, 4)])
def test_ggx_e_reestimated_by_uniform_sampling(j, i):
    """E(mu, r) = int f cos dwi over the hemisphere, f from reflect_eval, wi uniform."""
    rough, mu = _grid(i, 32), _grid(j, 32)
    a = rough * rough
    rng = np.random.default_rng(100 + 32 * j + i)
    n = 400_000
    z = rng.random(n)
    ph = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - z * z)
    wi = np.stack([r * np.cos(ph), r * np.sin(ph), z], -1)
    f, _ = microfacet.reflect_values(a, a, [np.sqrt(1 - mu * mu), 0.0, mu], wi)
    g = f * z * 2 * np.pi
    est, err = g.mean(), g.std() / np.sqrt(n)
    assert abs(TABLES["ggx_E"][j, i] - est) < 4 * err + 0.003, (TABLES["ggx_E"][j, i], est, err)


# Cycles' table_ggx_E[j * 32 + i], table_ggx_Eavg[i], table_ggx_glass_E[(k * 16 + j) * 16 + i]
CYCLES_E = {(4, 8): 0.907414, (16, 16): 0.847421, (31, 31): 0.306853, (10, 25): 0.677649,
            (24, 4): 0.999618}
CYCLES_EAVG = {8: 0.985805, 16: 0.870874, 31: 0.409137}
CYCLES_GLASS_E = {(5, 8, 8): 0.959656, (8, 12, 4): 0.998646, (3, 4, 12): 0.747305}


def test_tables_agree_with_cycles():
    for (j, i), v in CYCLES_E.items():
        assert abs(TABLES["ggx_E"][j, i] - v) < 0.004, (j, i)
    for i, v in CYCLES_EAVG.items():
        assert abs(TABLES["ggx_Eavg"][i] - v) < 0.003, i
    for (k, j, i), v in CYCLES_GLASS_E.items():
        assert abs(TABLES["glass_E"][0, k, j, i] - v) < 0.01, (k, j, i)


def test_table_shapes_and_ranges():
    shapes = {"ggx_E": (32, 32), "ggx_Eavg": (32,), "glass_E": (2, 16, 16, 16),
              "glass_Eavg": (2, 16, 16), "schlick_s": (16, 16, 16), "schlick5_s": (16, 16),
              "sheen": (3, 32, 32)}
    for k, s in shapes.items():
        assert TABLES[k].shape == s, k
        assert np.all(np.isfinite(TABLES[k])), k
    for k in ("ggx_E", "ggx_Eavg", "glass_E", "glass_Eavg", "schlick_s", "schlick5_s"):
        assert np.all((TABLES[k] >= 0) & (TABLES[k] <= 1)), k
    # a smooth lobe loses nothing; E falls with roughness at grazing
    np.testing.assert_allclose(TABLES["ggx_E"][:, 0], 1.0, atol=1e-3)
    assert np.all(np.diff(TABLES["ggx_Eavg"]) <= 1e-3)


def test_compensation_restores_a_white_lobe():
    """1 + Fms (1 - E) / E at Fss = 1 is 1 / E: E times it is exactly 1."""
    for e in (0.3, 0.7, 0.99):
        assert abs(e * albedo_tables.compensation(e, 0.5, 1.0) - 1.0) < 1e-12
        # a darker Fresnel compensates less
        assert albedo_tables.compensation(e, 0.5, 0.5) < albedo_tables.compensation(e, 0.5, 1.0)


def test_interpolation_is_exact_on_the_grid():
    t = TABLES["ggx_E"]
    for j, i in [(0, 0), (5, 7), (31, 31)]:
        assert abs(albedo_tables.read_2d(t, i / 31, j / 31) - t[j, i]) < 1e-12


@pytest.mark.parametrize("side, k, j, i", [(0, 5, 8, 8), (0, 10, 12, 4), (1, 6, 10, 9),
                                           (1, 3, 14, 12)])
def test_glass_e_reestimated_by_uniform_sampling(side, k, j, i):
    """The rough dielectric's albedo (reflection + transmission, exact Fresnel) re-estimated
    by uniform sphere sampling of a single-scattering Glass closure's eval_bsdf."""
    from core.materials import closure, fresnel
    from core.scene import closures as cl
    from core.scene import contract
    rough, mu = _grid(i, 16), _grid(j, 16)
    z = min(max(k / 15, 1e-4), 0.99)
    ior = fresnel.ior_from_f0(z ** 4)
    t = closure.table(contract.Materials.from_list([{"closures": [dict(
        kind=cl.CLOSURE_GLASS, params=dict(color=1.0, roughness=rough, ior=ior,
                                           distribution=cl.DISTRIBUTION_GGX))]}]))
    rng = np.random.default_rng(7 + k + 16 * j + 256 * i + 4096 * side)
    n = 600_000
    c = rng.uniform(-1, 1, n)
    ph = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - c * c)
    wi = np.stack([r * np.cos(ph), r * np.sin(ph), c], -1)
    up = np.array([0.0, 0.0, 1.0])
    f = closure.eval_many(t, 0, [np.sqrt(1 - mu * mu), 0.0, mu], wi, up, up,
                          np.array([1.0, 0.0, 0.0]), side == 0)[:, 0] * 4 * np.pi
    est, err = f.mean(), f.std() / np.sqrt(n)
    got = TABLES["glass_E"][side, k, j, i]
    assert abs(got - est) < 4 * err + 0.005, (got, est, err)
