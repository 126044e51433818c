"""Rendered shading in the 3D viewport (photon_engine/viewport.py), headless: the logic
between draws, driven with the view matrices Blender would hand over. (The GPU draw itself
needs a window: the real-window test below runs Debian's Blender 3.4 under Xvfb.)"""

import types

import bpy
import numpy as np
import pytest

from tests.blender import scenes

pytestmark = pytest.mark.blender

W, H = 32, 24


@pytest.fixture
def lit_plane():
    scene = scenes.plane_and_point_light(width=W, height=H)
    scenes.use_photon_map(scene, photons_per_pass=4000, viewport_passes=6, seed=4)
    return scene


def camera_view(scene):
    """What Blender's RegionView3D holds when the viewport looks through the scene camera
    with the camera frame filling the view."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera.evaluated_get(depsgraph)
    return types.SimpleNamespace(
        view_matrix=cam.matrix_world.inverted(),
        window_matrix=cam.calc_matrix_camera(depsgraph, x=W, y=H))


def run_to_the_end(viewport, scene, view):
    from photon_map.photon_engine.viewport import view_camera

    depsgraph = bpy.context.evaluated_depsgraph_get()
    camera = view_camera(view, W, H)
    steps = 0
    while True:
        viewport.sync(depsgraph, camera)
        steps += 1
        if not viewport.step(seconds=0.0):  # one pass a draw
            return steps


def passes_in_view(view, region):
    """(image, SPPMState) of a ViewportRender through ``view`` cut to ``region`` (core
    pixels or None), run to its last pass."""
    import dataclasses

    from photon_map.photon_engine.viewport import ViewportRender, view_camera

    depsgraph = bpy.context.evaluated_depsgraph_get()
    viewport = ViewportRender()
    camera = dataclasses.replace(view_camera(view, W, H), region=region)
    while True:
        viewport.sync(depsgraph, camera)
        if not viewport.step(seconds=0.0):
            return viewport.image(), viewport.state


def assert_only_the_region_renders(view, region):
    """The view's passes cut to ``region`` (x0, y0, x1, y1) hold the whole view's pixels
    there, bit for bit, nothing elsewhere, and trace no visible point outside it."""
    x0, y0, x1, y1 = region
    (whole, _), (part, state) = (passes_in_view(view, cut) for cut in (None, region))
    assert whole[y0:y1, x0:x1].max() > 0
    np.testing.assert_array_equal(part[y0:y1, x0:x1], whole[y0:y1, x0:x1])
    outside = np.ones((H, W), bool)
    outside[y0:y1, x0:x1] = False
    assert np.all(part[outside] == 0.0)
    assert max(state.stats["visible_points"]) <= (x1 - x0) * (y1 - y0)


def test_viewport_through_the_camera_is_the_progressive_render(lit_plane):
    """The view's matrices give the scene camera's rays: after Viewport Passes passes the
    viewport shows the Progressive integrator's F12 image of the same passes."""
    from photon_map.photon_engine.viewport import ViewportRender

    viewport = ViewportRender()
    steps = run_to_the_end(viewport, lit_plane, camera_view(lit_plane))
    assert steps == 6 and viewport.state.passes == 6
    assert viewport.status() == "Photon Map | Viewport: pass 6 of 6 (done)"
    image = viewport.image()
    assert image.shape == (H, W, 3) and np.isfinite(image).all() and image.min() >= 0
    lit_plane.photon_map.integrator = 'progressive'
    lit_plane.photon_map.progressive_passes = 6
    lit_plane.photon_map.photons_per_pass = 4000
    final = scenes.render_passes(lit_plane)["Combined"][..., :3]
    assert final.mean() > 0
    np.testing.assert_allclose(image.mean(axis=(0, 1)), final.mean(axis=(0, 1)), rtol=1e-4)
    np.testing.assert_allclose(image, final, rtol=1e-3, atol=1e-3 * final.max())


def test_a_view_change_restarts_the_passes_and_a_scene_change_re_exports(lit_plane):
    from photon_map.photon_engine.viewport import ViewportRender, view_camera

    viewport = ViewportRender()
    view = camera_view(lit_plane)
    run_to_the_end(viewport, lit_plane, view)
    before = viewport.image()
    exported = viewport.scene
    depsgraph = bpy.context.evaluated_depsgraph_get()
    # Orbit: the same scene through another camera, passes from 1 again.
    from mathutils import Matrix
    view.view_matrix = view.view_matrix @ Matrix.Rotation(0.2, 4, 'Z')
    viewport.sync(depsgraph, view_camera(view, W, H))
    assert viewport.state is None and viewport.step(seconds=0.0)
    assert viewport.state.passes == 1 and viewport.scene.mesh is exported.mesh
    # A brighter light: view_update marks the scene, the next draw exports it again.
    bpy.data.lights[0].energy *= 2.0
    viewport.scene_changed()
    view.view_matrix = camera_view(lit_plane).view_matrix
    run_to_the_end(viewport, lit_plane, view)
    assert viewport.scene is not exported
    np.testing.assert_allclose(viewport.image(), 2.0 * before, rtol=1e-5, atol=1e-7)


def test_render_size_keeps_the_pixel_size_and_caps_the_pixels():
    from photon_map.photon_engine.viewport import MAX_PIXELS, render_size

    assert render_size(300, 200) == (300, 200)
    assert render_size(300, 200, pixel_size=2) == (150, 100)
    w, h = render_size(1920, 1080)
    assert w * h <= MAX_PIXELS and (w, h) == (1920 // 5, 1080 // 5)  # 4 would be 129,600
    assert render_size(0, 0) == (1, 1)


def test_a_refused_scene_shows_its_error_and_runs_nothing(lit_plane):
    from photon_map.photon_engine.viewport import ViewportRender

    bpy.data.objects["Plane"].location.x = float("nan")
    viewport = ViewportRender()
    assert run_to_the_end(viewport, lit_plane, camera_view(lit_plane)) == 1
    assert viewport.state is None and viewport.image() is None
    assert "'Plane'" in viewport.status() and viewport.status().startswith("Photon Map: ")


# --- A real viewport: Debian's Blender 3.4 with a window on a virtual X server (Xvfb) ------
#
# A top orthographic view of an emissive square (0.5 W/(m^2 sr)) over a grey world (0.18),
# with the Standard view transform: both are seen directly, so after any pass the screen
# shows exactly sRGB(0.5) = 188 / 255 in the middle and sRGB(0.18) = 118 / 255 outside it,
# which checks the whole path: the view's camera, the passes, the texture and Blender's
# display transform.

def test_rendered_shading_in_a_real_viewport(tmp_path):
    import matplotlib.image

    from tests.blender import debian_blender

    png = tmp_path / "view.png"
    seen = debian_blender.render_in_viewport(tmp_path, "square", png, passes=3, photons=1000)
    assert seen["error"] is None and seen["passes"] == 3 and not seen["more"], seen
    image = np.round(matplotlib.image.imread(png)[..., :3] * 255)
    # The window region inside the area's screenshot (Blender's y runs up from the bottom).
    ax, ay, aw, ah = seen["area"]
    rx, ry, rw, rh = seen["region"]
    top, left = (ay + ah) - (ry + rh), rx - ax
    view = image[top:top + rh, left:left + rw]
    centre = view[rh // 2 - 5:rh // 2 + 5, rw // 2 - 5:rw // 2 + 5]
    edge = view[rh // 2 - 5:rh // 2 + 5, int(rw * 0.95) - 5:int(rw * 0.95) + 5]
    assert np.abs(centre - 188).max() <= 2, centre[0, 0]
    assert np.abs(edge - 118).max() <= 2, edge[0, 0]


def test_the_viewport_render_region_renders_those_pixels_only(lit_plane):
    """View3D's Render Region (outside the camera view): the region's pixels are those of
    the whole view's passes, bit for bit, and nothing is traced outside it."""
    from photon_map.photon_engine.viewport import view_region

    view = camera_view(lit_plane)
    view.view_perspective = 'PERSP'
    space = types.SimpleNamespace(use_render_border=True, render_border_min_x=0.25,
                                  render_border_max_x=0.75, render_border_min_y=0.5,
                                  render_border_max_y=1.0)
    region = view_region(space, view, W, H)
    assert region == (8, 0, 24, 12)
    assert view_region(types.SimpleNamespace(use_render_border=False), view, W, H) is None
    assert_only_the_region_renders(view, region)


def test_the_scene_render_region_in_the_camera_view_renders_its_part_of_the_frame(lit_plane):
    """Looking through the camera, the Render Region is the scene's (``render.use_border``,
    fractions of the camera frame), placed where the camera frame sits in the view: here
    the view is zoomed out so the frame fills the middle half of it. Its pixels are those of
    the whole view's passes, bit for bit, and nothing outside it is traced or shown."""
    from mathutils import Matrix

    from photon_map.photon_engine.viewport import camera_frame_in_view, view_region

    view = camera_view(lit_plane)
    view.view_perspective = 'CAMERA'
    half = Matrix.Diagonal((0.5, 0.5, 1.0, 1.0))  # the camera frame in the middle half
    view.window_matrix = half @ view.window_matrix
    np.testing.assert_allclose(camera_frame_in_view(view, lit_plane), (0.25, 0.25, 0.75, 0.75),
                               atol=1e-6)
    space = types.SimpleNamespace(use_render_border=False)
    render = lit_plane.render
    assert view_region(space, view, W, H, lit_plane) is None  # use_border off: whole view
    render.use_border = True
    render.border_min_x, render.border_max_x = 0.0, 0.5
    render.border_min_y, render.border_max_y = 0.5, 1.0
    # x: 0.25 + [0, 0.5] x 0.5 of 32 pixels; y (up): 0.25 + [0.5, 1] x 0.5 of 24 -> rows 6-12
    region = view_region(space, view, W, H, lit_plane)
    assert region == (8, 6, 16, 12)
    assert_only_the_region_renders(view, region)
