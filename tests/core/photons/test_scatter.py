"""What a photon does at a hit (core/photons/scatter.py ``scatter_kernel``) and the storage
rules (core/photons/store.py ``stores``), on one wavefront built by hand: the rules' truth
table, Russian roulette's expected flux, the mirror law and Lambert's cosine law."""

import itertools

import numpy as np
import pytest
from scipy import stats

from core import sampling
from core.materials import bsdf, closure
from core.photons import scatter
from core.photons.store import (MODE_CAUSTIC, MODE_GLOBAL, STORE_ALL, STORE_BOUNCED,
                                STORE_NOT_DIRECT, stores)
from core.scene import shapes
from core.scene.contract import Materials

# A tilted 2 x 2 m quad, so that the normal's frame is not the world's axes.
_N = np.array([0.3, -0.4, 0.866])
_N /= np.linalg.norm(_N)
_U = np.cross(_N, [1.0, 0.0, 0.0])
_U /= np.linalg.norm(_U)
_V = np.cross(_N, _U)
PLANE = shapes.quad([0.5, -0.2, 0.1], _U, _V)
assert np.allclose(PLANE.normals[0, 0], _N)
NORMAL = _N
DIMS = np.array([sampling.stream(sampling.PHOTON, 1, k) for k in range(4)]
                + [sampling.stream(sampling.WAVELENGTH, 1)], np.int64)


def _directions(rng, n, side=-1.0, min_cos=0.05, max_cos=1.0):
    """n unit directions of travel with side * (d . n) in [min_cos, max_cos]: arriving at
    the front (side -1) or at the back (side +1), uniformly over that part of the sphere."""
    c = rng.uniform(min_cos, max_cos, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    s = np.sqrt(1 - c * c)
    d = (s * np.cos(phi))[:, None] * _U + (s * np.sin(phi))[:, None] * _V + (side * c)[:, None] * _N
    return d


def scatter_wavefront(rows, d, *, flux=None, mode=MODE_GLOBAL, store_rule=STORE_ALL,
                      n_diff=0, n_spec=0, seed=11, bounce=0, last=False, rng=None,
                      nrm=None):
    """Run scatter_kernel on N photons hitting PLANE (both triangles, random barycentrics)
    with material rows[0] (nrm (N, 3): shading normals a program set); returns the
    kernel's outputs and inputs as a dict."""
    rng = rng or np.random.default_rng(5)
    n = d.shape[0]
    mats = Materials.from_list(rows)
    m = bsdf.material_table(mats)
    has_specular = np.any(m["specular"] > 0, axis=1) | np.any(m["transmission"] > 0, axis=1)
    tri_v = PLANE.corners.astype(np.float32)
    tri_n = PLANE.normals.astype(np.float32)
    tri_mat = np.zeros(2, np.int32)
    prim = rng.integers(0, 2, n).astype(np.int32)
    b = rng.random((n, 2))
    b = np.where(b.sum(axis=1, keepdims=True) > 1, 1 - b, b).astype(np.float32)
    d32 = np.ascontiguousarray(d, np.float32)
    flux = np.ascontiguousarray(np.broadcast_to(1.0 if flux is None else flux, (n, 3)),
                                np.float64)
    nd = np.full(n, n_diff, np.int32)
    ns = np.full(n, n_spec, np.int32)
    out = dict(store=np.empty(n, bool), s_pos=np.empty((n, 3), np.float32),
               s_flux=np.empty((n, 3), np.float32), s_dir=np.empty((n, 3), np.float32),
               alive=np.empty(n, bool), o_new=np.empty((n, 3), np.float32),
               d_new=np.empty((n, 3), np.float32), f_new=np.empty((n, 3)))
    scatter.scatter_kernel(tri_v, tri_n, tri_mat, 2.0, closure.table(mats),
                           np.any(m["diffuse"] > 0, axis=1), has_specular, np.zeros((0, 3)),
                           np.zeros(0, np.int32), np.zeros((0, 3)),
                           np.zeros((0, 3)) if nrm is None else np.ascontiguousarray(nrm, np.float64),
                           np.zeros(0), prim,
                           b[:, 0].copy(), b[:, 1].copy(), d32, flux,
                           np.arange(n, dtype=np.int64), nd, ns, np.zeros(n), np.int64(seed), DIMS,
                           np.int64(bounce), mode, np.int64(store_rule), last,
                           out["store"], out["s_pos"], out["s_flux"], out["s_dir"],
                           out["alive"], out["o_new"], out["d_new"], out["f_new"])
    c = tri_v[prim].astype(np.float64)
    out["hit"] = c[:, 0] + b[:, :1] * (c[:, 1] - c[:, 0]) + b[:, 1:] * (c[:, 2] - c[:, 0])
    out.update(d=d32.astype(np.float64), flux=flux, n_diff=nd, n_spec=ns)
    return out


# --- storage rules ----------------------------------------------------------------------

def rule(mode, store_rule, diffuse_lobe, n_diffuse, n_specular):
    """store.py's docstring, written out."""
    if not diffuse_lobe:
        return False  # photons are stored only on surfaces with a diffuse lobe
    if mode == MODE_CAUSTIC:  # light -> S+ -> D: specular bounces and no diffuse one
        return n_specular > 0 and n_diffuse == 0
    if store_rule == STORE_ALL:
        return True
    if store_rule == STORE_BOUNCED:  # after at least one diffuse bounce
        return n_diffuse > 0
    # STORE_NOT_DIRECT: all but the first hit of a photon straight from its source.
    return n_diffuse > 0 or n_specular > 0


COMBOS = list(itertools.product((MODE_GLOBAL, MODE_CAUSTIC),
                                (STORE_ALL, STORE_BOUNCED, STORE_NOT_DIRECT),
                                (False, True), (0, 1, 3), (0, 1, 2)))


def test_stores_truth_table():
    for combo in COMBOS:
        assert stores(*combo) == rule(*combo), combo


def test_stores_caustic_with_a_diffuse_bounce():
    """A caustic path is L S+ D: a photon with a diffuse bounce behind it is not stored
    (scatter_kernel ends caustic photons at their first diffuse bounce anyway)."""
    assert not stores(MODE_CAUSTIC, STORE_ALL, True, 1, 1)


@pytest.mark.parametrize("mode, store_rule", [
    (MODE_GLOBAL, STORE_ALL), (MODE_GLOBAL, STORE_BOUNCED), (MODE_GLOBAL, STORE_NOT_DIRECT),
    (MODE_CAUSTIC, STORE_ALL)])
def test_kernel_stores_by_the_rules(mode, store_rule, rng):
    # The kernel's store flag at a diffuse + glossy surface (a caustic's first surface
    # may be specular) follows the rules for every bounce history, with the photon's
    # position, flux and the direction it came from.
    d = _directions(rng, 64)
    for nd, ns in itertools.product((0, 1, 2), (0, 1, 2)):
        if mode == MODE_CAUSTIC and nd > 0:
            continue
        out = scatter_wavefront([{"diffuse": [0.5] * 3, "specular": [0.3] * 3}], d,
                                flux=[2.0, 1.0, 0.5], mode=mode, store_rule=store_rule,
                                n_diff=nd, n_spec=ns)
        want = rule(mode, store_rule, True, nd, ns)
        assert np.all(out["store"] == want), (nd, ns)
        if want:
            np.testing.assert_allclose(out["s_pos"], out["hit"], atol=1e-6)
            np.testing.assert_array_equal(out["s_flux"], np.float32([[2.0, 1.0, 0.5]] * 64))
            np.testing.assert_allclose(out["s_dir"], -out["d"], atol=1e-7)
    # No diffuse lobe, nothing stored (a mirror).
    out = scatter_wavefront([{"specular": [1.0] * 3}], d, mode=mode, store_rule=store_rule,
                            n_diff=1, n_spec=1)
    assert not out["store"].any() and out["alive"].all()


def test_caustic_photons_end_at_a_diffuse_bounce(rng):
    d = _directions(rng, 20000)
    # First hit on a diffuse-only surface: not a caustic path, dropped.
    out = scatter_wavefront([{"diffuse": [0.9] * 3}], d, mode=MODE_CAUSTIC)
    assert not out["store"].any() and not out["alive"].any()
    # After a specular bounce: stored there, and ends.
    out = scatter_wavefront([{"diffuse": [0.9] * 3}], d, mode=MODE_CAUSTIC, n_spec=1)
    assert out["store"].all() and not out["alive"].any()
    # Diffuse + mirror first surface: not stored; only the mirror lobe carries it on,
    # so no survivor has a diffuse bounce, and about 0.4 of them survive.
    out = scatter_wavefront([{"diffuse": [0.5] * 3, "specular": [0.4] * 3}], d,
                            mode=MODE_CAUSTIC)
    assert not out["store"].any()
    alive = out["alive"]
    assert np.all(out["n_diff"] == 0) and np.all(out["n_spec"][alive] == 1)
    assert abs(alive.mean() - 0.4) < 4 * np.sqrt(0.4 * 0.6 / d.shape[0])


def test_last_bounce_stores_but_does_not_continue(rng):
    out = scatter_wavefront([{"diffuse": [1.0] * 3}], _directions(rng, 100), last=True)
    assert out["store"].all() and not out["alive"].any()


# --- Russian roulette -------------------------------------------------------------------

@pytest.mark.parametrize("rows, survive, weight", [
    ([{"diffuse": [0.3] * 3}], 0.3, [1.0, 1.0, 1.0]),
    ([{"diffuse": [0.75] * 3}], 0.75, [1.0, 1.0, 1.0]),
    # Coloured: roulette by the max channel, then tint / max per channel.
    ([{"diffuse": [0.6, 0.3, 0.0]}], 0.6, [1.0, 0.5, 0.0]),
    # Diffuse and mirror lobes: each chosen with its tint, grey, so the flux is kept.
    ([{"diffuse": [0.4] * 3, "specular": [0.3] * 3}], 0.7, [1.0, 1.0, 1.0]),
])
def test_russian_roulette_keeps_the_expected_flux(rows, survive, weight, rng):
    n = 200_000
    phi = np.array([3.0, 2.0, 1.0]) / n
    out = scatter_wavefront(rows, _directions(rng, n), flux=phi, rng=rng)
    alive = out["alive"]
    # Survivors ~ Binomial(n, p): 4.5 standard deviations.
    tol = 4.5 * np.sqrt(survive * (1 - survive) / n)
    assert abs(alive.mean() - survive) < tol
    # Each survivor carries its flux times tint / p exactly.
    np.testing.assert_allclose(out["f_new"][alive], np.broadcast_to(phi * weight, (alive.sum(), 3)),
                               rtol=1e-12)
    # So the surviving flux over the emitted flux estimates the albedo.
    lobes = sum(np.array(r.get(k, [0.0] * 3)) for r in rows for k in ("diffuse", "specular"))
    ratio = out["f_new"][alive].sum(axis=0) / (phi * n)
    np.testing.assert_allclose(ratio, lobes, atol=tol * max(weight))


def test_lobes_above_one_are_all_sampled_and_weighted_up(rng):
    # diffuse 0.8 + mirror 0.6 > 1: probabilities scaled to 0.8/1.4 and 0.6/1.4, no
    # absorption, every survivor weighted by 1.4; the expected flux is still 0.8 + 0.6.
    n = 100_000
    out = scatter_wavefront([{"diffuse": [0.8] * 3, "specular": [0.6] * 3}],
                            _directions(rng, n), flux=np.full(3, 1.0 / n), rng=rng)
    alive = out["alive"]
    assert alive.mean() > 0.999  # only diffuse directions below the surface are lost
    total = float(np.float32(0.8)) + float(np.float32(0.6))  # the materials' float32 tints
    np.testing.assert_allclose(out["f_new"][alive], total / n, rtol=1e-12)
    frac_mirror = (out["n_spec"][alive] == 1).mean()
    assert abs(frac_mirror - 0.6 / 1.4) < 4.5 * np.sqrt(0.25 / n)


# --- the mirror -------------------------------------------------------------------------

@pytest.mark.parametrize("side", [-1.0, 1.0])  # front, back
def test_mirror_reflects_angle_in_equals_angle_out(side, rng):
    n = 5000
    d = _directions(rng, n, side=side, min_cos=1e-3)
    out = scatter_wavefront([{"specular": [1.0] * 3}], d, flux=[1.0, 0.5, 0.25],
                            n_diff=2, rng=rng)
    assert out["alive"].all() and not out["store"].any()
    o = out["d_new"].astype(np.float64)
    cos_in = d @ NORMAL
    cos_out = o @ NORMAL
    # Angle in = angle out, on the side the photon came from; same plane of incidence.
    np.testing.assert_allclose(cos_out, -cos_in, atol=2e-7)
    np.testing.assert_allclose(o - cos_out[:, None] * NORMAL, d - cos_in[:, None] * NORMAL,
                               atol=2e-7)
    np.testing.assert_allclose(o, d - 2 * cos_in[:, None] * NORMAL, atol=2e-7)
    # Starts off the surface on that side, flux untouched (tint 1), one more specular bounce.
    assert np.all(np.sign((out["o_new"] - out["hit"]) @ NORMAL) == -side)
    np.testing.assert_array_equal(out["f_new"], out["flux"])
    assert np.all(out["n_spec"] == 1) and np.all(out["n_diff"] == 2)


# --- Lambert ----------------------------------------------------------------------------

@pytest.mark.parametrize("side, min_cos, max_cos, seed", [(-1.0, 0.05, 1.0, 1), (1.0, 0.9, 1.0, 2),
                                                          (-1.0, 1e-3, 0.05, 3)])  # grazing
def test_diffuse_bounce_is_cosine_distributed(side, min_cos, max_cos, seed, rng):
    # Whatever the arrival direction (front, back, grazing), the new direction follows
    # the cosine law about the normal on the arrival side. (The local direction depends
    # only on the photon's random numbers, so each case gets its own seed.)
    d = _directions(rng, 100_000, side=side, min_cos=min_cos, max_cos=max_cos)
    out = scatter_wavefront([{"diffuse": [1.0] * 3}], d, seed=seed, rng=rng)
    alive = out["alive"]
    assert alive.mean() > 0.9999  # albedo 1: only degenerate directions are lost
    assert np.all(out["n_diff"][alive] == 1)
    o = out["d_new"][alive].astype(np.float64)
    normal = -side * NORMAL  # the side the photon arrived on
    cos = o @ normal
    assert cos.min() > 0.0
    # Lambert: pdf(w) = cos / pi, so P(cos theta <= c) = c^2.
    edges = np.linspace(0.0, 1.0, 21)
    observed, _ = np.histogram(np.clip(cos, 0, 1), edges)
    expected = np.diff(edges ** 2) * cos.shape[0]
    p = stats.chisquare(observed, expected).pvalue
    assert p > 0.01, p  # measured p = 0.72, 0.45, 0.086 (seeds 1, 2, 3)
    # And uniform in azimuth about the normal.
    t = o - cos[:, None] * normal
    phi = np.arctan2(t @ np.cross(normal, _U), t @ _U)
    observed, _ = np.histogram(phi, np.linspace(-np.pi, np.pi, 17))
    p_phi = stats.chisquare(observed).pvalue
    assert p_phi > 0.01, p_phi  # measured 0.71, 0.11, 0.66
    # Leaves from just above the surface on that side, flux kept (albedo 1).
    assert np.all((out["o_new"][alive] - out["hit"][alive]) @ normal > 0)
    np.testing.assert_array_equal(out["f_new"][alive], out["flux"][alive])


def test_a_program_normal_turns_the_diffuse_bounce(rng):
    # A shader program's normal (Normal Map / Bump, nrm) is the one the bounce samples
    # about: Lambert about a normal tilted 20 degrees from the face's has its mean
    # direction (2/3 n for the full cosine lobe) along the tilted normal, not the face's.
    d = _directions(rng, 100_000, side=-1.0)
    tilt = np.radians(20.0)
    bent = np.cos(tilt) * NORMAL + np.sin(tilt) * _U
    out = scatter_wavefront([{"diffuse": [1.0] * 3}], d, rng=rng,
                            nrm=np.tile(bent, (d.shape[0], 1)))
    o = out["d_new"][out["alive"]].astype(np.float64)
    mean = o.mean(axis=0)
    # Brute force: the cosine lobe about the bent normal (about the face's where the
    # photon arrives from below the bent normal: closure._local), without the directions
    # below the face (a bounce cannot leave through the surface), sampled in numpy.
    wo = -np.repeat(d, 4, axis=0)
    n = np.where((wo @ bent > 1e-7)[:, None], bent, NORMAL)
    x = np.cross(n, _V)
    x /= np.linalg.norm(x, axis=1)[:, None]
    y = np.cross(n, x)
    r1, r2 = rng.random(wo.shape[0]), rng.random(wo.shape[0])
    ct, st = np.sqrt(1 - r1), np.sqrt(r1)
    w = (st * np.cos(2 * np.pi * r2))[:, None] * x + (st * np.sin(2 * np.pi * r2))[:, None] * y \
        + ct[:, None] * n
    want = w[w @ NORMAL > 0].mean(axis=0)
    angle = np.degrees(np.arccos(mean @ want / np.linalg.norm(mean) / np.linalg.norm(want)))
    assert angle < 0.5, angle
    assert np.degrees(np.arccos(mean @ NORMAL / np.linalg.norm(mean))) > 15.0
    # A zero row keeps the interpolated normal.
    out = scatter_wavefront([{"diffuse": [1.0] * 3}], d, rng=rng, nrm=np.zeros_like(d))
    o = out["d_new"][out["alive"]].astype(np.float64)
    mean = o.mean(axis=0)
    assert np.degrees(np.arccos(mean @ NORMAL / np.linalg.norm(mean))) < 0.5
