"""Cycles as the reference for a varying Principled Volume colour (issue 16): the fog cube
of cycles_mesh_media_reference.py (1.2 m, 0.1 m above a grey floor, spot light 300 W above
it, no World; Principled Volume Density 0.8, Anisotropy 0.2) whose **Color** is a Noise
Texture's Color over the Object coordinates (Scale 2, Detail 1: each channel about 0.2 to
0.8, varying apart) and whose **Absorption Color** is a Linear Gradient's Color along the
object's x (0 at x <= 0 to 0.6 at the +x face), so the albedo and the absorption's tint
both vary across the cube.

Cycles renders full transport with BOUNCES bounces of every kind, volume bounces included,
two seeds of CYCLES_SAMPLES each, averaged. Cached in
tests/data/cycles_colour_media_fog_colour_48x36.npz with a fingerprint of this module's
scene code. Re-render with:

    .venv/bin/python tests/blender/cycles_colour_media_reference.py
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
NOISE = {"Scale": 2.0, "Detail": 1.0, "Roughness": 0.5}


def colour_fog_scene():
    """mesh_ref's fog cube with a Noise-driven Color and a Gradient-driven Absorption
    Color."""
    scene = mesh_ref.mesh_media_scene("fog_cube")
    mat = bpy.data.materials["Fog"]
    tree = mat.node_tree
    vol = next(n for n in tree.nodes if n.bl_idname == 'ShaderNodeVolumePrincipled')
    coord = tree.nodes.new('ShaderNodeTexCoord')
    noise = tree.nodes.new('ShaderNodeTexNoise')
    for key, value in NOISE.items():
        noise.inputs[key].default_value = value
    gradient = tree.nodes.new('ShaderNodeTexGradient')
    gradient.gradient_type = 'LINEAR'
    tree.links.new(coord.outputs["Object"], noise.inputs["Vector"])
    tree.links.new(coord.outputs["Object"], gradient.inputs["Vector"])
    tree.links.new(noise.outputs["Color"], vol.inputs["Color"])
    tree.links.new(gradient.outputs["Color"], vol.inputs["Absorption Color"])
    return scene


SCENES = {"fog_colour": colour_fog_scene}


def fingerprint(name=None) -> str:
    return ref.code_fingerprint([colour_fog_scene, mesh_ref.fingerprint(), (RESOLUTION, NOISE)])

CACHE = media_ref.Cache("cycles_colour_media", SCENES, fingerprint, (CYCLES_SAMPLES, 2), RESOLUTION)
reference_path, load_reference, main = CACHE.path, CACHE.load, CACHE.main


if __name__ == "__main__":
    main(sys.argv[1:] or None)
