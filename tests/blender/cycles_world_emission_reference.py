"""Cycles as the reference for the World's volume emission lighting the scene (issue 16):
48 x 36, no light, a grey floor (10 m, albedo 0.5) with a white 0.6 m cube (albedo 0.8)
on it, and on the World's Volume a Principled Volume that only absorbs and emits (Color
black, Density 0.6, Absorption Color black: sigma_a = 0.6 per metre, sigma_s = 0; Emission
Strength 1, Emission Color (1, 0.6, 0.3): emission (1, 0.6, 0.3) W/(m^3 sr)); the World's
background black. Everything is lit by the glowing air: in Cycles by an infinite medium,
in Photon Map by its photons from the scene's bounding sphere (radius 7.1 m here: light
from farther out is attenuated by exp(-0.6 x 7.1) = 1.4 % straight up from the centre).

Cycles renders full transport with BOUNCES bounces of every kind, two seeds of
CYCLES_SAMPLES each, averaged; cached with the Emission pass (what camera rays collect
from the medium itself) in tests/data/cycles_world_emission_glow_air_48x36.npz with a
fingerprint of this module's scene code. Re-render with:

    .venv/bin/python tests/blender/cycles_world_emission_reference.py
"""

from __future__ import annotations

import pathlib
import sys

import bpy

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tests.blender import cycles_media_reference as media_ref  # noqa: E402
from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes  # noqa: E402

RESOLUTION = (48, 36)
CYCLES_SAMPLES = 1024
"""Samples per pixel and seed (two seeds are averaged)."""
BOUNCES = media_ref.BOUNCES
AIR = {"Color": (0.0, 0.0, 0.0, 1.0), "Density": 0.6, "Anisotropy": 0.0,
       "Absorption Color": (0.0, 0.0, 0.0, 1.0), "Emission Strength": 1.0,
       "Emission Color": (1.0, 0.6, 0.3, 1.0)}


def glow_air_world(scene):
    """The World: black background, the Principled Volume AIR on its Volume output."""
    world = bpy.data.worlds.new("Glowing air")
    scene.world = world
    tree = scenes.ensure_node_tree(world)
    for node in list(tree.nodes):
        if node.type != 'OUTPUT_WORLD':
            tree.nodes.remove(node)
    output = next(n for n in tree.nodes if n.type == 'OUTPUT_WORLD')
    volume = tree.nodes.new('ShaderNodeVolumePrincipled')
    for key, value in AIR.items():
        volume.inputs[key].default_value = value
    tree.links.new(volume.outputs[0], output.inputs["Volume"])
    return world


def glow_air_scene(resolution=RESOLUTION):
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    scenes.add_plane(size=10.0, material=scenes.diffuse_material("Floor", (0.5, 0.5, 0.5)))
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(0.0, 0.0, 0.3))
    cube = bpy.context.active_object
    cube.name = "Cube"
    cube.data.materials.append(scenes.diffuse_material("White", (0.8, 0.8, 0.8)))
    scenes.add_camera(location=(0.0, -1.6, 1.0), look_at=(0.0, 0.0, 0.25), lens=28.0)
    glow_air_world(scene)
    scene.view_layers[0].use_pass_emit = True
    return scene


SCENES = {"glow_air": glow_air_scene}


def fingerprint(name=None) -> str:
    return ref.code_fingerprint([glow_air_world, glow_air_scene, media_ref.configure_cycles_media,
                                 (RESOLUTION, BOUNCES, AIR)])

CACHE = media_ref.Cache("cycles_world_emission", SCENES, fingerprint, (CYCLES_SAMPLES, 2),
                        RESOLUTION, extra_passes=("Emission",))
reference_path, load_reference, main = CACHE.path, CACHE.load, CACHE.main


if __name__ == "__main__":
    main(sys.argv[1:] or None)
