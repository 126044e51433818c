"""Jensen's classic test scene: a Cornell box with a mirror sphere and a glass sphere, and
the demo built on it: the same box with a glossy floor and a rough copper sphere.

As a script, from the repository root (renders with Photon Map, writes OUT.exr and OUT.png):

    .venv/bin/python examples/cornell_box.py -o out/demo [--classic] [--quality final]
        [--resolution 320x240] [--samples N] [--global-photons N] [--caustic-photons N]
        [--gather-rays N] [--indirect final_gather|preview|off] [--save-blend out/demo.blend]

The settings are the Quality dial's (Render Properties > Quality; default Final: 32
samples, 500,000 + 500,000 photons, k 100, 256 gather rays); any of --samples,
--global-photons, --caustic-photons, --gather-rays or --indirect changes that value only,
and the dial reads Custom, as it does in Blender. The script renders the demo
(``build_demo``); --classic renders Jensen's box as it is (``build_cornell_box``).

As a module (the tests build it for Cycles and Photon Map alike):

    from examples.cornell_box import build_cornell_box, build_demo
    build_cornell_box(scale=1e-3, offset=(1e4, 1e4, 1e4))

The box is 2 m wide, deep and high (x in [-1, 1], y in [-1, 1], z in [0, 2] before
``scale`` and ``offset``), open towards -Y where the camera looks in. Walls are Diffuse
BSDFs with the reflectances of the original Cornell box (white floor, ceiling and back
wall, red left wall, green right wall). The mirror is a Glossy BSDF of roughness 0, the
glass sphere a Glass BSDF of IOR 1.5; a small square area light hangs just below the
ceiling, facing down, and is visible to the camera. The world is black.

The demo (``build_demo``) changes two things: the floor is a Principled BSDF of roughness
0.2 (white base, a dielectric specular layer: a glossy floor that blurs the spheres and the
light in it), and a copper sphere (Principled, Metallic 1, Roughness 0.3) lies in the left
front corner beside the mirror sphere.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import pathlib
import sys
import time

import bpy
import bmesh

ROOT = pathlib.Path(__file__).resolve().parents[1]

# Linear RGB reflectances (Cornell box measured data, reduced to RGB).
WHITE = (0.725, 0.71, 0.68)
RED = (0.63, 0.065, 0.05)
GREEN = (0.14, 0.45, 0.091)
MIRROR = (0.9, 0.9, 0.9)

LIGHT_SIZE = 0.5
"""Side of the square area light, metres (at scale 1)."""
LIGHT_POWER = 50.0
"""Area light power at scale 1, watts: about 1 W/(m^2 sr) on the floor below it."""
SPHERE_RADIUS = 0.38
MIRROR_CENTRE = (-0.45, 0.35, SPHERE_RADIUS)
GLASS_CENTRE = (0.45, -0.35, SPHERE_RADIUS)
CAMERA_LOCATION = (0.0, -3.0, 1.0)

FLOOR_ROUGHNESS = 0.2
"""The demo's glossy floor: a Principled BSDF (base WHITE) of this roughness."""
COPPER = (0.955, 0.637, 0.538)
"""Copper's Base Color (linear RGB, its reflectance at normal incidence)."""
COPPER_ROUGHNESS = 0.3
COPPER_RADIUS = 0.22
COPPER_CENTRE = (-0.68, -0.25, COPPER_RADIUS)
"""On the floor, 0.06 m clear of the mirror sphere and 0.1 m of the left wall."""

DEMO_QUALITY = "final"
"""The demo's Quality preset: smooth indirect light and caustics at 320 x 240 in about
30 s on 2 cores (docs/photon_rendering.md)."""


def _material(name, idname, color, **inputs):
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender < 5.0
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    bsdf = nodes.new(idname)
    bsdf.inputs["Color"].default_value = (*color, 1.0)
    for key, value in inputs.items():
        bsdf.inputs[key].default_value = value
    out = nodes.new('ShaderNodeOutputMaterial')
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def _principled(name, color, **inputs):
    """A material of one Principled BSDF: Base Color ``color``, other inputs by name."""
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender < 5.0
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    bsdf = nodes.new('ShaderNodeBsdfPrincipled')
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    for key, value in inputs.items():
        bsdf.inputs[key].default_value = value
    out = nodes.new('ShaderNodeOutputMaterial')
    links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def _mesh_object(name, bm, material, collection, location):
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    collection.objects.link(obj)
    return obj


def _quad(name, corners, material, collection, location):
    """A quad; ``corners`` relative to ``location``, counter-clockwise seen from the lit side."""
    bm = bmesh.new()
    verts = [bm.verts.new(c) for c in corners]
    bm.faces.new(verts)
    return _mesh_object(name, bm, material, collection, location)


def _sphere(name, centre, radius, material, collection, segments=64):
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=segments // 2, radius=radius)
    for face in bm.faces:
        face.smooth = True
    return _mesh_object(name, bm, material, collection, centre)


def build_cornell_box(scale=1.0, offset=(0.0, 0.0, 0.0), resolution=(320, 240),
                      light_power=LIGHT_POWER, scene=None):
    """Build the scene into ``scene`` (default: the current one, assumed empty).

    scale: every length is multiplied by it, and the light power by scale^2, so the
        irradiance and so the image stay the same.
    offset: (3,) metres added to every position after scaling (camera included).
    resolution: (width, height) pixels, at 100 %.
    Returns the scene. The render engine is left as it is.
    """
    scene = scene or bpy.context.scene
    s = float(scale)
    ox, oy, oz = (float(v) for v in offset)

    def at(x, y, z):
        return (ox + s * x, oy + s * y, oz + s * z)

    def rel(x, y, z):
        return (s * x, s * y, s * z)

    coll = scene.collection
    white = _material("White", 'ShaderNodeBsdfDiffuse', WHITE)
    red = _material("Red", 'ShaderNodeBsdfDiffuse', RED)
    green = _material("Green", 'ShaderNodeBsdfDiffuse', GREEN)
    mirror = _material("Mirror", 'ShaderNodeBsdfGlossy', MIRROR, Roughness=0.0)
    glass = _material("Glass", 'ShaderNodeBsdfGlass', (1.0, 1.0, 1.0), Roughness=0.0, IOR=1.5)

    # Walls, normals facing into the box. Mesh data stays near each object's origin and
    # the offset goes into the object's location, as it would in a real scene: Blender
    # stores vertices in float32, so baking 1e4 m into them would quantise the geometry
    # (and its normals) to a millimetre.
    origin = at(0, 0, 0)
    _quad("Floor", [rel(-1, -1, 0), rel(1, -1, 0), rel(1, 1, 0), rel(-1, 1, 0)], white, coll, origin)
    _quad("Ceiling", [rel(-1, -1, 2), rel(-1, 1, 2), rel(1, 1, 2), rel(1, -1, 2)], white, coll, origin)
    _quad("Back", [rel(-1, 1, 0), rel(1, 1, 0), rel(1, 1, 2), rel(-1, 1, 2)], white, coll, origin)
    _quad("Left", [rel(-1, -1, 0), rel(-1, 1, 0), rel(-1, 1, 2), rel(-1, -1, 2)], red, coll, origin)
    _quad("Right", [rel(1, -1, 0), rel(1, -1, 2), rel(1, 1, 2), rel(1, 1, 0)], green, coll, origin)
    _sphere("MirrorSphere", at(*MIRROR_CENTRE), s * SPHERE_RADIUS, mirror, coll)
    _sphere("GlassSphere", at(*GLASS_CENTRE), s * SPHERE_RADIUS, glass, coll)

    light = bpy.data.lights.new("CeilingLight", 'AREA')
    light.shape = 'SQUARE'
    light.size = s * LIGHT_SIZE
    light.energy = light_power * s * s
    light_obj = bpy.data.objects.new("CeilingLight", light)
    light_obj.location = at(0.0, 0.0, 1.98)  # just below the ceiling, facing down (-Z)
    light_obj.visible_camera = True
    coll.objects.link(light_obj)

    cam = bpy.data.cameras.new("Camera")
    cam.lens = 35.0
    cam.sensor_width = 36.0
    cam.clip_start = 0.01 * s
    cam.clip_end = 100.0 * s
    cam_obj = bpy.data.objects.new("Camera", cam)
    cam_obj.location = at(*CAMERA_LOCATION)
    cam_obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looking along +Y, Z up
    coll.objects.link(cam_obj)
    scene.camera = cam_obj

    world = bpy.data.worlds.new("Black")
    if world.node_tree is None:
        world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        bg.inputs["Strength"].default_value = 0.0
    world.color = (0.0, 0.0, 0.0)
    scene.world = world

    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    return scene


def build_demo(scale=1.0, offset=(0.0, 0.0, 0.0), resolution=(320, 240),
                light_power=LIGHT_POWER, scene=None):
    """The demo scene: ``build_cornell_box`` (same arguments, same return) with a glossy
    floor (Principled, roughness FLOOR_ROUGHNESS) and a rough copper sphere (Principled,
    Metallic 1, Roughness COPPER_ROUGHNESS, radius COPPER_RADIUS at COPPER_CENTRE)."""
    scene = build_cornell_box(scale, offset, resolution, light_power, scene)
    s = float(scale)
    ox, oy, oz = (float(v) for v in offset)
    floor = bpy.data.objects["Floor"]
    floor.data.materials[0] = _principled("GlossyFloor", WHITE, Roughness=FLOOR_ROUGHNESS)
    copper = _principled("Copper", COPPER, Metallic=1.0, Roughness=COPPER_ROUGHNESS)
    cx, cy, cz = COPPER_CENTRE
    _sphere("CopperSphere", (ox + s * cx, oy + s * cy, oz + s * cz), s * COPPER_RADIUS, copper,
            scene.collection)
    return scene


def load_photon_map():
    """Import the repository as the extension package ``photon_map`` and register the engine.

    Uses the CLI's own bootstrap (photon_engine/__main__.py), so the demo loads the engine
    exactly as ``python -m photon_engine`` does.
    """
    spec = importlib.util.spec_from_file_location(
        "_photon_map_bootstrap", ROOT / "photon_engine" / "__main__.py")
    bootstrap = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bootstrap)
    package = bootstrap.load_extension_package()
    if not hasattr(bpy.types.Scene, "photon_map"):
        package.register()
    return package


def _resolution(text):
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, e.g. 320x240, got {text!r}") from None
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError(f"resolution must be positive, got {text!r}")
    return w, h


def main(argv=None):
    parser = argparse.ArgumentParser(description="Render the demo (a Cornell box with a glossy "
                                     "floor and a copper sphere) with Photon Map.")
    parser.add_argument("-o", "--output", default="out/demo",
                        help="output path without extension: writes OUTPUT.exr and OUTPUT.png")
    parser.add_argument("--classic", action="store_true",
                        help="Jensen's box as it is: Lambert floor, no copper sphere")
    parser.add_argument("--quality", choices=("draft", "preview", "final", "converged"),
                        default=DEMO_QUALITY, help=f"the Quality preset (default {DEMO_QUALITY})")
    parser.add_argument("--samples", type=int, help="camera samples per pixel")
    parser.add_argument("--global-photons", type=int,
                        help="photons emitted for the global map (indirect light)")
    parser.add_argument("--caustic-photons", type=int,
                        help="photons aimed at the spheres for the caustic map")
    parser.add_argument("--gather-rays", type=int, help="final-gather rays per pixel")
    parser.add_argument("--indirect", choices=("final_gather", "preview", "off"),
                        help="indirect light mode")
    parser.add_argument("--resolution", type=_resolution, default=(320, 240),
                        help="WIDTHxHEIGHT in pixels (default 320x240)")
    parser.add_argument("--save-blend", metavar="PATH",
                        help="also save the scene as a .blend (for the CLI or blender -b)")
    args = parser.parse_args(argv)

    package = load_photon_map()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    build = build_cornell_box if args.classic else build_demo
    scene = build(resolution=args.resolution)
    scene.render.engine = 'PHOTON_MAP'
    settings = scene.photon_map
    settings.quality = args.quality
    # Each value given by hand overrides the preset's (the dial then reads Custom).
    for name, value in (("samples", args.samples), ("global_photons", args.global_photons),
                        ("caustic_photons", args.caustic_photons),
                        ("final_gather_rays", args.gather_rays),
                        ("indirect_mode", args.indirect)):
        if value is not None:
            setattr(settings, name, value)
    if args.save_blend:
        path = pathlib.Path(args.save_blend).resolve()
        path.parent.mkdir(parents=True, exist_ok=True)
        bpy.ops.wm.save_as_mainfile(filepath=str(path))
        print(f"saved {path}")

    started = time.perf_counter()
    try:
        bpy.ops.render.render()
    except RuntimeError as error:
        print(f"cornell_box: render failed: {error}", file=sys.stderr)
        return 1
    elapsed = time.perf_counter() - started

    from importlib import import_module
    cli = import_module(f"{package.__name__}.photon_engine.cli")
    out = pathlib.Path(args.output).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    result = bpy.data.images["Render Result"]
    for fmt, ext in (("OPEN_EXR_MULTILAYER", ".exr"), ("PNG", ".png")):
        cli.set_format(scene.render.image_settings, fmt)
        result.save_render(filepath=str(out) + ext, scene=scene)
        print(f"wrote {out}{ext}")
    w, h = args.resolution
    print(f"rendered {'classic box' if args.classic else 'demo'} {w}x{h} at "
          f"{settings.samples} samples/pixel (quality "
          f"{settings.quality}) in {elapsed:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
