"""The engine end to end through ``bpy.ops.render.render()``: pixels in the Render Result,
progress, cancel, and bad input ending as a message (or a correct black image)."""

import bpy
import numpy as np
import pytest

from tests.blender import scenes

pytestmark = [pytest.mark.blender, pytest.mark.api]

W, H = 32, 24


@pytest.fixture
def pm():
    return scenes.photon_map()


def lit_plane(samples=4, **light):
    """32x24 view straight down (+Y up, +X right in the image) on a 4 m grey plane."""
    scene = scenes.plane_and_point_light(width=W, height=H)
    if light:
        point = bpy.data.objects["Point"]
        for key, value in light.items():
            setattr(point, key, value)
    scenes.use_photon_map(scene, samples=samples)
    return scene


def test_every_core_pass_has_a_blender_pass(pm):
    from photon_map.core import passes
    from photon_map.photon_engine.render import EXTRA_PASSES

    assert set(passes.PASSES) <= set(EXTRA_PASSES)
    # ... under the names core/passes.py gives them (what the EXR writer uses too).
    for core_name, blender_name in EXTRA_PASSES.items():
        assert passes.BLENDER_PASS_NAMES[core_name] == blender_name, core_name


def test_stats_say_which_maps_were_built_and_why_not(pm):
    from photon_map.photon_engine.render import photon_log, photon_summary

    stats = {"caustic_photons_stored": 0, "global_photons_stored": 1234,
             "skipped": {"caustics": "no mirror, glass or glossy surface in the scene"},
             "global_radius": 0.25, "photon_maps": {"decisions": ["caustic map skipped: x"]}}
    line = photon_summary(stats)
    assert "global map 1,234 photons" in line and "no caustic map (no mirror" in line
    log = photon_log(stats)
    assert "caustic map skipped: x" in log and any("0.25 m" in l for l in log)


def test_render_result_holds_finite_passes(pm):
    lit_plane()
    passes = scenes.render_passes()
    combined = passes["Combined"]
    assert combined.shape == (H, W, 4)
    rgb = combined[..., :3]
    assert np.isfinite(rgb).all() and rgb.min() >= 0.0 and rgb.max() > 0.0
    assert np.all(combined[..., 3] == 1.0)
    # A grey Lambert plane under a point light: all of it is direct light, nothing else
    # (the plane cannot light itself: no indirect light; nothing specular: no caustics).
    assert {"Emission", "Environment", "Direct", "Specular", "Caustics", "Indirect"} <= set(passes)
    np.testing.assert_allclose(passes["Direct"], rgb, rtol=1e-6, atol=1e-9)
    for name in ("Emission", "Environment", "Specular", "Caustics", "Indirect"):
        assert np.all(passes[name] == 0.0), name


def test_image_is_not_upside_down(pm):
    """The camera looks down -Z with +Y up: a light over the (+X, +Y) corner of the plane
    must light the top-right of the picture (Blender's rect is stored bottom row first)."""
    lit_plane(location=(1.2, 0.9, 0.3))
    luminance = scenes.render_passes()["Combined"][..., :3].sum(axis=2)
    row, col = np.unravel_index(np.argmax(luminance), luminance.shape)
    assert row < H // 4 and col > 3 * W // 4, (row, col)
    assert luminance[: H // 2].mean() > 2 * luminance[H // 2:].mean()
    assert luminance[:, W // 2:].mean() > 2 * luminance[:, : W // 2].mean()


class ProgressLog:
    """Wraps render.progress_callbacks: records every progress call, and answers "stop"
    from the ``cancel_after``-th call on (what Esc does through test_break)."""

    def __init__(self, monkeypatch, cancel_after=None):
        from photon_map.photon_engine import render

        self.calls, self.cancel_after = [], cancel_after
        original = render.progress_callbacks

        def factory(engine):
            blender_progress, blender_stop = original(engine)

            def progress(fraction, message):
                blender_progress(fraction, message)  # the real update_progress/stats
                self.calls.append((fraction, message))

            def stop():
                if self.cancel_after is not None and len(self.calls) >= self.cancel_after:
                    return True
                return blender_stop()

            return progress, stop

        monkeypatch.setattr(render, "progress_callbacks", factory)


def test_progress_reaches_one(pm, monkeypatch):
    from photon_map.core.integrators import photon_mapping as integrator

    monkeypatch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 64)  # many small tiles
    lit_plane(samples=2)
    log = ProgressLog(monkeypatch)
    scenes.render_passes()
    fractions = [f for f, _ in log.calls]
    assert len(fractions) >= 3
    assert all(0.0 <= f <= 1.0 for f in fractions)
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert all(isinstance(m, str) and m for _, m in log.calls)


def test_cancel_stops_early_and_keeps_the_rendered_part(pm, monkeypatch):
    from photon_map.core.integrators import photon_mapping as integrator

    monkeypatch.setattr(integrator, "TARGET_SAMPLES_PER_TILE", 64)
    lit_plane(samples=2)
    full = ProgressLog(monkeypatch)
    reference = scenes.render_passes()["Combined"]
    full_calls = len(full.calls)

    # The photon pass reports first; cancel at the second tile of the camera pass.
    photon_calls = next(i for i, (_, m) in enumerate(full.calls) if "tile" in m)
    cancel = ProgressLog(monkeypatch, cancel_after=photon_calls + 2)
    partial = scenes.render_passes()["Combined"]
    # Stopped at the first answer "cancel": no further tile, never 100%.
    assert len(cancel.calls) == photon_calls + 2 < full_calls
    assert all(f < 1.0 for f, _ in cancel.calls)
    rendered = np.any(partial[..., :3] > 0, axis=2)
    assert 0 < rendered.sum() < rendered.size
    # What was rendered is kept exactly (same seed); the rest is black, not garbage.
    np.testing.assert_allclose(partial[rendered], reference[rendered], rtol=1e-6)
    assert np.isfinite(partial).all()


def test_no_camera_is_refused_by_blender(pm):
    scenes.reset()
    scenes.set_resolution(8, 6)
    scenes.add_plane(material=scenes.diffuse_material())
    scenes.add_light('POINT', location=(0, 0, 1))
    scenes.use_photon_map()
    with pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.render.render()


def test_empty_scene_renders_black(pm, capfd):
    scenes.reset()
    scenes.set_resolution(8, 6)
    scenes.add_camera()
    scenes.use_photon_map(samples=1)
    combined = scenes.render_passes()["Combined"]
    assert combined.shape == (6, 8, 4)
    assert np.all(combined[..., :3] == 0.0)
    assert "Traceback" not in capfd.readouterr().err


def test_no_lights_renders_black(pm, capfd):
    scenes.reset()
    scenes.set_resolution(8, 6)
    scenes.add_plane(material=scenes.diffuse_material())
    scenes.add_camera(location=(0, 0, 3))
    scenes.use_photon_map(samples=1)
    combined = scenes.render_passes()["Combined"]
    assert np.all(combined[..., :3] == 0.0)
    assert "Traceback" not in capfd.readouterr().err


def test_nan_transform_is_reported_by_name(pm, capfd):
    lit_plane()
    bpy.data.objects["Plane"].location.x = float("nan")
    with pytest.raises(RuntimeError) as caught:
        bpy.ops.render.render()
    message = str(caught.value)
    assert message.startswith("Error: Photon Map:") and "'Plane'" in message
    assert "Traceback" not in capfd.readouterr().err


def test_zero_area_triangles_change_nothing(pm, capfd):
    lit_plane(samples=2)
    clean = scenes.render_passes()["Combined"]

    # A mesh of degenerate triangles (repeated and collinear vertices) over the plane.
    mesh = bpy.data.meshes.new("Degenerate")
    vertices = [(0.0, 0.0, 0.5), (0.5, 0.0, 0.5), (1.0, 0.0, 0.5), (0.5, 0.0, 0.5)]
    mesh.from_pydata(vertices, [], [(0, 1, 2), (0, 1, 3)])
    mesh.update()
    obj = bpy.data.objects.new("Degenerate", mesh)
    bpy.context.scene.collection.objects.link(obj)

    dirty = scenes.render_passes()["Combined"]
    assert np.isfinite(dirty).all()
    np.testing.assert_allclose(dirty, clean, rtol=1e-5, atol=1e-7)
    assert "Traceback" not in capfd.readouterr().err


def test_export_warnings_are_reported_once(pm, capfd):
    """A material the exporter cannot read renders grey with one warning naming it."""
    lit_plane(samples=1)
    mat = bpy.data.objects["Plane"].active_material
    nodes = mat.node_tree.nodes
    toon = nodes.new('ShaderNodeBsdfToon')
    mat.node_tree.links.new(toon.outputs[0], nodes["Material Output"].inputs["Surface"])
    mat.name = "Unreadable Toon"
    scenes.render_passes()
    out = capfd.readouterr()
    text = out.out + out.err
    assert text.count("Unreadable Toon") == 1, text[-2000:]
