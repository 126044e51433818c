"""Pictures of the photon debug overlay for docs/debug_overlay.md.

    .venv/bin/python tools/overlay_pictures.py [--out docs/images] [--no-viewport]

Renders a small box room (diffuse walls, a red and a green wall, a glass sphere, a block,
an area light under the ceiling) with the core, traces its photon maps and writes
``overlay_render.png`` (Combined | global-map dots | caustic-map dots | both over
Combined). Then, unless ``--no-viewport``, it opens Debian's Blender 3.4 with a window on
a virtual X server (``xvfb-run``; the ``bpy`` module has no GPU), builds the same room,
hands the photons to ``photon_engine/overlay.py`` and saves a screenshot of the 3D view
as ``overlay_viewport.png``. Needs ``apt-get install blender xvfb``.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.integrators import debug_overlay  # noqa: E402
from core.integrators import photon_mapping as integrator  # noqa: E402
from core.integrators.photon_terms import trace_maps  # noqa: E402
from core.prepared import prepare  # noqa: E402
from core.scene import geometry, shapes  # noqa: E402
from core.io.exr import save_png  # noqa: E402
from core.scene.contract import LIGHT_AREA, Lights, Materials, Scene  # noqa: E402
from core.settings import RenderSettings  # noqa: E402


def room_scene(width=200, height=150) -> Scene:
    room = shapes.box([-1, -1, 0], [1, 1, 2], inward=True)
    # The inward box's faces in shapes.box order: +x, -x, +y, -y, +z, -z (two triangles each).
    wall = np.zeros(room.corners.shape[0], np.int32)
    wall[0:2], wall[2:4] = 1, 2  # +x green, -x red
    back = np.ones(room.corners.shape[0], bool)
    back[6:8] = False  # open the -y face towards the camera
    parts = [(shapes.Part(room.corners[back & (wall == m)], room.normals[back & (wall == m)]), m)
             for m in (0, 1, 2)]
    parts.append((shapes.uv_sphere([0.25, 0.2, 0.45], 0.45, rings=24, segments=48), 3))
    parts.append((shapes.box([-0.75, 0.1, 0.0], [-0.25, 0.6, 0.7]), 0))
    mesh = shapes.assemble(parts)
    materials = Materials.from_list([
        {"name": "White", "diffuse": [0.75, 0.75, 0.75]},
        {"name": "Green", "diffuse": [0.15, 0.6, 0.15]},
        {"name": "Red", "diffuse": [0.65, 0.1, 0.1]},
        {"name": "Glass", "transmission": [1.0, 1.0, 1.0], "ior": 1.5},
    ])
    light = shapes.look_at([0, 0, 1.98], [0, 0, 0], up=(0, 1, 0))
    lights = Lights.from_list([{"kind": LIGHT_AREA, "to_world": light, "power": 60.0,
                                "size": [0.5, 0.5]}])
    camera = shapes.pinhole([0, -3.4, 1.0], [0, 0, 0.9], width, height, np.radians(40))
    return Scene(mesh, materials, lights, camera).validate()


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "images"))
    parser.add_argument("--no-viewport", action="store_true")
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    scene = room_scene()
    settings = RenderSettings(samples=4, global_photons=20_000, caustic_photons=20_000,
                              final_gather_rays=16)
    combined = integrator.render(scene, settings).passes["combined"]
    extent = geometry.scene_extent(*scene.bounds())
    with prepare(scene, settings.threads) as prepared:
        accel = prepared.accel
        maps = trace_maps(prepared, settings)
        panels = [combined]
        for which in ("global", "caustic"):
            positions, flux = debug_overlay.select_photons(maps.global_map, maps.caustic_map, which)
            dots = debug_overlay.photon_overlay(scene.camera, accel, positions, flux, extent=extent)
            panels.append(dots[..., :3])
            print(f"{which}: {len(positions)} photons, {int(dots[..., 3].sum())} pixels with a dot")
        positions, flux = debug_overlay.select_photons(maps.global_map, maps.caustic_map, "both")
        both = debug_overlay.photon_overlay(scene.camera, accel, positions, flux, extent=extent,
                                            dot_radius_px=0)
        panels.append(debug_overlay.composite_over(combined, both))
    gap = np.ones((combined.shape[0], 4, 3), np.float32)
    strip = np.concatenate(sum(([p, gap] for p in panels), [])[:-1], axis=1)
    save_png(str(out / "overlay_render.png"), np.clip(strip, 0, 1))
    print("wrote", out / "overlay_render.png")
    if not args.no_viewport:
        colors = debug_overlay.display_colors(flux)
        viewport_screenshot(scene, positions, colors, out / "overlay_viewport.png")


# Run inside Blender 3.4 (with a window): the room as one mesh, the render camera, the
# photons through photon_engine/overlay.py, then a screenshot of the 3D view.
VIEWPORT_SCRIPT = r"""
import os, sys
import bpy, numpy as np
from mathutils import Matrix

npz, blend, png = sys.argv[sys.argv.index("--") + 1:]
data = np.load(npz)

if bpy.app.background:  # first run: build the room and save it (no splash when opened)
    for o in list(bpy.data.objects):  # the factory cube, light and camera
        bpy.data.objects.remove(o)
    tris = data["triangles"].reshape(-1, 3)
    mesh = bpy.data.meshes.new("Room")
    mesh.from_pydata(tris.tolist(), [], np.arange(len(tris)).reshape(-1, 3).tolist())
    for i, color in enumerate(data["material_colors"]):
        mat = bpy.data.materials.new(f"M{i}")
        mat.diffuse_color = (*color, 1.0)
        mesh.materials.append(mat)
    mesh.polygons.foreach_set("material_index", data["material"].astype(np.int32))
    scene = bpy.context.scene
    scene.collection.objects.link(bpy.data.objects.new("Room", mesh))
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.sensor_fit = "HORIZONTAL"
    cam.data.angle = float(data["fov"])
    cam.matrix_world = Matrix(data["camera"].tolist())
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 800, 600
    for screen in bpy.data.screens:
        for area in screen.areas:
            if area.type == "VIEW_3D":
                space = area.spaces.active
                space.shading.type = "SOLID"
                space.shading.color_type = "MATERIAL"
                space.show_gizmo = space.show_region_toolbar = space.show_region_header = False
                space.overlay.show_floor = space.overlay.show_axis_x = False
                space.overlay.show_axis_y = space.overlay.show_text = False
                space.overlay.show_extras = False
                space.region_3d.view_perspective = "CAMERA"
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    sys.exit(0)

from photon_map.photon_engine import overlay

overlay.enabled = lambda scene: True
overlay.set_photons(data["positions"], data["colors"])
overlay.register()

def frame_camera():
    window = bpy.context.window_manager.windows[0]
    area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width)
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.view3d.view_center_camera()

def save():
    window = bpy.context.window_manager.windows[0]
    area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width)
    with bpy.context.temp_override(window=window, area=area):
        bpy.ops.screen.screenshot_area(filepath=png)
    print("SAVED", png, "shader", overlay._points.shader_name)
    sys.stdout.flush()
    os._exit(0)

bpy.app.timers.register(frame_camera, first_interval=2.0)
bpy.app.timers.register(save, first_interval=4.0)
"""


def viewport_screenshot(scene, positions, colors, png):
    import tempfile

    sys.path.insert(0, str(ROOT))
    from tests.blender import debian_blender

    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        fov = 2 * np.arctan(scene.camera.film_size[0] / 2)
        np.savez(tmp / "photons.npz", triangles=scene.mesh.triangle_vertices(),
                 material=scene.mesh.material_index, camera=scene.camera.to_world, fov=fov,
                 material_colors=np.clip(scene.materials.diffuse + scene.materials.transmission
                                         * 0.6, 0, 1) ** (1 / 2.2),
                 positions=positions, colors=colors)
        (tmp / "shot.py").write_text(VIEWPORT_SCRIPT)
        args = ["--python", tmp / "shot.py", "--", tmp / "photons.npz", tmp / "room.blend", png]
        build = debian_blender.run(["-b", "--factory-startup", *args], tmp, timeout=120)
        if build.returncode != 0:
            raise RuntimeError(build.stdout[-2000:] + build.stderr[-2000:])
        log = debian_blender.run_with_window([tmp / "room.blend", "-p", "0", "0", "1400", "1000",
                                              *args], tmp, screen=(1400, 1000))
    print(log[-1500:])

if __name__ == "__main__":
    main()
