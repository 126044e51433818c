"""Rendered shading in a real 3D viewport, run inside Debian's Blender (3.4) twice:

    blender -b --factory-startup --addons photon_map --python viewport_window.py -- \
        SCENE BLEND PNG PASSES PHOTONS LIMIT ROOT          # build SCENE, save BLEND
    xvfb-run blender --factory-startup BLEND --addons photon_map --python viewport_window.py -- ...
                                                        # open it with a window, render, screenshot

(``debian_blender.render_in_viewport`` runs both.) The first run builds the scene and
sets up the 3D views (a saved file opens without the splash screen); the second switches
them to Rendered shading (a file opens in Solid), counts the viewport's passes, and once
PASSES are done (or after LIMIT seconds) saves a screenshot of the largest 3D view as PNG
and prints ``VIEWPORT {json}``: passes, more, error, draws, seconds, and the area and
window-region rectangles (x, y, width, height; Blender's y runs up from the bottom).

Scenes: ``square``, an emissive square (0.5 W/(m^2 sr)) over a grey world (0.18) seen from
the top, orthographic, with the Standard view transform (tests/blender/test_viewport.py);
``cornell``, the demo's Cornell box through its camera (tools/viewport_picture.py).

Not a test module: it imports bpy at the top and runs only inside Blender.
"""

import json
import os
import sys
import time

import bpy

scene_name, blend, png, passes, photons, limit, root = sys.argv[sys.argv.index("--") + 1:]


def square_scene(scene):
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
    scene.view_settings.look = "None"
    return scene


def square_view(r3d):
    from mathutils import Quaternion

    r3d.view_perspective = "ORTHO"
    r3d.view_rotation = Quaternion((1.0, 0.0, 0.0, 0.0))  # top view
    r3d.view_location = (0.0, 0.0, 0.0)
    r3d.view_distance = 4.0


def cornell_scene(scene):
    sys.path.insert(0, root)
    from examples.cornell_box import build_cornell_box

    return build_cornell_box(resolution=(640, 480))


def cornell_view(r3d):
    r3d.view_perspective = "CAMERA"


SCENES = {"square": (square_scene, square_view), "cornell": (cornell_scene, cornell_view)}
build, view = SCENES[scene_name]

if bpy.app.background:  # first run: build and save
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scene = build(bpy.context.scene)
    scene.render.engine = "PHOTON_MAP"
    scene.view_settings.view_transform = "Standard"
    scene.photon_map.viewport_passes = int(passes)
    scene.photon_map.photons_per_pass = int(photons)
    for screen in bpy.data.screens:
        for area in screen.areas:
            if area.type == "VIEW_3D":
                space = area.spaces.active
                space.overlay.show_overlays = False
                space.show_gizmo = space.show_region_toolbar = space.show_region_header = False
                view(space.region_3d)
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    sys.exit(0)

from photon_map.photon_engine import viewport  # noqa: E402

seen = {"passes": 0, "more": True, "error": None, "draws": 0}
step = viewport.ViewportRender.step


def counted(self, seconds=viewport.STEP_SECONDS):
    more = step(self, seconds)
    seen.update(passes=self.state.passes if self.state else 0, more=more, error=self.error,
                draws=seen["draws"] + 1)
    return more


viewport.ViewportRender.step = counted
window = bpy.context.window_manager.windows[0]
area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width)
region = next(r for r in area.regions if r.type == "WINDOW")
if area.spaces.active.region_3d.view_perspective == "CAMERA":
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.view3d.view_center_camera()
area.spaces.active.shading.type = "RENDERED"  # a file opens in Solid shading
started = time.perf_counter()


def poll():
    if seen["more"] and not seen["error"] and time.perf_counter() - started < float(limit):
        return 0.5
    with bpy.context.temp_override(window=window, area=area):
        bpy.ops.screen.screenshot_area(filepath=png)
    seen.update(seconds=round(time.perf_counter() - started, 1),
                area=[area.x, area.y, area.width, area.height],
                region=[region.x, region.y, region.width, region.height])
    print("VIEWPORT", json.dumps(seen))
    sys.stdout.flush()
    os._exit(0)  # quit_blender() is ignored while the startup script runs


bpy.app.timers.register(poll, first_interval=1.0)
