"""Cycles as the reference for a World volume of varying density (issue 16): a closed room
(4 x 4 x 2.5 m, grey diffuse walls, floor and ceiling of albedo 0.5, normals inward) lit
by a 1 m square area light under its ceiling pointing down (400 W), the camera inside
(1 m up, near the -y wall, looking along +y; the light out of its view). The World's
Volume is a Principled Volume (Color 0.8, Anisotropy 0.2, Absorption Color black:
sigma_s = 0.8 rho, sigma_a = 0.2 rho per metre) whose Density is

    rho = FOG_GAIN x Gradient(Generated) x Noise(Object)

(Math Multiply nodes): a Linear Gradient Texture of the Generated coordinates
(clamp(x, 0, 1): no fog on the room's x < 0 half, a ramp over 0 < x < 1 m, full beyond) and
a Noise Texture of the Object coordinates (NOISE). The World has no object: Cycles reads
both as the shading point's position (``compiler.background`` gives the World's
Generated as NODE_GEOM_P, the Object texture coordinate is P when there is no object),
which Photon Map's World program also reads (core/prepared.density_fields).

The room is closed, so the World's fog Cycles integrates along every ray is the fog inside
the room, which Photon Map's World box (core/prepared.world_medium_box: the room's box
widened by 1 %) holds whole.

Cycles renders full transport with BOUNCES bounces of every kind (volume bounces
included), CYCLES_SEEDS seeds of CYCLES_SAMPLES each, averaged (image_a, image_b: the odd
and even seeds; block_sigma from their difference). Cached in
tests/data/cycles_world_fog_fog_room_48x36.npz with a fingerprint of this module's scene
code. Re-render with:

    .venv/bin/python tests/blender/cycles_world_fog_reference.py
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
CYCLES_SAMPLES = 512
"""Samples per pixel and seed."""
CYCLES_SEEDS = 2
"""Renders averaged (seeds 1..CYCLES_SEEDS)."""
BOUNCES = media_ref.BOUNCES
ROOM = (4.0, 4.0, 2.5)
"""The room's size (x, y, z) in metres: x and y centred on 0, the floor at z = 0."""
WALL_ALBEDO = 0.5
FOG = {"Color": (0.8, 0.8, 0.8, 1.0), "Anisotropy": 0.2,
       "Absorption Color": (0.0, 0.0, 0.0, 1.0)}
FOG_GAIN = 1.6
"""rho = FOG_GAIN x Gradient x Noise (per metre): about 0.8 where the gradient is 1."""
NOISE = {"Scale": 0.8, "Detail": 2.0, "Roughness": 0.5}


def room(size=ROOM, albedo=WALL_ALBEDO):
    """A closed box ``size`` (x, y, z) metres, x and y centred on 0, floor at z = 0, its
    six faces' normals pointing inward, one grey diffuse material of ``albedo``."""
    sx, sy, sz = size[0] / 2, size[1] / 2, size[2]
    verts = [(x, y, z) for z in (0.0, sz) for y in (-sy, sy) for x in (-sx, sx)]
    # each quad wound so that its normal (right-hand rule) points into the room
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
             (1, 5, 7, 3)]
    mesh = bpy.data.meshes.new("Room")
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    mesh.materials.append(scenes.diffuse_material("Walls", (albedo, albedo, albedo)))
    obj = bpy.data.objects.new("Room", mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def varying_fog_world(scene):
    """The World: black background, a Principled Volume (FOG) on its Volume output whose
    Density is FOG_GAIN x Gradient(Generated).Fac x Noise(Object).Fac."""
    world = bpy.data.worlds.new("Varying Fog")
    scene.world = world
    tree = scenes.ensure_node_tree(world)
    for node in list(tree.nodes):
        if node.type != 'OUTPUT_WORLD':
            tree.nodes.remove(node)
    output = next(n for n in tree.nodes if n.type == 'OUTPUT_WORLD')
    volume = tree.nodes.new('ShaderNodeVolumePrincipled')
    for key, value in FOG.items():
        volume.inputs[key].default_value = value
    coords = tree.nodes.new('ShaderNodeTexCoord')
    gradient = tree.nodes.new('ShaderNodeTexGradient')  # Linear: clamp(x, 0, 1)
    noise = tree.nodes.new('ShaderNodeTexNoise')
    for key, value in NOISE.items():
        noise.inputs[key].default_value = value
    product = tree.nodes.new('ShaderNodeMath')
    product.operation = 'MULTIPLY'
    gain = tree.nodes.new('ShaderNodeMath')
    gain.operation = 'MULTIPLY'
    gain.inputs[1].default_value = FOG_GAIN
    tree.links.new(coords.outputs["Generated"], gradient.inputs["Vector"])
    tree.links.new(coords.outputs["Object"], noise.inputs["Vector"])
    tree.links.new(gradient.outputs["Fac"], product.inputs[0])
    tree.links.new(noise.outputs["Fac"], product.inputs[1])
    tree.links.new(product.outputs[0], gain.inputs[0])
    tree.links.new(gain.outputs[0], volume.inputs["Density"])
    tree.links.new(volume.outputs[0], output.inputs["Volume"])
    return world


def fog_room_scene(resolution=RESOLUTION):
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    room()
    scenes.add_light('AREA', location=(0.0, 0.0, ROOM[2] - 0.05), power=400.0, size=1.0,
                     name="Panel")  # unrotated: emits along -z
    scenes.add_camera(location=(0.0, -1.9, 1.0), look_at=(0.0, 2.0, 0.8), lens=20.0)
    varying_fog_world(scene)
    return scene


SCENES = {"fog_room": fog_room_scene}


def fingerprint(name=None) -> str:
    return ref.code_fingerprint([room, varying_fog_world, fog_room_scene,
                                 media_ref.configure_cycles_media,
                                 (RESOLUTION, BOUNCES, ROOM, WALL_ALBEDO, FOG, FOG_GAIN, NOISE)])

CACHE = media_ref.Cache("cycles_world_fog", SCENES, fingerprint, (CYCLES_SAMPLES, CYCLES_SEEDS),
                        RESOLUTION)
reference_path, load_reference, main = CACHE.path, CACHE.load, CACHE.main


if __name__ == "__main__":
    main(sys.argv[1:] or None)
