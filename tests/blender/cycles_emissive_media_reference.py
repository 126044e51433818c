"""Cycles as the reference for emissive media lighting the scene (issue 16): 48 x 36, no
World (black, no volume), no light, a white diffuse floor (4 m, albedo 0.8) and above it a
1 m cube whose material has only a Volume: a Principled Volume of low density that emits
(Color 0.8, Density 0.3, Anisotropy 0, Absorption Color black: sigma_s = 0.24,
sigma_a = 0.06 per metre; Emission Strength 2, Emission Color (1, 0.6, 0.3): emission
(2, 1.2, 0.6) W/(m^3 sr), radiance added per metre of path, not scaled by the density).
The only light is the medium's: the floor is lit by it, the cube glows.

Cycles renders full transport with BOUNCES bounces of every kind (volume bounces
included, caustics on, no clamping), two seeds of CYCLES_SAMPLES each, averaged. Cached in
tests/data/cycles_emissive_media_glow_cube_48x36.npz with a fingerprint of this module's
scene code. Re-render with:

    .venv/bin/python tests/blender/cycles_emissive_media_reference.py
"""

from __future__ import annotations

import pathlib
import sys

import bpy

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tests.blender import cycles_media_reference as media_ref  # noqa: E402
from tests.blender import cycles_mesh_media_reference as mesh_ref  # noqa: E402
from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes  # noqa: E402

RESOLUTION = (48, 36)
CYCLES_SAMPLES = 2048
"""Samples per pixel and seed (two seeds are averaged)."""
BOUNCES = media_ref.BOUNCES
GLOW = {"Color": (0.8, 0.8, 0.8, 1.0), "Density": 0.3, "Anisotropy": 0.0,
        "Absorption Color": (0.0, 0.0, 0.0, 1.0), "Emission Strength": 2.0,
        "Emission Color": (1.0, 0.6, 0.3, 1.0)}


def glow_cube_scene(resolution=RESOLUTION):
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    scenes.add_plane(size=4.0, material=scenes.diffuse_material("Floor", (0.8, 0.8, 0.8)))
    glow = mesh_ref.volume_material("Glow", None, 'ShaderNodeVolumePrincipled', GLOW)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.7))
    cube = bpy.context.active_object
    cube.name = "GlowBox"
    cube.data.materials.append(glow)
    scenes.add_camera(location=(0.0, -4.5, 1.6), look_at=(0.0, 0.0, 0.4), lens=32.0)
    return scene  # no World and no light: the medium is the only emitter


SCENES = {"glow_cube": glow_cube_scene}


def fingerprint(name=None) -> str:
    return ref.code_fingerprint([mesh_ref.volume_material, glow_cube_scene,
                                 media_ref.configure_cycles_media, (RESOLUTION, BOUNCES, GLOW)])

CACHE = media_ref.Cache("cycles_emissive_media", SCENES, fingerprint, (CYCLES_SAMPLES, 2),
                        RESOLUTION)
reference_path, load_reference, main = CACHE.path, CACHE.load, CACHE.main


if __name__ == "__main__":
    main(sys.argv[1:] or None)
