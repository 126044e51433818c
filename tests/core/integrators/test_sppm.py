"""Stochastic progressive photon mapping (core/integrators/sppm.py): convergence against
references it did not make (the photon-mapping integrator at high settings, cached with
make_caustic_reference.py; the integrator's shadow-ray direct light), the SPPM statistics
rules, bounded memory, cancelling, determinism and scale invariance."""

import pathlib
import tracemalloc

import numpy as np
import pytest

from core.integrators import photon_mapping as integrator
from core.scene import shapes
from core.integrators import camera_paths, sppm
from core.prepared import prepare
from core.scene.contract import CAMERA_ORTHOGRAPHIC, LIGHT_AREA, LIGHT_POINT, Camera, Lights, Materials, Scene
from core.settings import RenderSettings, SettingsError
from tests.core.scenes import caustic_scene
from tests.metrics import rel_mse

DATA = pathlib.Path(__file__).resolve().parents[2] / "data"
SETTINGS = RenderSettings().with_values(threads=1)


def floor_scene(width=16, height=16):
    """Only a floor under a point light: no second bounce is possible, so the full solution
    is the direct light."""
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [2, 0, 0], [0, 2, 0]), 0)])
    mats = Materials.from_list([{"diffuse": [0.8, 0.5, 0.2]}])
    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0.3, 0.2, 1.5],
                                "power": 100.0}])
    cam = shapes.pinhole([0, -2.0, 2.0], [0, 0, 0], width, height, 0.9)
    return Scene(mesh, mats, lights, cam).validate()


def _finite_nonnegative(img):
    assert np.all(np.isfinite(img)), "NaN/Inf in the image"
    assert img.min() >= 0.0, f"negative radiance {img.min()}"


def progressive(scene, settings, passes, photons_per_pass, **values):
    """``sppm.render`` of ``passes`` passes of ``photons_per_pass`` photons; values: other
    settings (progressive_direct, time_budget, ...) and the render's callbacks."""
    callbacks = {k: values.pop(k) for k in ("on_progress", "on_tile", "should_stop")
                 if k in values}
    return sppm.render(scene, settings.with_values(progressive_passes=passes,
                                                   photons_per_pass=photons_per_pass, **values),
                       **callbacks)


def caustic_errors(direct):
    """relMSE at 1, 4, 16, 64 passes against the photon-mapping reference, and the image."""
    ref = np.load(DATA / "pm_caustic_ref.npz")["image"]
    errors = {}
    settings = SETTINGS.with_values(photons_per_pass=25_000, progressive_direct=direct)
    for state in sppm.progressive_passes(caustic_scene(), settings, 64):
        if state.passes in (1, 4, 16, 64):
            img = state.radiance()
            _finite_nonnegative(img)
            errors[state.passes] = rel_mse(img, ref)
    return [errors[k] for k in (1, 4, 16, 64)], img, ref


def test_caustic_converges_to_the_photon_map_reference_faster_with_shadow_rays():
    """Both forms (direct light by shadow rays, the default; and standard SPPM, all by
    photons) converge to the photon-mapping integrator's image of the scene; the hybrid's
    error is below standard SPPM's at every pass count."""
    found = {}
    for direct in sppm.DIRECT_MODES:
        e, img, ref = caustic_errors(direct)
        # Monotone within noise: each 4x more passes must cut the error (by any amount).
        assert all(b < a for a, b in zip(e, e[1:])), (direct, e)
        assert e[-1] < 0.02, (direct, e)
        # The image's mean is right, not just its noise low.
        assert abs(img.mean() / ref.mean() - 1.0) < 0.03, direct
        found[direct] = e
    hybrid, photons = found["shadow_rays"], found["photons"]
    assert all(h < p for h, p in zip(hybrid, photons)), (hybrid, photons)


@pytest.mark.parametrize("direct", sppm.DIRECT_MODES)
def test_floor_converges_to_the_integrators_direct_light(direct):
    """Independent oracle for the photon form: the integrator's shadow rays (different
    code, no photons). The default form uses those shadow rays itself (one per pass):
    there it must agree too, and store no photon (a floor alone has no other path)."""
    scene = floor_scene()
    oracle = integrator.render(scene, RenderSettings().with_values(
        threads=1, samples=64, indirect_mode="off", caustics=False)).passes["combined"]
    out = progressive(scene, SETTINGS, 48, 20_000, progressive_direct=direct)
    img = out.passes["combined"]
    _finite_nonnegative(img)
    assert oracle.mean() > 0.05
    for c in range(3):
        assert abs(img[..., c].mean() / oracle[..., c].mean() - 1.0) < 0.03, c
    assert rel_mse(img, oracle) < 0.01
    if direct == "shadow_rays":
        assert sum(out.stats["photons_stored"]) == 0 and out.stats["rays_shadow"] > 0
    else:
        assert min(out.stats["photons_stored"]) > 0 and out.stats["rays_shadow"] == 0


def test_radius_follows_the_global_schedule():
    """r_k^2 = r_1^2 prod_{j=1}^{k} (j + alpha) / (j + 1) (Knaus & Zwicker), ~ k^(alpha - 1)."""
    alpha, r1 = 0.6, 0.25
    r = sppm.radius_schedule(r1, alpha, 1000)
    assert r[0] == r1 and np.all(np.diff(r) < 0)
    expect = r1 * r1 * np.cumprod(np.r_[1.0, [(j + alpha) / (j + 1) for j in range(1, 1000)]])
    np.testing.assert_allclose(r * r, expect, rtol=1e-12)
    # Asymptotically r_k^2 ~ c k^(alpha - 1): the local slope of log r^2 against log k.
    slope = np.log(r[999] ** 2 / r[499] ** 2) / np.log(1000 / 500)
    assert abs(slope - (alpha - 1)) < 0.01
    # A prefix of a longer schedule is the shorter schedule, bit for bit.
    np.testing.assert_array_equal(sppm.radius_schedule(r1, alpha, 10), r[:10])
    out = progressive(caustic_scene(1.0, 8, 8), SETTINGS, 5, 1_000)
    assert out.stats["radius_max"] == sppm.radius_schedule(out.stats["initial_radius"],
                                                           out.stats["alpha"], 5)[4]


def _renderer(scene, settings):
    from core.prepared import prepare
    prepared = prepare(scene, settings.threads)
    return prepared, sppm.PassRenderer(prepared, settings.validated())


def test_a_pass_rendered_alone_equals_it_inside_a_run():
    """Pass independence: pass k is a function of (scene, settings, k) alone, whatever was
    rendered before it in the same process."""
    scene = caustic_scene(1.0, 16, 16)
    settings = SETTINGS.with_values(photons_per_pass=4_000, progressive_passes=8)
    prepared, r = _renderer(scene, settings)
    try:
        run = [r.render_pass(k, sppm._new_stats()) for k in range(6)]
    finally:
        prepared.close()
    prepared, r = _renderer(scene, settings)
    try:
        alone = r.render_pass(4, sppm._new_stats())
        assert r.radius(4) < r.radius(0)
    finally:
        prepared.close()
    np.testing.assert_array_equal(alone, run[4])
    assert not np.array_equal(run[3], run[4])


def test_blocks_merged_in_any_order_give_the_single_process_image_bit_for_bit():
    scene = caustic_scene(1.0, 16, 16)
    settings = SETTINGS.with_values(photons_per_pass=3_000, progressive_passes=10,
                                    progressive_block=3)
    single = sppm.render(scene, settings).passes["combined"]
    prepared, r = _renderer(scene, settings)
    try:
        blocks = [r.render_block(a, b) for a, b in sppm.pass_blocks(10, 3)]
    finally:
        prepared.close()
    assert [(s.start, s.stop) for s in blocks] == [(0, 3), (3, 6), (6, 9), (9, 10)]
    merged = sppm.ImageSum(16, 16)
    for s in (blocks[2], blocks[0], blocks[3], blocks[1]):
        merged.add(s)
    assert merged.passes == 10 and merged.waiting == 0
    np.testing.assert_array_equal(merged.radiance(), single)
    with pytest.raises(ValueError, match="twice"):
        merged.add(blocks[1])


def _peak_bytes(passes):
    tracemalloc.start()
    try:
        out = progressive(caustic_scene(1.0, 16, 16), SETTINGS, passes, 20_000)
        return tracemalloc.get_traced_memory()[1], out
    finally:
        tracemalloc.stop()


def test_memory_is_bounded_whatever_the_pass_count():
    progressive(caustic_scene(1.0, 8, 8), SETTINGS, 1, 100)  # load the kernels
    few, out_few = _peak_bytes(2)
    many, out_many = _peak_bytes(16)
    # One pass's photons alive at a time: the most held does not grow with passes.
    assert out_many.stats["photons_alive_max"] <= 1.2 * out_few.stats["photons_alive_max"]
    assert len(out_many.stats["photons_stored"]) == 16
    assert out_many.stats["photons_emitted"] == 16 * 20_000
    # A leak of each pass's stored photons (~36 B each, ~2.5k per pass here) would add
    # ~1.2 MB over 14 more passes; per-pass stats lists add a few kB.
    assert many < 1.05 * few + 100_000, (few, many)


def test_cancel_after_pass_k_returns_k_passes():
    seen = []
    stop_after = 3
    out = progressive(caustic_scene(1.0, 16, 16), SETTINGS, 10, 4_000,
                      should_stop=lambda: len(seen) >= stop_after,
                      on_tile=lambda k, passes: seen.append((k, passes["combined"].copy())))
    assert out.cancelled
    assert out.stats["passes"] == stop_after
    assert [k for k, _ in seen] == [1, 2, 3]
    done = progressive(caustic_scene(1.0, 16, 16), SETTINGS, stop_after, 4_000)
    assert not done.cancelled
    np.testing.assert_array_equal(out.passes["combined"], done.passes["combined"])
    np.testing.assert_array_equal(seen[-1][1], done.passes["combined"])


class StepClock:
    """A stand-in for sppm's ``time`` module whose perf_counter advances ``step`` seconds
    a call: the budget's arithmetic is then the same on an idle and a loaded machine."""

    def __init__(self, step):
        self.now, self.step = 0.0, step

    def perf_counter(self):
        self.now += self.step
        return self.now


def test_time_budget_stops_after_the_passes_that_fit(monkeypatch):
    scene = caustic_scene(1.0, 16, 16)
    clock = StepClock(0.001)
    monkeypatch.setattr(sppm, "time", clock)
    one = progressive(scene, SETTINGS, 1, 4_000)
    per_pass = one.stats["time_total"]  # the clock's seconds a pass (its calls x step)
    out = progressive(scene, SETTINGS, 100_000, 4_000, time_budget=0.3)
    assert not out.cancelled
    assert out.stats["stopped_by"] == "time_budget"
    assert 2 <= out.stats["passes"] < 100_000
    # it stops before the pass that would end past the budget, not earlier
    assert out.stats["time_total"] <= 0.3 + clock.step
    assert out.stats["time_total"] + 2 * per_pass > 0.3
    ample = progressive(scene, SETTINGS, 3, 4_000, time_budget=1e6)
    assert ample.stats["passes"] == 3 and ample.stats["stopped_by"] == "passes"
    with pytest.raises(SettingsError, match="time_budget"):
        progressive(scene, SETTINGS, 3, 100, time_budget=-1.0)


def test_deterministic_across_runs_and_threads():
    a = progressive(caustic_scene(1.0, 16, 16), SETTINGS, 4, 4_000).passes["combined"]
    b = progressive(caustic_scene(1.0, 16, 16), SETTINGS.with_values(threads=2), 4,
                    4_000).passes["combined"]
    np.testing.assert_array_equal(a, b)
    c = progressive(caustic_scene(1.0, 16, 16), SETTINGS.with_values(seed=1), 4,
                    4_000).passes["combined"]
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_scale_invariance(scale):
    base = progressive(caustic_scene(1.0, 16, 16), SETTINGS, 8, 8_000)
    scaled = progressive(caustic_scene(scale, 16, 16), SETTINGS, 8, 8_000)
    a, b = scaled.passes["combined"], base.passes["combined"]
    _finite_nonnegative(a)
    np.testing.assert_allclose(scaled.stats["initial_radius"],
                               scale * base.stats["initial_radius"], rtol=1e-6)
    # Same random numbers, scaled geometry: equal up to float32 rounding at the edges.
    assert rel_mse(a, b) < 0.01
    assert abs(a.mean() / b.mean() - 1.0) < 0.01


def test_empty_and_unlit_scenes_are_black_and_finite():
    s = caustic_scene(1.0, 8, 8)
    dark = Scene(s.mesh, s.materials, Lights.empty(), s.camera).validate()
    img = progressive(dark, SETTINGS, 2, 1_000).passes["combined"]
    assert np.all(img == 0.0)


def test_bad_input_raises_errors_naming_the_setting():
    s = caustic_scene(1.0, 8, 8)
    for values, name in (({"progressive_passes": 0}, "progressive_passes"),
                         ({"photons_per_pass": -1}, "photons_per_pass"),
                         ({"progressive_alpha": 1.0}, "progressive_alpha"),
                         ({"progressive_alpha": 0.0}, "progressive_alpha"),
                         ({"progressive_radius": -1.0}, "progressive_radius"),
                         ({"progressive_radius": float("nan")}, "progressive_radius"),
                         ({"progressive_direct": "both"}, "progressive_direct")):
        with pytest.raises(SettingsError, match=name):
            sppm.render(s, SETTINGS.with_values(**{"progressive_passes": 2,
                                                   "photons_per_pass": 100, **values}))


def test_visible_points_see_through_an_area_light():
    # The progressive camera pass passes lights too: light radiance + the emitter behind.
    ceiling = shapes.quad([0, 0, 2], [3, 0, 0], [0, 3, 0])
    if ceiling.normals[0, 0, 2] > 0:
        ceiling = shapes.Part(ceiling.corners[:, ::-1], -ceiling.normals)
    mats = Materials.from_list([{"emission": [0.25, 0.5, 1.0]}])
    light = {"kind": LIGHT_AREA, "position": [0, 0, 1.9], "power": 40.0, "size": [2.0, 2.0],
             "visible_to_camera": True}
    cam = Camera(to_world=shapes.look_at([0, 0, 0], [0, 0, 2], (0, 1, 0)), width=4, height=4,
                 film_size=np.array([0.5, 0.5]), kind=CAMERA_ORTHOGRAPHIC)
    scene = Scene(shapes.assemble([(ceiling, 0)]), mats, Lights.from_list([light]), cam)
    with prepare(scene, 2) as prepared:
        seen = np.zeros((16, 3))
        camera_paths.visible_points(prepared, cam, 3, 0, 2, seen)
    np.testing.assert_allclose(seen, np.broadcast_to(40.0 / (4 * np.pi) + np.array([0.25, 0.5, 1.0]),
                                                     (16, 3)), rtol=1e-6)
