"""The depth-of-field scene (tests/blender/test_dof.py) and Cycles' cached image of it
through an orthographic camera with depth of field.

The scene: a row of spheres from near to far on a lit floor, the camera focused on the
second one (focus object). Perspective: f/0.1 (aperture radius = focal length / (2
f-stop)); Cycles renders it in the test's own process. Orthographic (``ortho=True``): the
same row seen through a 4 m wide orthographic camera at f/1, whose aperture radius Cycles
takes as 1 / (2 f-stop) = 0.5 scene units (blender/camera.cpp; no focal length, no unit
scale); every ray of a film point passes through that point's spot at the focus distance
(kernel/camera/camera.h, camera_sample_orthographic).

Run as a script to re-render the cached orthographic reference
tests/data/cycles_dof_ortho_64x48.npz (about a minute on 2 cores):

    .venv/bin/python tests/blender/cycles_dof_reference.py
"""

from __future__ import annotations

import math
import pathlib
import sys

import numpy as np

import bpy

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes  # noqa: E402

SIZE = (64, 48)
ORTHO_FSTOP = 1.0
ORTHO_SCALE = 4.0
CYCLES_SAMPLES = 1024  # per seed, two seeds


def dof_scene(fstop=0.1, blades=0, rotation=0.0, ratio=1.0, use_dof=True, ortho=False):
    scenes.reset()
    scenes.set_resolution(*SIZE)
    scenes.add_plane(size=12.0, material=scenes.diffuse_material("Floor", (0.6, 0.6, 0.6)))
    colours = [(0.9, 0.2, 0.2), (0.2, 0.9, 0.2), (0.2, 0.3, 0.9), (0.9, 0.8, 0.2)]
    spheres = []
    for k, (x, y) in enumerate([(-0.9, -1.5), (-0.2, 0.0), (0.6, 2.0), (1.5, 4.5)]):
        spheres.append(scenes.add_sphere(radius=0.35, location=(x, y, 0.35), segments=24,
                                         material=scenes.diffuse_material(f"S{k}", colours[k])))
    scenes.add_light('SUN', power=3.0, angle=0.05, rotation=(0.6, 0.2, 0.3))
    scene = bpy.context.scene
    cam_data = bpy.data.cameras.new("DofCamera")
    cam_data.lens = 50.0
    if ortho:
        cam_data.type = 'ORTHO'
        cam_data.ortho_scale = ORTHO_SCALE
    cam = bpy.data.objects.new("DofCamera", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, -4.5, 0.9)
    cam.rotation_euler = (math.radians(82.0), 0.0, 0.0)
    scene.camera = cam
    dof = cam_data.dof
    dof.use_dof = use_dof
    dof.focus_object = spheres[1]
    dof.aperture_fstop = fstop
    dof.aperture_blades = blades
    dof.aperture_rotation = rotation
    dof.aperture_ratio = ratio
    return scene


def ortho_scene(**kwargs):
    return dof_scene(fstop=ORTHO_FSTOP, ortho=True, **kwargs)


def fingerprint() -> str:
    return ref.code_fingerprint([dof_scene, ortho_scene, ref.configure_cycles,
                                 (SIZE, ORTHO_FSTOP, ORTHO_SCALE, CYCLES_SAMPLES)])


def reference_path() -> pathlib.Path:
    return ref.DATA / f"cycles_dof_ortho_{SIZE[0]}x{SIZE[1]}.npz"


def load_reference() -> dict:
    """a, b (H, W, 3) float32: Cycles' orthographic DOF image from two seeds."""
    return ref.load_cached(reference_path(), fingerprint(), "cycles_dof_reference.py")


def main():
    import time

    started = time.perf_counter()
    a, b = (ref.render_cycles(ortho_scene(), CYCLES_SAMPLES, seed=s) for s in (1, 2))
    np.savez_compressed(reference_path(), a=a, b=b, samples=np.int64(CYCLES_SAMPLES),
                        fingerprint=np.str_(fingerprint()),
                        blender=np.str_(bpy.app.version_string))
    print(f"{reference_path().relative_to(ROOT)}: in {time.perf_counter() - started:.1f} s, "
          f"mean {a.mean():.4f} / {b.mean():.4f}")


if __name__ == "__main__":
    main()
