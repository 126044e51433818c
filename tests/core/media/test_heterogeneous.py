"""Heterogeneous density (docs/volumes.md "Heterogeneous density"): the batched trackers
against closed forms, the program-driven density of a mesh medium, the majorant, and a
heterogeneous albedo-1 box in a white furnace."""

import dataclasses

import numpy as np
import pytest
from scipy import stats

from core import prepared as prepared_mod
from core.integrators import photon_mapping, volume
from core.media import tracking
from core.media.density import measure_majorant, principled_volume_coefficients
from core.scene import shapes
from core.scene.contract import CAMERA_ORTHOGRAPHIC, Camera, Lights, Materials, Mesh, Scene, World
from core.scene.media import Media
from core.settings import RenderSettings
from core.shading import program as pg

pytestmark = pytest.mark.core


def _ramp(points, field):
    """rho(x) = x on [0, 1] (the test segments run along x from 0)."""
    return np.clip(points[:, 0], 0.0, None)


RHO_C, ABSORB = 2.0, np.array([0.2, 0.5, 0.8])


def _colour_ramp(points, field=None):
    """A Principled Volume of density 2 whose Color varies along x: C(x) = (x, 0.5 + 0.4
    sin(2 pi x), 1 - x) on [0, 1], Absorption Color (0.2, 0.5, 0.8): its extinction per
    channel (K, 3), 1/m (at most rho: C + (1 - C)(1 - sqrt A) <= 1)."""
    x = np.clip(points[:, 0], 0.0, 1.0)
    color = np.stack([x, 0.5 + 0.4 * np.sin(2 * np.pi * x), 1.0 - x], axis=1)
    sa, ss = principled_volume_coefficients(np.full(x.shape, RHO_C), color, ABSORB)
    return sa + ss


def test_ratio_tracking_through_a_varying_colour_is_exp_minus_its_optical_depth():
    """The per-channel density (a Principled Volume's Color varying along x, issue 16),
    sigma_t,c = 1/m scaled by the factors (K, 3), majorant rho = 2: the mean of 200k walks
    = exp(-the numerical integral of sigma_t,c over [0, 1]) within 4 standard errors."""
    from scipy.integrate import quad

    n = 200_000
    T = tracking.ratio_tracking_batch(_colour_ramp, np.zeros((n, 3)),
                                      np.tile([1.0, 0, 0], (n, 1)), 0.0, 1.0,
                                      np.zeros(n, np.int64), np.ones(3), RHO_C, 11, 3)
    tau = [quad(lambda x, c=c: _colour_ramp(np.array([[x, 0.0, 0.0]]))[0, c], 0.0, 1.0,
                limit=200)[0] for c in range(3)]
    exact = np.exp(-np.array(tau))
    mean, se = T.mean(axis=0), T.std(axis=0) / np.sqrt(n)
    print(mean, exact, se)
    assert np.all(np.abs(mean - exact) < 4 * se + 1e-12), (mean, exact, se)
    assert np.all(np.abs(mean - exact) < 3e-3) and T.min() >= 0.0
    # The albedo really varies: red scatters more at x = 1, blue at x = 0
    sa, ss = principled_volume_coefficients(np.full(2, RHO_C),
                                            [[0.0, 0.5, 1.0], [1.0, 0.5, 0.0]], ABSORB)
    assert ss[1, 0] > ss[0, 0] and ss[0, 2] > ss[1, 2] and np.all(sa >= 0.0)


def _colour_ramp_split(points, field=None):
    """_colour_ramp's (sigma_a, sigma_s) per channel as delta tracking's (K, 6) factors of
    unit rho_a, rho_s."""
    x = np.clip(points[:, 0], 0.0, 1.0)
    color = np.stack([x, 0.5 + 0.4 * np.sin(2 * np.pi * x), 1.0 - x], axis=1)
    sa, ss = principled_volume_coefficients(np.full(x.shape, RHO_C), color, ABSORB)
    return np.concatenate([sa, ss], axis=1)


def test_single_scattering_in_a_varying_colour_matches_the_integral():
    """Delta tracking of flights along x over [0, 1] m through _colour_ramp's medium with
    the per-channel (K, 6) factors: E[w; scattered] = integral of sigma_s,c T_c, E[w;
    passed] = T_c(1) (numerical integrals), within 4 standard errors, 200k flights."""
    from scipy.integrate import quad

    n = 200_000
    t, scattered, w = tracking.delta_tracking_batch(
        _colour_ramp_split, np.zeros((n, 3)), np.tile([1.0, 0, 0], (n, 1)), 0.0, 1.0,
        np.zeros(n, np.int64), 0.0, 0.0, np.ones(3), np.ones(3), RHO_C, 13, 5)

    def tau(x, c):
        return quad(lambda y: _colour_ramp(np.array([[y, 0.0, 0.0]]))[0, c], 0.0, x,
                    limit=200)[0]

    def sigma_s(x, c):
        return _colour_ramp_split(np.array([[x, 0.0, 0.0]]))[0, 3 + c]
    for c in range(3):
        scat = quad(lambda x: sigma_s(x, c) * np.exp(-tau(x, c)), 0.0, 1.0, limit=100)[0]
        est = np.where(scattered, w[:, c], 0.0)
        assert abs(est.mean() - scat) < 4 * est.std() / np.sqrt(n), (c, est.mean(), scat)
        passed = np.where(scattered, 0.0, w[:, c])
        T1 = np.exp(-tau(1.0, c))
        assert abs(passed.mean() - T1) < 4 * passed.std() / np.sqrt(n), (c, passed.mean(), T1)
    assert np.all(np.isfinite(w)) and w.min() >= 0.0


def test_a_per_channel_density_above_the_majorant_is_refused():
    def over(points, field):
        return np.tile([0.5, 1.5, 0.5], (points.shape[0], 1))
    with pytest.raises(tracking.MajorantExceeded, match="outside"):
        tracking.ratio_tracking_batch(over, np.zeros((4, 3)), np.tile([1.0, 0, 0], (4, 1)),
                                      0.0, 10.0, np.zeros(4, np.int64), np.ones(3), 1.0, 1, 3)


def test_ratio_tracking_through_a_linear_ramp_is_exp_minus_the_optical_depth():
    """rho = x over [0, 1] m, sigma_t = (0.5, 2, 4)/m: E[T] = exp(-sigma_t / 2); the mean of
    400k walks within 1e-3 (and within 4 standard errors)."""
    n = 400_000
    sigma = np.array([0.5, 2.0, 4.0])
    T = tracking.ratio_tracking_batch(_ramp, np.zeros((n, 3)), np.tile([1.0, 0, 0], (n, 1)),
                                      0.0, 1.0, np.zeros(n, np.int64), sigma, 1.0, 7, 3)
    exact = np.exp(-sigma / 2)
    mean, se = T.mean(axis=0), T.std(axis=0) / np.sqrt(n)
    assert np.all(np.abs(mean - exact) < 1e-3), (mean, exact)
    assert np.all(np.abs(mean - exact) < 4 * se + 1e-12), (mean, exact, se)
    assert T.min() >= 0.0


def test_delta_tracking_distances_follow_the_ramps_distribution_chi2():
    """Albedo 1, grey, rho = x over [0, 2] m, sigma_s = 1.5/m: collision density
    sigma x exp(-sigma x^2 / 2) (every weight 1), passing probability exp(-2 sigma);
    chi-square of 200k flights over 30 equal-probability bins + the passing bin."""
    n, L, sig = 200_000, 2.0, 1.5
    t, scattered, w = tracking.delta_tracking_batch(
        _ramp, np.zeros((n, 3)), np.tile([1.0, 0, 0], (n, 1)), 0.0, L, np.zeros(n, np.int64),
        0.0, 0.0, 0.0, sig, L, 11, 5)
    np.testing.assert_allclose(w, 1.0, rtol=1e-12)
    cdf = lambda x: 1.0 - np.exp(-sig * x ** 2 / 2)  # noqa: E731
    p_pass = 1.0 - cdf(L)
    edges = np.sqrt(-2.0 * np.log(1.0 - np.linspace(0, cdf(L), 31)) / sig)
    counts = np.histogram(t[scattered], edges)[0]
    observed = np.append(counts, (~scattered).sum())
    expected = np.append(np.full(30, n * cdf(L) / 30), n * p_pass)
    assert stats.chisquare(observed, expected).pvalue > 1e-3
    assert np.all(t[~scattered] == L)


def test_a_density_above_the_majorant_raises_naming_it():
    with pytest.raises(tracking.MajorantExceeded, match="majorant"):
        tracking.ratio_tracking_batch(_ramp, np.zeros((4, 3)), np.tile([1.0, 0, 0], (4, 1)),
                                      0.0, 5.0, np.zeros(4, np.int64), np.ones(3), 1.0, 1, 1)


def _ramp_instructions():
    """Input Generated (registers 0-2) -> Separate -> Math Add: register 6 = 2 x
    Generated.x."""
    ins = np.full((3, pg.INSTRUCTION_WIDTH), -1, np.int32)
    ins[:, 1:pg.FIRST_OPERAND] = 0
    f = pg.FIRST_OPERAND
    ins[0, 0], ins[0, 1], ins[0, f] = pg.OP_INPUT, pg.SOURCE_GENERATED, 0   # regs 0-2
    ins[1, 0], ins[1, f:f + 4] = pg.OP_SEPARATE, (0, 3, 4, 5)               # x, y, z
    ins[2, 0], ins[2, 1], ins[2, f:f + 4] = pg.OP_MATH, 0, (3, 3, 3, 6)     # 0 = ADD
    return ins


def _gradient_program():
    """rho = 2 x Generated.x (``_ramp_instructions``)."""
    return pg.ShaderProgram.build(_ramp_instructions(), [], [[6, pg.TARGET_DENSITY, 0, 0]], 7,
                                  name="ramp")


def _ramp_box(sigma_s=(0.0, 0.0, 0.0), sigma_a=(0.0, 0.0, 0.0), g=0.0):
    """A 2 m box from -1 to 1 whose density is 2 x Generated.x = x + 1 (0 to 2)."""
    lo, hi = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    return Media.from_list([{"bounds": 0, "name": "Ramp", "boundary": shapes.box(lo, hi).corners,
                             "sigma_s": sigma_s, "sigma_a": sigma_a, "anisotropy": g,
                             "density_texture": 0}],
                           programs=(_gradient_program(),))


def _scene(media, world=1.0):
    cam = Camera(to_world=shapes.look_at([0, -5, 0], [0, 0, 0], (0, 0, 1)), width=12,
                 height=12, film_size=np.array([1.6, 1.6]), kind=CAMERA_ORTHOGRAPHIC)
    # The box object: identity transform, texture space -1..1 (Generated = (x + 1) / 2)
    mesh = dataclasses.replace(Mesh.empty(), object_names=("Box",),
                               object_to_world=np.eye(4)[None],
                               object_texspace=np.array([[[0.0, 0, 0], [1.0, 1, 1]]]))
    return Scene(mesh, Materials.from_list([{"diffuse": [0, 0, 0]}]), Lights.empty(), cam,
                 world=World(radiance=np.full(3, world, np.float32)), media=media).validate()


def test_a_programs_density_gives_the_transmittance_of_its_optical_depth():
    """The ramp box (rho = x + 1) through the shader program: rays along +x cross optical
    depth sigma_t * 2 (the integral of x + 1 over [-1, 1]), rays along y at x = 0.5 cross
    sigma_t * 1.5 * 2; the mean of 200k ratio-tracking estimates within 4 standard errors
    and 2e-3. The majorant measured on the lattice covers rho's maximum 2."""
    sigma = np.array([0.1, 0.3, 0.6])
    scene = _scene(_ramp_box(sigma_a=sigma))
    prep = prepared_mod.prepare(scene, 1)
    med = prep.medium
    assert 2.0 <= med.fields.majorant[0] <= 2.0 * 1.5 + 1e-6
    n = 200_000
    for o, d, depth in (([-3, 0.2, 0.1], [1, 0, 0], 2.0), ([0.5, -3, 0.3], [0, 1, 0], 3.0)):
        T = med.transmittance(np.tile(o, (n, 1)), np.tile(d, (n, 1)), np.full(n, 10.0))
        exact = np.exp(-sigma * depth)
        mean, se = T.mean(axis=0), T.std(axis=0) / np.sqrt(n)
        assert np.all(np.abs(mean - exact) < np.minimum(4 * se + 1e-9, 2e-3)), (mean, exact)
    prep.close()


def test_automatic_volume_light_samples_follow_the_density():
    """Volume Light Samples 0 (automatic): AUTO_SAMPLES_VARYING (4) when a medium's density
    varies (its shadow rays are tracked), AUTO_SAMPLES_HOMOGENEOUS (16) for the same box of
    constant density; a hand-set count is taken as it is."""
    assert (volume.AUTO_SAMPLES_VARYING, volume.AUTO_SAMPLES_HOMOGENEOUS) == (4, 16)
    varying = _scene(_ramp_box(sigma_s=(0.5, 0.5, 0.5)))
    constant = dataclasses.replace(varying, media=dataclasses.replace(
        varying.media, density_texture=np.full_like(varying.media.density_texture, -1)))
    for scene, want in ((varying, 4), (constant, 16)):
        prep = prepared_mod.prepare(scene, 1)
        try:
            assert volume.prepare(RenderSettings(), prep, 4).light_samples == want
            st = RenderSettings(volume_light_samples=7)
            assert volume.prepare(st, prep, 4).light_samples == 7
        finally:
            prep.close()


def test_the_majorant_bounds_a_smooth_field_and_clipping_is_reported():
    rho = lambda p: 1.0 + np.sin(3.0 * p[:, 0])  # noqa: E731
    maj = measure_majorant(rho, [0, 0, 0], [2, 1, 1])
    assert 2.0 <= maj <= 3.0 + 1e-9


def test_a_heterogeneous_albedo_one_box_in_a_white_furnace_conserves_energy():
    """The ramp box (density 0 to 2, sigma_s 1.5/m at density 1: optical depth 0 to 6
    across, 3 on average), g = 0.3, no surface, World radiance 1: every camera ray must see
    radiance 1; the image mean of Combined within 2 % per channel, every pixel finite and
    >= 0."""
    scene = _scene(_ramp_box(sigma_s=(1.5, 1.5, 1.5), g=0.3))
    st = RenderSettings(samples=4, caustics=False, indirect_mode="preview",
                        global_photons=100_000, photon_max_bounces=256, threads=2, seed=5)
    out = photon_mapping.render(scene, st).passes
    comb = out["combined"].astype(np.float64)
    assert np.all(np.isfinite(comb)) and comb.min() >= 0
    mean = comb.reshape(-1, 3).mean(axis=0)
    print("furnace mean", mean)
    np.testing.assert_allclose(mean, 1.0, rtol=0.02)


def test_ratio_tracking_follows_the_render_seed():
    """The transmittance walks of ``Medium.stretches`` are keyed by the render seed
    (``prepare(..., seed)``): the same seed gives the same estimates, another seed others
    (both unbiased)."""
    scene = _scene(_ramp_box(sigma_a=(0.5, 0.5, 0.5)))
    n = 64
    o, d = np.tile([-3.0, 0.2, 0.1], (n, 1)), np.tile([1.0, 0.0, 0.0], (n, 1))
    out = []
    for seed in (1, 1, 2):
        prep = prepared_mod.prepare(scene, 1, seed)
        out.append(prep.medium.transmittance(o, d, np.full(n, 10.0)))
        prep.close()
    np.testing.assert_array_equal(out[0], out[1])
    assert not np.array_equal(out[0], out[2])


def test_a_varying_density_beside_a_homogeneous_medium_in_the_same_mesh_adds():
    """An Add / Mix of a varying density and a homogeneous medium exports as two rows in
    the same object (photon_engine/export_volumes.py): the ramp box (rho = x + 1, optical
    depth 2 sigma_het along x) and a homogeneous sigma_hom over the same boundary: the mean
    transmittance along x = exp(-(2 sigma_het + 2 sigma_hom)) within 4 standard errors."""
    lo, hi = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    corners = shapes.box(lo, hi).corners
    het, hom = np.array([0.1, 0.3, 0.6]), np.array([0.2, 0.0, 0.05])
    media = Media.from_list([{"bounds": 0, "name": "Ramp", "boundary": corners,
                              "sigma_a": het, "density_texture": 0},
                             {"bounds": 0, "name": "Ramp (homogeneous part)",
                              "boundary": corners, "sigma_a": hom}],
                            programs=(_gradient_program(),))
    prep = prepared_mod.prepare(_scene(media), 1)
    n = 100_000
    T = prep.medium.transmittance(np.tile([-3, 0.2, 0.1], (n, 1)), np.tile([1.0, 0, 0], (n, 1)),
                                  np.full(n, 10.0))
    exact = np.exp(-2.0 * het - 2.0 * hom)
    mean, se = T.mean(axis=0), T.std(axis=0) / np.sqrt(n)
    assert np.all(np.abs(mean - exact) < 4 * se + 1e-9), (mean, exact)
    prep.close()


def _colour_program():
    """Seven outputs (a varying colour, core/scene/media.py): rho = 2 x Generated.x, Color
    = Absorption Color = Generated (gx, gy, gz) (``_ramp_instructions``)."""
    outputs = [[6, pg.TARGET_DENSITY, 0, 0]] + [[c, pg.TARGET_DENSITY, 0, 1 + c]
                                               for c in range(3)] \
        + [[c, pg.TARGET_DENSITY, 0, 4 + c] for c in range(3)]
    return pg.ShaderProgram.build(_ramp_instructions(), [], outputs, 7, name="colour ramp")


def test_a_colour_programs_medium_gives_the_transmittance_of_its_per_channel_depth():
    """The ramp box (rho = x + 1) whose Color and Absorption Color are its Generated
    coordinates (so the albedo varies along x), row weights sigma_s (1, 0.5, 2), sigma_a
    (0.5, 1, 1.5): Medium.transmittance along x at (y, z) = (0.2, 0.1) against exp(-the
    numerical integral of rho (w_s C + w_a max(1 - C, 0) max(1 - sqrt C, 0))) per channel,
    the mean of 200k walks within 4 standard errors and 2e-3; the grid bounds the largest
    factor (rho C <= 2); the scattering factor at a point is rho C."""
    from scipy.integrate import quad

    ws, wa = np.array([1.0, 0.5, 2.0]), np.array([0.5, 1.0, 1.5])
    media = Media.from_list([{"bounds": 0, "name": "Tinted", "sigma_s": ws, "sigma_a": wa,
                              "boundary": shapes.box(np.full(3, -1.0), np.full(3, 1.0)).corners,
                              "density_texture": 0}], programs=(_colour_program(),))
    prep = prepared_mod.prepare(_scene(media), 1)
    med = prep.medium
    assert med.fields.colour == {0}
    assert 2.0 <= med.fields.majorant[0] <= 3.0 + 1e-6
    y, z = 0.2, 0.1
    gy, gz = (y + 1) / 2, (z + 1) / 2

    def sigma_t(x, c):
        col = ((x + 1) / 2, gy, gz)[c]
        return (x + 1) * (ws[c] * col + wa[c] * (1 - col) * (1 - np.sqrt(col)))
    exact = np.exp(-np.array([quad(sigma_t, -1.0, 1.0, args=(c,))[0] for c in range(3)]))
    n = 200_000
    T = med.transmittance(np.tile([-3.0, y, z], (n, 1)), np.tile([1.0, 0, 0], (n, 1)),
                          np.full(n, 10.0))
    mean, se = T.mean(axis=0), T.std(axis=0) / np.sqrt(n)
    print("colour transmittance", mean, exact, se)
    assert np.all(np.abs(mean - exact) < np.minimum(4 * se + 1e-9, 2e-3)), (mean, exact, se)
    p = np.array([[0.5, y, z]])  # the render frame is the world here (no Mesh.origin)
    np.testing.assert_allclose(med.fields.scattering(p, [0]),
                               [[1.5 * 0.75, 1.5 * gy, 1.5 * gz]], rtol=1e-6)
    assert not med.fields.warnings()
    prep.close()


def test_a_density_program_of_two_outputs_is_refused_naming_it():
    """A density program has one output or seven (density, Color, Absorption Color)."""
    from core.scene.checks import SceneError

    prog = _colour_program()
    two = dataclasses.replace(prog, outputs=prog.outputs[:2])
    media = Media.from_list([{"bounds": 0, "name": "Odd", "density_texture": 0,
                              "boundary": shapes.box(np.full(3, -1.0), np.full(3, 1.0)).corners}],
                            programs=(two,))
    with pytest.raises(SceneError, match="colour ramp.*one output.*or 7"):
        media.validate(1)
    dataclasses.replace(media, programs=(prog,)).validate(1)


def test_a_world_volume_of_varying_density_fills_the_scenes_box():
    """A World fog whose density is the ramp program (rho = 2 x Generated.x; the World's
    Generated is the position, as in Cycles without an object: rho = max(2 x, 0)) beside a
    clear 2 m box: its varying part fills the scene's box (the box, the camera at y = -5,
    widened by 1 % of the diagonal, core/prepared.py world_medium_box) and nothing beyond.
    Rays along +x entering the box (from x = -3) and along +y from inside it (at x = 0.5),
    one ending at 10 m, one escaping: the mean of 200k ratio-tracking walks against
    exp(-sigma the analytic integral of rho) within 4 standard errors and 2e-3; the sun's
    light reaches the box unattenuated (World sigma_t 0 for light from infinity)."""
    sigma = np.array([0.1, 0.3, 0.6])
    media = Media.from_list([
        {"name": "Fog", "sigma_a": sigma, "density_texture": 0},
        {"bounds": 0, "name": "Clear", "boundary": shapes.box(np.full(3, -1.0), np.full(3, 1.0)).corners}],
        programs=(_gradient_program(),))
    scene = _scene(media)
    lo, hi = prepared_mod.world_medium_box(scene)
    pad = 0.01 * np.sqrt(2.0 ** 2 + 6.0 ** 2 + 2.0 ** 2)
    np.testing.assert_allclose(lo, [-1 - pad, -5 - pad, -1 - pad])
    np.testing.assert_allclose(hi, [1 + pad, 1 + pad, 1 + pad])
    prep = prepared_mod.prepare(scene, 1)
    med = prep.medium
    assert np.all(med.world_sigma_t == 0.0)
    n = 200_000
    # Along x at (y, z) = (0.2, 0.1): the integral of 2 x over [0, hi_x]; along y at x = 0.5:
    # rho = 1 over [-3, hi_y]
    for o, d, depth in (([-3, 0.2, 0.1], [1, 0, 0], hi[0] ** 2),
                        ([0.5, -3, 0.3], [0, 1, 0], hi[1] + 3.0)):
        for t_end in (10.0, np.inf):
            T = med.transmittance(np.tile(o, (n, 1)), np.tile(d, (n, 1)), np.full(n, t_end))
            exact = np.exp(-sigma * depth)
            mean, se = T.mean(axis=0), T.std(axis=0) / np.sqrt(n)
            assert np.all(np.abs(mean - exact) < np.minimum(4 * se + 1e-9, 2e-3)), \
                (o, t_end, mean, exact)
    assert not med.fields.warnings()
    prep.close()


def test_a_varying_medium_renders_the_same_whatever_the_tiling(monkeypatch):
    """The camera pass's tiles adapt to the time they take, so a seeded render must not
    depend on which rays share a batch: the ratio-tracking walks of a heterogeneous medium
    are keyed by each segment's origin, direction and stretch within its ray, not by its
    place in the batch (an absorbing ramp box seen against World light 1, one tile against
    tiles of 16 samples)."""
    scene = _scene(_ramp_box(sigma_a=(0.5, 0.8, 1.1)))
    st = RenderSettings(samples=4, caustics=False, indirect_mode="off", threads=1, seed=7)
    whole = photon_mapping.render(scene, st)
    monkeypatch.setattr(photon_mapping, "TARGET_SAMPLES_PER_TILE", 16)
    tiled = photon_mapping.render(scene, st)
    assert tiled.stats["tiles"] > 5 and whole.stats["tiles"] == 1
    assert 0.0 < whole.passes["combined"].min() < whole.passes["combined"].max() < 1.0
    for k, v in whole.passes.items():
        np.testing.assert_array_equal(tiled.passes[k], v, err_msg=k)
