"""The viewport photon display, as far as it can be tested headless.

The ``bpy`` module always runs in background mode, where Blender's ``gpu`` module refuses
to work ("GPU functions for drawing are not available in background mode": checked for
``gpu.platform.backend_type_get()``, ``gpu.types.GPUOffScreen`` and
``gpu.shader.from_builtin`` with bpy 5.0.1). So the bpy tests check what background mode
must do (no handler, no GPU call) and the data the handler would draw; the drawing itself
is tested at the end with Debian's Blender 3.4 given a window by Xvfb (skipped without
``xvfb-run``).
"""

import sys
import types

import bpy
import numpy as np
import pytest

from tests.blender import scenes

pytestmark = pytest.mark.blender


@pytest.fixture
def overlay():
    scenes.photon_map()
    from photon_map.photon_engine import overlay as module

    module.clear()
    yield module
    module.unregister()


def test_background_mode_adds_no_handler_timer_or_hook(overlay):
    assert bpy.app.background
    overlay.register()
    assert not overlay.is_registered()
    assert not bpy.app.timers.is_registered(overlay._poll_redraw)
    assert overlay._on_load_pre not in bpy.app.handlers.load_pre
    overlay.unregister()  # harmless when nothing was added
    assert not overlay.is_registered()


def test_set_photons_keeps_positions_as_given_below_the_cap(overlay, rng):
    positions = rng.normal(size=(1000, 3))
    colors = rng.uniform(0, 2, (1000, 3))
    assert overlay.set_photons(positions, colors) == 1000
    kept, rgba = overlay.photons()
    assert kept.dtype == np.float32 and kept.shape == (1000, 3) and kept.flags.c_contiguous
    np.testing.assert_array_equal(kept, positions.astype(np.float32))
    assert rgba.dtype == np.float32 and rgba.shape == (1000, 4)
    np.testing.assert_array_equal(rgba[:, :3], np.clip(colors, 0, 1).astype(np.float32))
    assert (rgba[:, 3] == 1).all()


def test_set_photons_subsamples_to_the_cap(overlay, rng):
    n = overlay.MAX_VIEWPORT_PHOTONS + 50_000
    positions = np.empty((n, 3), np.float32)
    positions[:, 0] = np.arange(n)  # each row names its photon
    positions[:, 1:] = rng.normal(size=(n, 2))
    colors = np.repeat(positions[:, :1] / n, 3, axis=1)
    assert overlay.set_photons(positions, colors) == overlay.MAX_VIEWPORT_PHOTONS
    kept, rgba = overlay.photons()
    assert kept.shape == (overlay.MAX_VIEWPORT_PHOTONS, 3) and kept.dtype == np.float32
    index = kept[:, 0].astype(np.int64)
    assert (np.diff(index) > 0).all()  # distinct photons, in their original order
    np.testing.assert_array_equal(kept, positions[index])  # rows kept whole, unchanged
    np.testing.assert_allclose(rgba[:, 0], index / n, rtol=1e-6)  # colours follow their photon
    # A uniform sample: each half of the map keeps about its share.
    first_half = (index < n // 2).mean()
    assert abs(first_half - 0.5) < 0.01
    # Reproducible.
    overlay.set_photons(positions, colors)
    np.testing.assert_array_equal(overlay.photons()[0], kept)


def test_set_photons_rejects_bad_shapes(overlay):
    with pytest.raises(ValueError, match="positions"):
        overlay.set_photons(np.zeros((4, 2)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="colors"):
        overlay.set_photons(np.zeros((4, 3)), np.zeros((5, 3)))
    assert overlay.set_photons(np.zeros((0, 3)), np.zeros((0, 3))) == 0


def test_draw_returns_early_without_touching_gpu(overlay, monkeypatch):
    class NoGPU(types.ModuleType):
        def __getattr__(self, name):
            raise AssertionError(f"gpu.{name} used in background mode")

    monkeypatch.setitem(sys.modules, "gpu", NoGPU("gpu"))
    monkeypatch.setattr(overlay, "enabled", lambda scene: True)
    overlay.set_photons(np.zeros((10, 3)), np.ones((10, 3)))
    assert overlay.draw() is False
    assert not overlay._points.gpu_failed  # it returned before trying


def test_toggle_reads_the_scene_property_for_photon_map_only(overlay):
    holder = types.SimpleNamespace(photon_map=types.SimpleNamespace(show_photons_in_viewport=True),
                                   render=types.SimpleNamespace(engine='PHOTON_MAP'))
    assert overlay.enabled(holder)
    holder.render.engine = 'CYCLES'  # our panel, and so the toggle, is hidden there
    assert not overlay.enabled(holder)
    holder.render.engine = 'PHOTON_MAP'
    holder.photon_map.show_photons_in_viewport = False
    assert not overlay.enabled(holder)
    # Before the property exists (and on a real scene without it).
    assert not overlay.enabled(types.SimpleNamespace(render=holder.render))
    assert overlay.enabled(bpy.context.scene) is False


def test_clear_forgets_the_photons(overlay):
    overlay.set_photons(np.zeros((3, 3)), np.zeros((3, 3)))
    overlay.clear()
    assert overlay.photons() is None


# --- The Photons render pass, end to end through bpy.ops.render.render -----------------

def half_lit_floor(**settings):
    """32x24, looking straight down from 3 m (+Y up, +X right in the image) at a 2 m
    plane covering only the top of the view (y in [0.2, 2.2] m; the view spans about
    +-1.16 m in y), under a point light. Few photons, one sample: a second or so."""
    scene = scenes.reset()
    scenes.set_resolution(32, 24)
    scenes.add_plane(size=2.0, location=(0.0, 1.2, 0.0), material=scenes.diffuse_material())
    scenes.add_light('POINT', location=(0.0, 0.0, 1.0), power=100.0, shadow_soft_size=0.0)
    scenes.add_camera(location=(0.0, 0.0, 3.0), look_at=(0.0, 0.0, 0.0), lens=35.0)
    # final_gather keeps the photons' first hits in the global map (this scene has no
    # second bounce); one gather ray per pixel keeps it fast.
    return scenes.use_photon_map(scene, samples=1, global_photons=3000, caustic_photons=0,
                                 indirect_mode='final_gather', final_gather_rays=1,
                                 overlay_dot_radius=0.0, **settings)


def test_photons_pass_in_the_render_result(overlay):
    half_lit_floor(photon_debug_pass=True)
    passes = scenes.render_passes()
    dots = passes["Photons"]
    assert dots.shape == (24, 32, 4)
    assert np.all(np.isfinite(dots)) and dots.min() >= 0
    alpha = dots[..., 3]
    assert set(np.unique(alpha)) == {0.0, 1.0}
    assert 20 <= (alpha == 1).sum() < 0.5 * alpha.size  # dots, not a filled image
    assert not dots[alpha == 0].any()  # (0, 0, 0, 0) between the dots
    assert dots[alpha == 1][:, :3].max() > 0
    # The plane holding the photons fills only rows 0..9 from the top (y = 0.2 m is at row
    # 24 * (1.157 - 0.2) / 2.314 = 9.9): the pass is not upside down.
    rows = np.nonzero(alpha)[0]
    assert rows.max() <= 10
    # Not composited: Combined shows the lit plane (x in [-1, 1] m: columns 6..25), not
    # the dots, and black below it.
    combined = passes["Combined"]
    assert combined[:8, 7:25, :3].min() > 0 and not combined[14:, :, :3].any()

    # Composited: Combined is the dot's colour where there is a dot.
    scenes.use_photon_map(overlay_composite=True)
    composited = scenes.render_passes()
    lit = composited["Photons"][..., 3] == 1
    np.testing.assert_array_equal(composited["Photons"], dots)  # same seed, same photons
    np.testing.assert_allclose(composited["Combined"][lit][:, :3], dots[lit][:, :3], rtol=1e-6)
    np.testing.assert_array_equal(composited["Combined"][~lit], combined[~lit])


def test_no_photons_pass_when_switched_off(overlay):
    half_lit_floor(photon_debug_pass=False)
    passes = scenes.render_passes()
    assert "Photons" not in passes
    assert {"Combined", "Direct", "Indirect"} <= set(passes)


def test_overlay_settings_reach_the_core(overlay):
    from photon_map.core.settings import OVERLAY_MAPS
    from photon_map.photon_engine import properties

    scene = scenes.use_photon_map(photon_debug_pass=True, overlay_map='caustic',
                                  overlay_dot_radius=2.5, overlay_composite=True)
    core = properties.to_core_settings(scene.photon_map)
    assert (core.photon_debug_pass, core.overlay_map, core.overlay_dot_radius,
            core.overlay_composite) == (True, "caustic", 2.5, True)
    rna = scene.photon_map.bl_rna.properties
    assert tuple(item.identifier for item in rna["overlay_map"].enum_items) == OVERLAY_MAPS
    assert "show_photons_in_viewport" in rna
    assert "show_photons_in_viewport" not in properties.setting_names()


def test_render_hands_the_chosen_maps_photons_to_the_viewport(overlay, monkeypatch):
    """What render.py does after a render with a window (bpy.app.background is False
    there; read-only here, so a stand-in bpy answers for the call)."""
    from photon_map.photon_engine import render

    maps = types.SimpleNamespace(
        global_map=types.SimpleNamespace(positions=np.zeros((3, 3), np.float32),
                                         flux=np.full((3, 3), 2.0, np.float32)),
        caustic_map=types.SimpleNamespace(positions=np.ones((2, 3), np.float32),
                                          flux=np.full((2, 3), 0.5, np.float32)))
    render.show_in_viewport(maps, "caustic")
    assert overlay.photons() is None  # background mode: nothing kept
    monkeypatch.setitem(sys.modules, "bpy", types.SimpleNamespace(
        app=types.SimpleNamespace(background=False)))
    render.show_in_viewport(maps, "caustic")
    positions, rgba = overlay.photons()
    np.testing.assert_array_equal(positions, np.ones((2, 3)))
    np.testing.assert_array_equal(rgba, np.ones((2, 4)))  # 0.5 W / 0.5 W: colour 1
    render.show_in_viewport(maps, "both")
    positions, rgba = overlay.photons()
    assert positions.shape == (5, 3)
    np.testing.assert_allclose(rgba[3:, :3], 0.25)  # relative to the 2 W photons
    render.show_in_viewport(None, "both")  # a render without maps clears the display
    assert overlay.photons()[0].shape == (0, 3)


# --- A real draw: Debian's Blender 3.4 with a window on a virtual X server (Xvfb) -------
#
# There the gpu module works (OpenGL on Mesa's software rasteriser). The script draws the
# handler into an offscreen buffer with view and projection matrices written out here, so
# the expected pixel of each point is computed from the pinhole formula, not by Blender.

DRAW_SCRIPT = r'''
import sys, bpy, gpu, numpy as np
from mathutils import Matrix
from photon_map.photon_engine import overlay

out, size = sys.argv[sys.argv.index("--") + 1], 64
view = Matrix(VIEW)
proj = Matrix(PROJ)
overlay.enabled = lambda scene: True
overlay.set_photons(np.array(POINTS, np.float32), np.array(COLORS, np.float32))
offscreen = gpu.types.GPUOffScreen(size, size)
with offscreen.bind():
    fb = gpu.state.active_framebuffer_get()
    fb.clear(color=(0.0, 0.0, 0.0, 1.0), depth=1.0)
    with gpu.matrix.push_pop():
        gpu.matrix.load_matrix(view)
        gpu.matrix.load_projection_matrix(proj)
        # An opaque occluder in front of the left half, written into the depth buffer.
        shader = gpu.shader.from_builtin("UNIFORM_COLOR")
        from gpu_extras.batch import batch_for_shader
        quad = batch_for_shader(shader, "TRIS", {"pos": OCCLUDER}, indices=((0, 1, 2), (0, 2, 3)))
        gpu.state.depth_test_set("LESS_EQUAL")
        gpu.state.depth_mask_set(True)
        shader.bind()
        shader.uniform_float("color", (0.2, 0.2, 0.2, 1.0))
        quad.draw(shader)
        gpu.state.depth_test_set("NONE")  # the handler must turn depth testing on itself
        drew = overlay.draw()
    pixels = np.array(fb.read_color(0, 0, size, size, 4, 0, "FLOAT").to_list(), np.float32)
    # The next render's photons replace the batch: one blue point at the centre.
    overlay.set_photons(np.zeros((1, 3), np.float32), np.array([[0.0, 0.0, 1.0]], np.float32))
    fb.clear(color=(0.0, 0.0, 0.0, 1.0), depth=1.0)
    with gpu.matrix.push_pop():
        gpu.matrix.load_matrix(view)
        gpu.matrix.load_projection_matrix(proj)
        overlay.draw()
    second = np.array(fb.read_color(0, 0, size, size, 4, 0, "FLOAT").to_list(), np.float32)
np.save(out, pixels.reshape(size, size, 4)[::-1])  # row 0 at the top
np.save(out.replace(".npy", "_second.npy"), second.reshape(size, size, 4)[::-1])
print("DREW", drew, overlay._points.shader_name)
sys.stdout.flush()
import os
os._exit(0)  # quit_blender() is ignored while the startup script runs
'''

SIZE = 64
EYE_Z = 5.0
FOCAL = 1.0 / np.tan(np.radians(30.0))  # 60 degrees vertical field of view
NEAR, FAR = 0.1, 100.0
# A 3 x 3 grid in the plane z = 0; the left column is behind the occluder.
GRID = [(x, y, 0.0) for y in (-1.0, 0.0, 1.0) for x in (-1.0, 0.0, 1.0)]
GRID_COLORS = [(1.0, 0.0, 0.0) if x >= 0 else (0.0, 1.0, 0.0) for x, _, _ in GRID]  # green: hidden
OCCLUDER_QUAD = [(-3.0, -3.0, 1.0), (-0.5, -3.0, 1.0), (-0.5, 3.0, 1.0), (-3.0, 3.0, 1.0)]


def _matrices():
    view = np.eye(4)
    view[2, 3] = -EYE_Z  # camera at (0, 0, 5) looking down -Z
    proj = np.zeros((4, 4))
    proj[0, 0] = proj[1, 1] = FOCAL
    proj[2, 2] = (FAR + NEAR) / (NEAR - FAR)
    proj[2, 3] = 2 * FAR * NEAR / (NEAR - FAR)
    proj[3, 2] = -1.0
    return view, proj


def _expected_pixel(point):
    """(column, row from the top) of a world point: x_ndc = f x / depth."""
    x, y, z = point
    depth = EYE_Z - z
    col = (FOCAL * x / depth + 1) / 2 * SIZE
    row = (1 - (FOCAL * y / depth + 1) / 2) * SIZE
    return int(col), int(row)


def test_real_draw_into_an_offscreen_buffer(tmp_path):
    from tests.blender import debian_blender

    view, proj = _matrices()
    script = (DRAW_SCRIPT.replace("VIEW", repr(view.tolist())).replace("PROJ", repr(proj.tolist()))
              .replace("POINTS", repr(GRID)).replace("COLORS", repr(GRID_COLORS))
              .replace("OCCLUDER", repr(OCCLUDER_QUAD)))
    (tmp_path / "draw.py").write_text(script)
    out = tmp_path / "pixels.npy"
    log = debian_blender.run_with_window(["--factory-startup", "--python-exit-code", "1",
                                          "--python", tmp_path / "draw.py", "--", out],
                                         tmp_path, timeout=120)
    assert out.is_file(), log[-3000:]
    assert "DREW True" in log
    image = np.load(out)
    red = (image[..., 0] > 0.9) & (image[..., 1] < 0.1)
    green = (image[..., 1] > 0.9) & (image[..., 0] < 0.1)
    grey = np.isclose(image[..., :3], 0.2, atol=0.02).all(axis=2)
    for point, color in zip(GRID, GRID_COLORS):
        col, row = _expected_pixel(point)
        if point[0] < 0:  # behind the occluder: depth-tested away
            assert grey[row, col] and not green.any()
        else:
            patch = red[row - 1:row + 2, col - 1:col + 2]
            assert patch.sum() >= 4, (point, col, row)  # a 3 px point around the pixel
    # Nothing else is drawn: six visible points of about 3 x 3 pixels each.
    assert 6 * 4 <= red.sum() <= 6 * 16
    # After set_photons, the handler draws the new points only.
    second = np.load(tmp_path / "pixels_second.npy")
    lit = second[..., :3].max(axis=2) > 0.5
    rows, cols = np.nonzero(lit)
    assert (second[lit][:, 2] > 0.9).all() and (second[lit][:, :2] < 0.1).all()
    assert abs(cols.mean() - SIZE / 2) <= 1.5 and abs(rows.mean() - SIZE / 2) <= 1.5
    assert 4 <= lit.sum() <= 16
