"""Images that fill in (update_result) and the progressive (SPPM) mode in Blender.

A C RenderEngine's methods cannot be monkeypatched, so ``FakeEngine`` stands in for it:
``render._render`` runs on the real depsgraph and the fake records begin / update / end and
copies of the images written; real ``bpy.ops.render.render`` renders check the same images
reach Blender.
"""

import bpy
import numpy as np
import pytest

from tests.blender import scenes

pytestmark = pytest.mark.blender

W, H = 24, 16


class FakeRect:
    """RenderPass.rect's bpy_prop_array: flat float32 storage set with foreach_set."""

    def __init__(self, size):
        self.data = np.zeros(size, np.float32)

    def foreach_set(self, values):
        assert len(values) == self.data.size
        self.data[:] = values


class FakePass:
    def __init__(self, channels, height, width):
        self.channels, self.shape = channels, (height, width, channels)
        self.rect = FakeRect(height * width * channels)

    def image(self):
        """(H, W, C) top row first, as the core's images."""
        return self.rect.data.reshape(self.shape)[::-1]


class FakeResult:
    def __init__(self, names, height, width):
        self.layers = [type("Layer", (), {})()]
        self.layers[0].passes = {name: FakePass(4 if name in ("Combined", "Photons") else 3,
                                                height, width) for name in names}


class FakeEngine:
    """Records what the engine does with Blender: the calls in order, the partial images
    (Combined at each update_result), the progress fractions and the status texts."""

    def __init__(self, names=("Combined", "Emission", "Environment", "Direct", "Specular",
                              "Caustics", "Indirect"), cancel_at=None):
        self.names, self.cancel_at = names, cancel_at
        self.calls, self.updates, self.fractions, self.stats, self.reports = [], [], [], [], []
        self.result, self.breaks = None, 0

    def begin_result(self, x, y, w, h, layer=None, view=None):
        self.calls.append("begin")
        assert (x, y) == (0, 0) and self.result is None
        self.result = FakeResult(self.names, h, w)
        return self.result

    def update_result(self, result):
        assert result is self.result
        self.calls.append("update")
        self.updates.append(result.layers[0].passes["Combined"].image().copy())

    def end_result(self, result, cancel=False, highlight=False, do_merge_results=False):
        assert result is self.result
        self.calls.append("end_cancel" if cancel else "end")

    def update_progress(self, fraction):
        self.fractions.append(fraction)

    def update_stats(self, stats, info):
        self.stats.append(info)

    def test_break(self):
        self.breaks += 1
        return self.cancel_at is not None and self.breaks >= self.cancel_at

    def report(self, kind, message):
        self.reports.append((set(kind), message))

    def final(self, name="Combined"):
        return self.result.layers[0].passes[name].image()


@pytest.fixture
def lit_plane():
    scenes.photon_map()
    scene = scenes.plane_and_point_light(width=W, height=H)
    scenes.use_photon_map(scene, samples=2, global_photons=3000, caustic_photons=1000,
                          final_gather_rays=4, seed=1)
    return scene


def run(engine):
    from photon_map.photon_engine import render

    render._render(engine, bpy.context.evaluated_depsgraph_get())
    return engine


def test_long_render_fills_in_then_ends_once(lit_plane, monkeypatch):
    from photon_map.core.integrators import photon_mapping as integrator

    monkeypatch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 32)  # many tiles
    monkeypatch.setattr(integrator, "UPDATE_SECONDS", 0.0)  # every tile (1 s in use)
    # ... whatever the updates cost: on a loaded machine the 5 % share skipped some.
    monkeypatch.setattr(integrator, "UPDATE_SHARE", float("inf"))
    engine = run(FakeEngine())
    assert engine.calls[0] == "begin" and engine.calls[-1] == "end"
    assert engine.calls.count("begin") == 1 and engine.calls.count("end") == 1
    assert engine.calls.count("update") >= 3
    final = engine.final()
    lit_rows = []
    for partial in engine.updates:
        # Rows fill from the top: each partial image is the final one so far, then 0.
        done = np.flatnonzero(np.any(partial[..., :3] > 0, axis=(1, 2)))
        rows = done.max() + 1 if done.size else 0
        lit_rows.append(rows)
        np.testing.assert_array_equal(partial[:max(rows - 1, 0)], final[:max(rows - 1, 0)])
        assert np.all(partial[rows:, :, :3] == 0)
    assert lit_rows == sorted(lit_rows) and 0 < lit_rows[0] < H
    # Blender gets the same picture through the real engine.
    real = scenes.render_passes(lit_plane)
    np.testing.assert_allclose(real["Combined"], final, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(real["Direct"], engine.final("Direct"), rtol=1e-6, atol=1e-8)


def test_quick_render_makes_no_partial_update(lit_plane):
    engine = run(FakeEngine())
    assert engine.calls == ["begin", "end"]


def test_esc_keeps_the_partial_image(lit_plane, monkeypatch):
    from photon_map.core.integrators import photon_mapping as integrator

    monkeypatch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 32)
    monkeypatch.setattr(integrator, "UPDATE_SECONDS", 0.0)
    full = run(FakeEngine()).final()
    engine = run(FakeEngine(cancel_at=8))  # photon pass reports, then a few tiles
    assert engine.calls[-1] == "end"
    partial = engine.final()
    rendered = np.any(partial[..., :3] > 0, axis=2)
    assert 0 < rendered.sum() < rendered.size
    np.testing.assert_array_equal(partial[rendered], full[rendered])
    assert any(s.startswith("Photon Map | Cancelled") for s in engine.stats)


# --- progressive ------------------------------------------------------------------------------

def progressive(scene, **values):
    scenes.use_photon_map(scene, integrator='progressive', photons_per_pass=2000, **values)
    return scene


def test_each_pass_updates_the_image_and_the_status(lit_plane, monkeypatch, capfd):
    from photon_map.core.integrators import sppm
    from photon_map.photon_engine import render
    from photon_map.photon_engine.export import export_scene
    from photon_map.photon_engine.properties import to_core_settings

    monkeypatch.setattr(render, "PASS_UPDATE_SECONDS", 0.0)
    progressive(lit_plane, progressive_passes=4)
    engine = run(FakeEngine(names=("Combined",)))
    assert engine.calls == ["begin", "update", "update", "update", "end"]
    texts = [s for s in engine.stats if "Pass " in s]
    assert texts == [f"Photon Map | Progressive: Pass {k} of 4" for k in (1, 2, 3, 4)]
    assert engine.fractions[:4] == [0.25, 0.5, 0.75, 1.0]
    log = capfd.readouterr().out
    assert "Photon Map: Progressive: 4 passes in " in log and "(no time budget)" in log
    assert "radius" in log and "2,000 photons per pass" in log
    # The final image is SPPM's after 4 passes, and the updates its earlier passes.
    depsgraph = bpy.context.evaluated_depsgraph_get()
    settings = to_core_settings(lit_plane.photon_map)
    images = []
    out = sppm.render(export_scene(depsgraph).scene,
                      settings.with_values(progressive_passes=4, photons_per_pass=2000),
                      on_tile=lambda k, image: images.append(image["combined"].copy()))
    np.testing.assert_allclose(engine.final()[..., :3], out.passes["combined"], rtol=1e-6)
    for partial, expected in zip(engine.updates, images):
        np.testing.assert_allclose(partial[..., :3], expected, rtol=1e-6)
    assert not np.allclose(images[0], images[-1])  # the image does change with passes
    # Through Blender: Combined only, the same picture.
    real = scenes.render_passes(lit_plane)
    assert set(real) == {"Combined"}
    np.testing.assert_allclose(real["Combined"][..., :3], out.passes["combined"], rtol=1e-6)


def test_esc_stops_after_the_pass_and_keeps_it(lit_plane):
    progressive(lit_plane, progressive_passes=6)
    engine = run(FakeEngine(names=("Combined",), cancel_at=2))
    assert engine.calls[-1] == "end"
    assert any("Cancelled" in s and "2 passes" in s and "stopped by Esc" in s
               for s in engine.stats)
    lit_plane.photon_map.progressive_passes = 2
    two = run(FakeEngine(names=("Combined",))).final()
    np.testing.assert_array_equal(engine.final(), two)


def test_time_budget_picks_the_pass_count_and_reports_it(lit_plane, capfd):
    progressive(lit_plane, progressive_passes=2)
    run(FakeEngine(names=("Combined",)))  # the kernels are loaded: passes take their time
    capfd.readouterr()
    budget = 3.0
    lit_plane.photon_map.time_budget = budget
    engine = run(FakeEngine(names=("Combined",)))
    out = capfd.readouterr().out
    line = next(l for l in out.splitlines() if "Photon Map: Progressive:" in l)
    passes = int(line.split("Progressive: ")[1].split(" passes")[0])
    took = float(line.split(" passes in ")[1].split(" s")[0])
    assert "(budget 3 s)" in line
    # It ran more passes than the 2 set without a budget, and about fits the budget.
    assert passes > 2, line
    assert 0.5 * budget <= took <= budget + 1.0, line
    assert any(f"Pass {passes} of ~" in s for s in engine.stats)
    fractions = [f for f in engine.fractions if f < 1.0]
    assert fractions == sorted(fractions)
    assert any(f"{passes} passes" in m for _, m in engine.reports)


# --- the Performance panel's Dask Scheduler (issue 17) ---------------------------------------

def test_dask_scheduler_setting_renders_the_same_image_and_esc_stops_it(lit_plane):
    """Dask Scheduler "local:2" (a LocalCluster of two workers, started and stopped by the
    render): the same Combined as this process, bit for bit (the passes merge exactly);
    Esc stops the cluster render with a finite partial image, reported as cancelled."""
    pytest.importorskip("dask.distributed")
    progressive(lit_plane, progressive_passes=6, threads=1)
    here = run(FakeEngine(names=("Combined",))).final()
    lit_plane.photon_map.dask_scheduler = "local:2"
    try:
        there = run(FakeEngine(names=("Combined",)))
        np.testing.assert_array_equal(there.final(), here)
        assert any("connecting to local:2" in s for s in there.stats)
        stopped = run(FakeEngine(names=("Combined",), cancel_at=2))
    finally:
        lit_plane.photon_map.dask_scheduler = ""
    assert stopped.calls[-1] == "end"
    assert any("Cancelled" in s and "stopped by Esc" in s for s in stopped.stats), stopped.stats
    image = stopped.final()
    assert np.isfinite(image).all() and image.min() >= 0.0


def test_dask_local_2_renders_the_demo_like_this_process():
    """The demo (Cornell box with a mirror and a glass sphere: caustic and global photons,
    specular paths) through the Dask Scheduler "local:2": the same Combined bit for bit."""
    pytest.importorskip("dask.distributed")
    from tests.blender import cycles_reference as cref

    scene = cref.demo_scene(resolution=(24, 18))
    progressive(scene, progressive_passes=4, threads=1, seed=3)
    here = run(FakeEngine(names=("Combined",))).final()
    scene.photon_map.dask_scheduler = "local:2"
    try:
        there = run(FakeEngine(names=("Combined",))).final()
    finally:
        scene.photon_map.dask_scheduler = ""
    assert here.mean() > 0.0
    np.testing.assert_array_equal(there, here)
