"""A picture of Rendered shading in the 3D viewport for the README (docs/images).

    .venv/bin/python tools/viewport_picture.py [--out docs/images/viewport_rendered.png]
        [--passes 64] [--photons 100000]

Builds the demo's Cornell box (examples/cornell_box.py) inside Debian's Blender 3.4 (the
``bpy`` module has no GPU), opens it with a window on a virtual X server (``xvfb-run``),
looks through the camera in Rendered shading with Photon Map, waits until Viewport Passes
passes are done and saves a screenshot of the 3D view. Needs ``apt-get install blender
xvfb`` (tools/setup.sh installs both).
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SCRIPT = r"""
import json, os, sys, time
import bpy

root, blend, png, passes, photons = sys.argv[sys.argv.index("--") + 1:]
if bpy.app.background:  # first run: build and save (no splash screen when opened)
    sys.path.insert(0, root)
    from examples.cornell_box import build_cornell_box
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scene = build_cornell_box(resolution=(640, 480))
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
                space.region_3d.view_perspective = "CAMERA"
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    sys.exit(0)

from photon_map.photon_engine import viewport

seen = {"passes": 0, "more": True, "error": None}
step = viewport.ViewportRender.step

def counted(self, seconds=viewport.STEP_SECONDS):
    more = step(self, seconds)
    seen.update(passes=self.state.passes if self.state else 0, more=more, error=self.error)
    return more

viewport.ViewportRender.step = counted
window = bpy.context.window_manager.windows[0]
area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width)
region = next(r for r in area.regions if r.type == "WINDOW")
with bpy.context.temp_override(window=window, area=area, region=region):
    bpy.ops.view3d.view_center_camera()
area.spaces.active.shading.type = "RENDERED"  # a file opens in Solid shading
started = time.perf_counter()

def poll():
    if seen["more"] and not seen["error"] and time.perf_counter() - started < 600:
        return 0.5
    with bpy.context.temp_override(window=window, area=area):
        bpy.ops.screen.screenshot_area(filepath=png)
    seen["seconds"] = round(time.perf_counter() - started, 1)
    print("VIEWPORT", json.dumps(seen))
    sys.stdout.flush()
    os._exit(0)

bpy.app.timers.register(poll, first_interval=1.0)
"""


def main(argv=None):
    from tests.blender import debian_blender

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "images" / "viewport_rendered.png"))
    parser.add_argument("--passes", type=int, default=64)
    parser.add_argument("--photons", type=int, default=100_000)
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        (tmp / "view.py").write_text(SCRIPT)
        script = ["--addons", "photon_map", "--python", tmp / "view.py", "--", ROOT,
                  tmp / "box.blend", out, args.passes, args.photons]
        debian_blender.check(debian_blender.run(["-b", "--factory-startup", *script], tmp))
        log = debian_blender.run_with_window(["--factory-startup", tmp / "box.blend", "-p", "0",
                                              "0", "900", "700", *script], tmp,
                                             screen=(900, 700), timeout=700)
    line = next((l for l in log.splitlines() if l.startswith("VIEWPORT ")), None)
    if line is None:
        print(log[-3000:], file=sys.stderr)
        return 1
    print(line)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
