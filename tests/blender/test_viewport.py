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

VIEW_SCRIPT = r"""
import json, os, sys
import bpy

blend, png = sys.argv[sys.argv.index("--") + 1:]
scene = bpy.context.scene
if bpy.app.background:  # first run: build and save (no splash screen when opened)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    world = bpy.data.worlds.new("Grey")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.18, 0.18, 0.18, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.world = world
    mesh = bpy.data.meshes.new("Square")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    mat = bpy.data.materials.new("Glow")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    emit.inputs["Strength"].default_value = 0.5
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(emit.outputs[0], out.inputs["Surface"])
    mesh.materials.append(mat)
    scene.collection.objects.link(bpy.data.objects.new("Square", mesh))
    scene.render.engine = "PHOTON_MAP"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.photon_map.viewport_passes = 3
    scene.photon_map.photons_per_pass = 1000
    from mathutils import Quaternion
    for screen in bpy.data.screens:
        for area in screen.areas:
            if area.type == "VIEW_3D":
                space = area.spaces.active
                space.overlay.show_overlays = False
                space.show_gizmo = space.show_region_toolbar = space.show_region_header = False
                r3d = space.region_3d
                r3d.view_perspective = "ORTHO"
                r3d.view_rotation = Quaternion((1.0, 0.0, 0.0, 0.0))  # top view
                r3d.view_location = (0.0, 0.0, 0.0)
                r3d.view_distance = 4.0
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    sys.exit(0)

from photon_map.photon_engine import viewport

seen = {"passes": 0, "more": True, "error": None, "draws": 0}
step = viewport.ViewportRender.step

def counted(self, seconds=viewport.STEP_SECONDS):
    more = step(self, seconds)
    seen.update(passes=self.state.passes if self.state else 0, more=more, error=self.error,
                draws=seen["draws"] + 1)
    return more

viewport.ViewportRender.step = counted
ticks = [0]
for area in bpy.context.window_manager.windows[0].screen.areas:
    if area.type == "VIEW_3D":  # a file opens in Solid shading: switch to Rendered here
        area.spaces.active.shading.type = "RENDERED"

def poll():
    ticks[0] += 1
    if (seen["more"] and not seen["error"]) and ticks[0] < 240:
        return 0.5
    window = bpy.context.window_manager.windows[0]
    area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width)
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(window=window, area=area):
        bpy.ops.screen.screenshot_area(filepath=png)
    seen.update(area=[area.x, area.y, area.width, area.height],
                region=[region.x, region.y, region.width, region.height])
    print("VIEWPORT", json.dumps(seen))
    sys.stdout.flush()
    os._exit(0)

bpy.app.timers.register(poll, first_interval=1.0)
"""


def test_rendered_shading_in_a_real_viewport(tmp_path):
    import json

    import matplotlib.image

    from tests.blender import debian_blender

    (tmp_path / "view.py").write_text(VIEW_SCRIPT)
    blend, png = tmp_path / "square.blend", tmp_path / "view.png"
    args = ["--addons", "photon_map", "--python", tmp_path / "view.py", "--", blend, png]
    debian_blender.check(debian_blender.run(["-b", "--factory-startup", *args], tmp_path))
    log = debian_blender.run_with_window(["--factory-startup", blend, "-p", "0", "0", "800",
                                          "600", *args], tmp_path, screen=(800, 600))
    line = next((l for l in log.splitlines() if l.startswith("VIEWPORT ")), None)
    assert line is not None, log[-3000:]
    seen = json.loads(line.split(" ", 1)[1])
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
