"""Cycles as the reference for heterogeneous density (issue 16): the fog cube of
cycles_mesh_media_reference.py (1.2 m, 0.1 m above a grey floor, spot light 300 W above it,
no World) whose Principled Volume Density is a Noise Texture over the Object coordinates
times NOISE_GAIN (Scale 2.5, Detail 2: density about 0.5 to 2.6 per metre, Color 0.8,
Anisotropy 0.2, Absorption Color black).

Cycles (null-scattering tracking of heterogeneous volumes) renders full transport with
BOUNCES bounces of every kind, volume bounces included, two seeds of CYCLES_SAMPLES each,
averaged. Cached in tests/data/cycles_noise_media_fog_noise_48x36.npz with a fingerprint
of this module's scene code. Re-render with:

    .venv/bin/python tests/blender/cycles_noise_media_reference.py
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

RESOLUTION = mesh_ref.RESOLUTION
CYCLES_SAMPLES = 2048
"""Samples per pixel and seed (two seeds are averaged)."""
NOISE = {"Scale": 2.5, "Detail": 2.0, "Roughness": 0.5}
NOISE_GAIN = 3.0
"""Density = NOISE_GAIN x the Noise Fac (Math Multiply)."""


def noise_fog_scene():
    """mesh_ref's fog cube with a Noise-driven Density."""
    scene = mesh_ref.mesh_media_scene("fog_cube")
    mat = bpy.data.materials["Fog"]
    tree = mat.node_tree
    vol = next(n for n in tree.nodes if n.bl_idname == 'ShaderNodeVolumePrincipled')
    coord = tree.nodes.new('ShaderNodeTexCoord')
    noise = tree.nodes.new('ShaderNodeTexNoise')
    for key, value in NOISE.items():
        noise.inputs[key].default_value = value
    gain = tree.nodes.new('ShaderNodeMath')
    gain.operation = 'MULTIPLY'
    gain.inputs[1].default_value = NOISE_GAIN
    tree.links.new(coord.outputs["Object"], noise.inputs["Vector"])
    tree.links.new(noise.outputs["Fac"], gain.inputs[0])
    tree.links.new(gain.outputs[0], vol.inputs["Density"])
    return scene


SCENES = {"fog_noise": noise_fog_scene}


def fingerprint(name=None) -> str:
    return ref.code_fingerprint([noise_fog_scene, mesh_ref.fingerprint(),
                                 (RESOLUTION, NOISE, NOISE_GAIN)])

CACHE = media_ref.Cache("cycles_noise_media", SCENES, fingerprint, (CYCLES_SAMPLES, 2), RESOLUTION)
reference_path, load_reference, main = CACHE.path, CACHE.load, CACHE.main


if __name__ == "__main__":
    main(sys.argv[1:] or None)
