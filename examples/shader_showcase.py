"""Shader graphs against Cycles: procedural wood, a normal-mapped brick wall, a metal whose
roughness is a noise texture and props coloured by a colour attribute, under an area light
and a uniform sky (issue 14's picture).

As a script, from the repository root (renders the scene with Cycles and with Photon Map
in this bpy process and writes the two side by side, Cycles left, captioned; prints the
channel means of both and their relative difference):

    .venv/bin/python examples/shader_showcase.py [-o docs/images/shader_showcase.png]
        [--small] [--cycles-samples 64] [--samples 32]

--small renders the 64 x 48 scene of tests/blender/test_shader_showcase.py instead of
320 x 240.

As a module:

    from examples.shader_showcase import build_showcase
    scene = build_showcase(resolution=(64, 48))

The scene (metres, Z up, the camera 5 m in front looking along +Y):
- floor: a 6 m square, Principled; Base Color = ColorRamp(Wave Texture bands distorted
  by its noise, on object coordinates stretched along Y): planks of wood; the same Wave
  into a Bump for the grain;
- wall: 4 m x 2.5 m at y = 1.5; Base Color = Brick Texture on its UV; Normal = Normal
  Map (tangent space, UV) of an Image Texture (Non-Color) computed here in numpy from
  the same brick layout (``brick_normal_map``): the bricks' edges bevelled, the mortar
  sunk;
- metal: a sphere, Principled Metallic 1, copper; Roughness = Map Range(Noise Texture)
  from 0.15 to 0.55;
- props: two boxes whose Base Color is a Color Attribute ("Paint", float colours per
  vertex, set here);
- an area light (1.5 m square, 200 W) above and in front, a uniform world (sky blue,
  strength 1).
Cycles renders it with 8 diffuse / glossy bounces, as Photon Map's photon_max_bounces
(tests/blender/cycles_gi_reference.py's settings), reflective caustics on: Photon Map's
global photons carry the light the metal reflects onto the floor.
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys
import time

import numpy as np

import bpy

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

WALL_SIZE = (4.0, 2.5)
"""The brick wall's width and height, metres (its UV spans it: u along x, v up)."""
BRICK_SCALE = 1.5
"""Brick Texture Scale on the Mapping's (u * 4, v * 2.5): bricks 0.5 / 1.5 = 33 cm long."""
BRICK_WIDTH, ROW_HEIGHT, MORTAR = 0.5, 0.25, 0.02
"""Brick Texture's Brick Width, Row Height and Mortar Size (its texture units)."""
BEVEL = 0.04
"""The normal map's bevel at the bricks' edges, texture units (twice the mortar)."""
NORMAL_STRENGTH = 1.0
NORMAL_MAP_SIZE = (256, 160)
"""Normal-map image (width, height) pixels: the wall's aspect ratio."""
SKY = (0.35, 0.45, 0.6)
LIGHT_POWER = 200.0
PAINT = ((0.8, 0.1, 0.1), (0.1, 0.6, 0.15), (0.1, 0.2, 0.8), (0.85, 0.75, 0.1))
"""The props' vertex colours (linear RGB), cycled over each box's corners."""


def brick_layout(px, py):
    """Distance (texture units) from (px, py) (arrays) to the nearest mortar edge of
    Cycles' Brick Texture (svm_brick: offset 0.5 on every second row, squash 1), the
    brick's own width and height being BRICK_WIDTH and ROW_HEIGHT."""
    row = np.floor(py / ROW_HEIGHT)
    offset = np.where(np.mod(row, 2) == 0, BRICK_WIDTH * 0.5, 0.0)
    brick = np.floor((px + offset) / BRICK_WIDTH)
    x = px + offset - brick * BRICK_WIDTH
    y = py - row * ROW_HEIGHT
    return np.minimum(np.minimum(x, y), np.minimum(BRICK_WIDTH - x, ROW_HEIGHT - y))


def brick_normal_map(size=NORMAL_MAP_SIZE) -> np.ndarray:
    """(H, W, 4) float32 RGBA, row 0 at the bottom (Blender's pixel order): a tangent-space
    normal map of the wall's bricks over its UV square. Height: 0 in the mortar, rising
    linearly to 1 over BEVEL inside each brick; the normal (-dh/du', -dh/dv', 1) over the
    wall's metres (u' = 4 u, v' = 2.5 v) scaled by NORMAL_STRENGTH, encoded n / 2 + 1 / 2."""
    w, h = size
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    U, V = np.meshgrid(u, v)
    k = BRICK_SCALE
    d = brick_layout(U * WALL_SIZE[0] * k, V * WALL_SIZE[1] * k)
    height = np.clip((d - MORTAR) / BEVEL, 0.0, 1.0) * (BEVEL / k)  # metres
    gy, gx = np.gradient(height, WALL_SIZE[1] / h, WALL_SIZE[0] / w)
    n = np.stack([-NORMAL_STRENGTH * gx, -NORMAL_STRENGTH * gy, np.ones_like(gx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.concatenate([0.5 * n + 0.5, np.ones((h, w, 1))], axis=-1).astype(np.float32)


def _material(name):
    """A new material with an empty node tree and its output; (material, tree, output)."""
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender < 5.0
        mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    return mat, tree, tree.nodes.new("ShaderNodeOutputMaterial")


def _principled(tree, out, **inputs):
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    for key, value in inputs.items():
        socket = bsdf.inputs[key.replace("_", " ")]
        socket.default_value = (*value, 1.0) if socket.type == 'RGBA' else value
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return bsdf


def wood_material():
    mat, tree, out = _material("Wood")
    bsdf = _principled(tree, out, Roughness=0.45)
    coord = tree.nodes.new("ShaderNodeTexCoord")
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (1.0, 0.15, 1.0)
    tree.links.new(coord.outputs["Object"], mapping.inputs["Vector"])
    wave = tree.nodes.new("ShaderNodeTexWave")
    wave.wave_type = 'BANDS'
    wave.bands_direction = 'X'
    wave.inputs["Scale"].default_value = 1.2
    wave.inputs["Distortion"].default_value = 6.0
    wave.inputs["Detail"].default_value = 2.0
    wave.inputs["Detail Scale"].default_value = 1.5
    tree.links.new(mapping.outputs["Vector"], wave.inputs["Vector"])
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.16, 0.07, 0.025, 1.0)
    ramp.color_ramp.elements[1].color = (0.55, 0.3, 0.12, 1.0)
    mid = ramp.color_ramp.elements.new(0.6)
    mid.color = (0.38, 0.19, 0.07, 1.0)
    tree.links.new(wave.outputs["Fac"], ramp.inputs["Fac"])
    tree.links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    bump = tree.nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = 0.3
    bump.inputs["Distance"].default_value = 0.005
    tree.links.new(wave.outputs["Fac"], bump.inputs["Height"])
    tree.links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    return mat


def brick_material():
    mat, tree, out = _material("Bricks")
    bsdf = _principled(tree, out, Roughness=0.8)
    coord = tree.nodes.new("ShaderNodeTexCoord")
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (*WALL_SIZE, 1.0)
    tree.links.new(coord.outputs["UV"], mapping.inputs["Vector"])
    brick = tree.nodes.new("ShaderNodeTexBrick")
    brick.offset, brick.offset_frequency = 0.5, 2
    brick.inputs["Scale"].default_value = BRICK_SCALE
    brick.inputs["Brick Width"].default_value = BRICK_WIDTH
    brick.inputs["Row Height"].default_value = ROW_HEIGHT
    brick.inputs["Mortar Size"].default_value = MORTAR
    brick.inputs["Color1"].default_value = (0.5, 0.12, 0.06, 1.0)
    brick.inputs["Color2"].default_value = (0.35, 0.09, 0.05, 1.0)
    brick.inputs["Mortar"].default_value = (0.6, 0.58, 0.55, 1.0)
    tree.links.new(mapping.outputs["Vector"], brick.inputs["Vector"])
    tree.links.new(brick.outputs["Color"], bsdf.inputs["Base Color"])
    w, h = NORMAL_MAP_SIZE
    image = bpy.data.images.new("BrickNormals", w, h, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(brick_normal_map().ravel())
    image.pack()  # a generated image: kept in the .blend if one is saved
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = 'Linear'
    tree.links.new(coord.outputs["UV"], tex.inputs["Vector"])
    nmap = tree.nodes.new("ShaderNodeNormalMap")
    nmap.space = 'TANGENT'
    nmap.uv_map = "UVMap"
    nmap.inputs["Strength"].default_value = 1.0
    tree.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    tree.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    return mat


def metal_material():
    mat, tree, out = _material("Copper")
    bsdf = _principled(tree, out, Base_Color=(0.95, 0.64, 0.54), Metallic=1.0)
    noise = tree.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 4.0
    noise.inputs["Detail"].default_value = 3.0
    remap = tree.nodes.new("ShaderNodeMapRange")
    remap.inputs["From Min"].default_value = 0.3
    remap.inputs["From Max"].default_value = 0.7
    remap.inputs["To Min"].default_value = 0.15
    remap.inputs["To Max"].default_value = 0.55
    tree.links.new(noise.outputs["Fac"], remap.inputs["Value"])
    tree.links.new(remap.outputs["Result"], bsdf.inputs["Roughness"])
    return mat


def painted_material():
    mat, tree, out = _material("Painted")
    bsdf = _principled(tree, out, Roughness=0.5)
    attr = tree.nodes.new("ShaderNodeVertexColor")
    attr.layer_name = "Paint"
    tree.links.new(attr.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def _add(op, material, name, **kw):
    op(**kw)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.materials.append(material)
    return obj


def _paint(obj):
    """A float colour per vertex (PAINT cycled), domain POINT: interpolated over faces."""
    mesh = obj.data
    att = mesh.color_attributes.new("Paint", 'FLOAT_COLOR', 'POINT')
    n = len(mesh.vertices)
    colours = np.array([(*PAINT[i % len(PAINT)], 1.0) for i in range(n)], np.float32)
    att.data.foreach_set("color", colours.ravel())


def build_showcase(resolution=(320, 240), scene=None):
    """Build the scene (module doc) into ``scene`` (default: the current one, assumed
    empty); resolution (width, height) pixels at 100 %. Returns the scene; the render
    engine is left as it is."""
    scene = scene or bpy.context.scene
    ops = bpy.ops.mesh
    _add(ops.primitive_plane_add, wood_material(), "Floor", size=6.0)
    wall = _add(ops.primitive_plane_add, brick_material(), "Wall", size=1.0,
                location=(0.0, 1.5, WALL_SIZE[1] / 2), rotation=(math.pi / 2, 0.0, 0.0))
    # The size goes into the mesh, not the object's (non-uniform) scale.
    co = np.empty(3 * len(wall.data.vertices), np.float32)
    wall.data.vertices.foreach_get("co", co)
    wall.data.vertices.foreach_set("co", (co.reshape(-1, 3) * (*WALL_SIZE, 1.0)).ravel())
    sphere = _add(ops.primitive_uv_sphere_add, metal_material(), "Metal", radius=0.5,
                  location=(-0.85, 0.3, 0.5), segments=48, ring_count=24)
    for poly in sphere.data.polygons:
        poly.use_smooth = True
    painted = painted_material()
    for name, size, loc, angle in (("Box", 0.7, (0.8, 0.0, 0.35), 0.5),
                                   ("SmallBox", 0.4, (0.2, 0.85, 0.2), -0.3)):
        box = _add(ops.primitive_cube_add, painted, name, size=size, location=loc,
                   rotation=(0.0, 0.0, angle))
        _paint(box)

    light = bpy.data.lights.new("Key", 'AREA')
    light.shape, light.size, light.energy = 'SQUARE', 1.5, LIGHT_POWER
    key = bpy.data.objects.new("Key", light)
    key.location = (1.2, -1.6, 3.2)
    key.rotation_euler = (math.radians(35.0), 0.0, math.radians(20.0))
    scene.collection.objects.link(key)

    world = bpy.data.worlds.new("Sky")
    if world.node_tree is None:
        world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    bg.inputs["Color"].default_value = (*SKY, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world

    cam = bpy.data.cameras.new("Camera")
    cam.lens, cam.sensor_width = 32.0, 36.0
    cam_obj = bpy.data.objects.new("Camera", cam)
    cam_obj.location = (0.0, -4.6, 1.7)
    cam_obj.rotation_euler = (math.radians(78.0), 0.0, 0.0)
    scene.collection.objects.link(cam_obj)
    scene.camera = cam_obj
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    return scene


def render_both(resolution, cycles_samples, samples, seed=1):
    """Cycles and Photon Map renders of the showcase in this bpy process: (cycles, ours)
    (H, W, 3) float32 linear radiance (Combined), row 0 at the top; the Photon Map
    render's passes as a third item."""
    from tests.blender import cycles_gi_reference as gi
    from tests.blender import scenes

    scene = scenes.reset()
    build_showcase(resolution, scene)
    gi.configure_cycles_gi(scene, cycles_samples, seed)
    # The light the metal reflects onto the floor: Photon Map's global photons carry it.
    scene.cycles.caustics_reflective = True
    cycles = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float32)
    scenes.use_photon_map(scene, samples=samples, seed=seed, final_gather_rays=256,
                          photon_max_bounces=gi.BOUNCES, indirect_mode='final_gather')
    passes = scenes.render_passes(scene)
    return cycles, passes["Combined"][..., :3].astype(np.float32), passes


def side_by_side(path, cycles, ours, captions):
    """Write the two linear images side by side as an sRGB PNG (Standard view), each with
    its caption underneath; returns path."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from core.io.exr import srgb_encode

    h, w = cycles.shape[:2]
    dpi = 100
    fig = plt.figure(figsize=(2 * w / dpi, (h + 28) / dpi), dpi=dpi)
    for i, (img, text) in enumerate(zip((cycles, ours), captions)):
        ax = fig.add_axes([i / 2, 28 / (h + 28), 0.5, h / (h + 28)])
        ax.imshow(srgb_encode(img), interpolation="nearest")
        ax.set_axis_off()
        fig.text(i / 2 + 0.25, 10 / (h + 28), text, ha="center", va="center", fontsize=9)
    pathlib.Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-o", "--output", default=str(ROOT / "docs" / "images" /
                                                      "shader_showcase.png"))
    parser.add_argument("--small", action="store_true", help="64 x 48 (the test's scene)")
    parser.add_argument("--cycles-samples", type=int, default=64)
    parser.add_argument("--samples", type=int, default=32, help="Photon Map's samples")
    args = parser.parse_args(argv)
    resolution = (64, 48) if args.small else (320, 240)
    t0 = time.perf_counter()
    cycles, ours, _ = render_both(resolution, args.cycles_samples, args.samples)
    mc, mo = cycles.reshape(-1, 3).mean(0), ours.reshape(-1, 3).mean(0)
    diff = 100.0 * (mo / mc - 1.0)
    print(f"{resolution[0]}x{resolution[1]} in {time.perf_counter() - t0:.0f} s; channel "
          f"means Cycles {np.round(mc, 4)}, Photon Map {np.round(mo, 4)}: "
          f"{np.round(diff, 2)} %")
    side_by_side(args.output, cycles, ours, (
        f"Cycles, {args.cycles_samples} spp",
        f"Photon Map, {args.samples} spp (means {diff[0]:+.1f} / {diff[1]:+.1f} / "
        f"{diff[2]:+.1f} %)"))
    print("wrote", args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
