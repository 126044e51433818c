"""How long would Photon Map take to draw a material preview (bl_use_preview)?

    .venv/bin/python tools/preview_timing.py

A stand-in for Blender's preview scene (a sphere over a checkered floor, two lights) at
the material panel's preview size, 128 x 128, rendered with the Draft preset and with a
short progressive render, after one warm-up render (the numba kernels compiled). Blender
re-renders the preview after every edit of a material, so it has to be a fraction of a
second to feel live (EEVEE draws it in about 0.1 s, Cycles refines it progressively).
"""

import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import bpy  # noqa: E402

from tests.blender import scenes  # noqa: E402


def preview_scene():
    scenes.reset()
    scenes.set_resolution(128, 128)
    scenes.add_plane(size=8.0, material=scenes.diffuse_material("Floor", (0.4, 0.4, 0.4)))
    scenes.add_sphere(radius=1.0, location=(0.0, 0.0, 1.0), segments=64,
                      material=scenes.diffuse_material("Preview", (0.8, 0.2, 0.2)))
    scenes.add_light('AREA', location=(3.0, -3.0, 5.0), power=500.0, size=2.0,
                     rotation=(0.6, 0.0, 0.8))
    scenes.add_light('POINT', location=(-4.0, -2.0, 3.0), power=300.0)
    scenes.add_camera(location=(0.0, -6.0, 2.5), look_at=(0.0, 0.0, 1.0))
    return bpy.context.scene


def timed(**settings):
    scene = preview_scene()
    scenes.use_photon_map(scene, **settings)
    started = time.perf_counter()
    bpy.ops.render.render()
    return time.perf_counter() - started


def main():

    scenes.photon_map()
    runs = {"draft": dict(samples=4, global_photons=50000, caustic_photons=50000, global_k=30,
                          final_gather_rays=16),
            "progressive 8 x 10k": dict(integrator='progressive', progressive_passes=8,
                                        photons_per_pass=10000)}
    for name, settings in runs.items():
        timed(**settings)  # warm-up
        best = min(timed(**settings) for _ in range(3))
        print(f"preview 128 x 128, {name}: {best:.2f} s (best of 3)", flush=True)


if __name__ == "__main__":
    main()
