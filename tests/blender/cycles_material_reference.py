"""Cycles as the reference for Photon Map's materials (issue 13): one sphere per material in
a uniform world plus an area light, and a rough-metal sphere in the demo's Cornell box.

The sphere scenes: a smooth UV sphere (radius 0.5 m, 64 segments) at the origin, a world of
uniform radiance WORLD (lights the sphere, hidden from camera rays, so the image is the
sphere on black), a 0.5 m square area light of LIGHT_POWER up to the right, a camera 3 m
away. Nothing else: what the sphere shows is its BSDF under a uniform environment and one
light (glass and the thin wall also refract the world through the sphere).
``MATERIALS`` names each material and the node tree that makes it: every plain lobe of
issue 13 (Diffuse with and without roughness, Glossy, Metallic, Glass, Refraction,
Translucent, Sheen) and the Principled BSDF (default; roughness 0 / 0.25 / 0.6 x metallic
0 / 1; coat; sheen; rough glass; thin wall, Blender 5.2's input; an anisotropic gold
metal, whose unlinked Tangent is Cycles' radial default), a Mix Shader of Diffuse
and Glossy and an Add Shader of Diffuse and Sheen; two Principled BSDFs driven by node
graphs (issue 14's shader programs: Noise into Base Color and a ColorRamp into Roughness,
Mapping + Checker into Base Color); a Mix Shader of Diffuse and Glossy whose Factor is
Layer Weight's Facing and a Glossy BSDF with a strong Bump (per-hit closure weights and
normals, ``per_hit``).

The Cornell box: the demo's box (examples/cornell_box.py) without its spheres and with one
rough-metal sphere (Principled metallic 1, roughness 0.3) where the mirror sphere was, so
its reflection shows the red and green walls.

Cycles renders full global illumination (BOUNCES bounces of every kind, caustics on, no
clamping, the 1-pixel box filter of cycles_reference.configure_cycles), two seeds of
CYCLES_SAMPLES each, averaged; the standard error of the 8 x 8 block means comes from the
two seeds. Everything is cached in one file, tests/data/cycles_materials.npz (one image and
block sigma per scene, a fingerprint of this module's scene code). Re-render (all scenes,
or the ones named; a few minutes on 2 cores) with:

    .venv/bin/python tests/blender/cycles_material_reference.py [principled_default ...]
"""

from __future__ import annotations

import pathlib
import sys

import numpy as np

import bpy

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes  # noqa: E402

RESOLUTION = (64, 64)
CORNELL_RESOLUTION = (64, 48)
CYCLES_SAMPLES = 1024
"""Samples per pixel and seed (two seeds are averaged)."""
BOUNCES = 12
WORLD = 0.25
"""Uniform world radiance, W/(m^2 sr), grey."""
LIGHT_POWER = 60.0
PATH = ref.DATA / "cycles_materials.npz"


# Materials ------------------------------------------------------------------------------

def node_material(name, idname, **inputs):
    """A material: one shader node of type ``idname`` with ``inputs`` (socket name ->
    value; a node property when the name is lower case) -> Material Output."""
    mat = bpy.data.materials.new(name)
    nodes = scenes.ensure_node_tree(mat).nodes
    nodes.clear()
    node = nodes.new(idname)
    for key, value in inputs.items():
        if key.islower():
            setattr(node, key, value)
        else:
            node.inputs[key].default_value = value
    out = nodes.new('ShaderNodeOutputMaterial')
    mat.node_tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat


def principled(name, **inputs):
    return node_material(name, 'ShaderNodeBsdfPrincipled', **inputs)


def combined(name, how, fac=0.3):
    """Mix Shader (``how`` "MIX", factor ``fac``) or Add Shader ("ADD") of a red Diffuse
    BSDF and a white Glossy BSDF of roughness 0.2 (Add: Diffuse 0.5 grey + Sheen)."""
    mat = bpy.data.materials.new(name)
    tree = scenes.ensure_node_tree(mat)
    nodes, links = tree.nodes, tree.links
    nodes.clear()
    first = nodes.new('ShaderNodeBsdfDiffuse')
    if how == "MIX":
        first.inputs["Color"].default_value = RED
        second = nodes.new('ShaderNodeBsdfGlossy')
        second.inputs["Color"].default_value = (0.9, 0.9, 0.9, 1.0)
        second.inputs["Roughness"].default_value = 0.2
        node = nodes.new('ShaderNodeMixShader')
        node.inputs[0].default_value = fac
        inputs = node.inputs[1], node.inputs[2]
    else:
        first.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
        second = nodes.new('ShaderNodeBsdfSheen')
        second.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
        node = nodes.new('ShaderNodeAddShader')
        inputs = node.inputs[0], node.inputs[1]
    links.new(first.outputs[0], inputs[0])
    links.new(second.outputs[0], inputs[1])
    links.new(node.outputs[0], nodes.new('ShaderNodeOutputMaterial').inputs["Surface"])
    return mat


def textured(name, which):
    """Principled BSDFs whose inputs are node graphs (issue 14, shader programs at every
    hit): "noise" a Noise Texture (Generated coordinates, scale 5, detail 2) colour into
    Base Color and its factor through a ColorRamp (0.15 grey at 0.3, 0.7 at 0.7) into
    Roughness; "checker" a Checker (RED / 0.9 grey, scale 4) of the Generated coordinates
    through a Mapping (30 degrees about Z, scale 2 x 1 x 1) into Base Color."""
    import math

    mat = principled(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.bl_idname == 'ShaderNodeBsdfPrincipled')
    if which == "noise":
        noise = nodes.new('ShaderNodeTexNoise')
        noise.inputs["Scale"].default_value = 5.0
        noise.inputs["Detail"].default_value = 2.0
        ramp = nodes.new('ShaderNodeValToRGB')
        stops = ramp.color_ramp.elements
        stops[0].position, stops[0].color = 0.3, (0.15, 0.15, 0.15, 1.0)
        stops[1].position, stops[1].color = 0.7, (0.7, 0.7, 0.7, 1.0)
        links.new(noise.outputs[1], bsdf.inputs["Base Color"])  # Color (by index: 4.2 / 5.x)
        links.new(noise.outputs[0], ramp.inputs[0])             # Fac / Factor
        links.new(ramp.outputs[0], bsdf.inputs["Roughness"])
    else:
        coords = nodes.new('ShaderNodeTexCoord')
        mapping = nodes.new('ShaderNodeMapping')
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(30.0))
        mapping.inputs["Scale"].default_value = (2.0, 1.0, 1.0)
        checker = nodes.new('ShaderNodeTexChecker')
        checker.inputs["Color1"].default_value = RED
        checker.inputs["Color2"].default_value = (0.9, 0.9, 0.9, 1.0)
        checker.inputs["Scale"].default_value = 4.0
        links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], checker.inputs["Vector"])
        links.new(checker.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def per_hit(name, which):
    """Node graphs that change a closure per hit (issue 14): "mix_facing" a Mix Shader of
    a red Diffuse and a white Glossy (roughness 0.2) whose Factor is Layer Weight's Facing
    (blend 0.5), the artists' rim pattern; "bump_glossy" a white Glossy (roughness 0.15)
    whose Normal is a Bump (distance 0.2) of a Noise Texture (Object coordinates, scale 6,
    detail 1): strong enough that some mirror directions would leave into the sphere."""
    mat = bpy.data.materials.new(name)
    tree = scenes.ensure_node_tree(mat)
    nodes, links = tree.nodes, tree.links
    nodes.clear()
    glossy = nodes.new('ShaderNodeBsdfGlossy')
    glossy.inputs["Color"].default_value = (0.9, 0.9, 0.9, 1.0)
    out = nodes.new('ShaderNodeOutputMaterial')
    if which == "mix_facing":
        glossy.inputs["Roughness"].default_value = 0.2
        diffuse = nodes.new('ShaderNodeBsdfDiffuse')
        diffuse.inputs["Color"].default_value = RED
        weight = nodes.new('ShaderNodeLayerWeight')
        weight.inputs["Blend"].default_value = 0.5
        mix = nodes.new('ShaderNodeMixShader')
        links.new(weight.outputs["Facing"], mix.inputs[0])
        links.new(diffuse.outputs[0], mix.inputs[1])
        links.new(glossy.outputs[0], mix.inputs[2])
        links.new(mix.outputs[0], out.inputs["Surface"])
    else:
        glossy.inputs["Roughness"].default_value = 0.15
        coords = nodes.new('ShaderNodeTexCoord')
        noise = nodes.new('ShaderNodeTexNoise')
        noise.inputs["Scale"].default_value = 6.0
        noise.inputs["Detail"].default_value = 1.0
        bump = nodes.new('ShaderNodeBump')
        bump.inputs["Distance"].default_value = 0.2
        links.new(coords.outputs["Object"], noise.inputs["Vector"])
        links.new(noise.outputs[0], bump.inputs["Height"])
        links.new(bump.outputs["Normal"], glossy.inputs["Normal"])
        links.new(glossy.outputs[0], out.inputs["Surface"])
    return mat


GOLD = (1.0, 0.71, 0.29, 1.0)
RED = (0.8, 0.15, 0.1, 1.0)

MATERIALS = {
    "diffuse": lambda: node_material("Diffuse", 'ShaderNodeBsdfDiffuse', Color=RED),
    "diffuse_rough": lambda: node_material("OrenNayar", 'ShaderNodeBsdfDiffuse', Color=RED,
                                           Roughness=0.8),
    "glossy": lambda: node_material("Glossy", 'ShaderNodeBsdfGlossy',
                                    Color=(0.9, 0.9, 0.9, 1.0), Roughness=0.3),
    "metallic": lambda: node_material("Metallic", 'ShaderNodeBsdfMetallic', Roughness=0.3,
                                      **{"Base Color": GOLD}),
    "glass": lambda: node_material("RoughGlassNode", 'ShaderNodeBsdfGlass', Roughness=0.3,
                                   IOR=1.5),
    "refraction": lambda: node_material("Refraction", 'ShaderNodeBsdfRefraction',
                                        Roughness=0.2, IOR=1.45),
    "translucent": lambda: node_material("Translucent", 'ShaderNodeBsdfTranslucent',
                                         Color=(0.8, 0.8, 0.8, 1.0)),
    "sheen": lambda: node_material("SheenNode", 'ShaderNodeBsdfSheen',
                                   Color=(0.8, 0.8, 0.8, 1.0), Roughness=0.5),
    "principled_default": lambda: principled("PrincipledDefault"),
    **{f"principled_r{int(r * 100):02d}_m{m}": (
        lambda r=r, m=m: principled(f"Principled r{r} m{m}", Roughness=r, Metallic=float(m),
                                    **{"Base Color": GOLD if m else RED}))
       for r in (0.0, 0.25, 0.6) for m in (0, 1)},
    "coat": lambda: principled("Coat", Roughness=0.5, **{
        "Base Color": RED, "Coat Weight": 1.0, "Coat Roughness": 0.05,
        "Coat Tint": (0.9, 0.95, 1.0, 1.0)}),
    "principled_sheen": lambda: principled("PrincipledSheen", Roughness=0.6, **{
        "Base Color": (0.1, 0.1, 0.5, 1.0), "Sheen Weight": 1.0, "Sheen Roughness": 0.3}),
    "rough_glass": lambda: principled("RoughGlass", Roughness=0.3, IOR=1.5, **{
        "Base Color": (1.0, 1.0, 1.0, 1.0), "Transmission Weight": 1.0}),
    "thin_wall": lambda: principled("ThinWall", Roughness=0.0, IOR=1.5, **{
        "Base Color": (1.0, 1.0, 1.0, 1.0), "Transmission Weight": 1.0, "Thin Wall": True}),
    "principled_aniso": lambda: principled("PrincipledAniso", Roughness=0.3, Metallic=1.0, **{
        "Base Color": GOLD, "Anisotropic": 0.8}),
    "mix_diffuse_glossy": lambda: combined("MixDiffuseGlossy", "MIX"),
    "add_diffuse_sheen": lambda: combined("AddDiffuseSheen", "ADD"),
    "noise_roughness": lambda: textured("NoiseRoughness", "noise"),
    "mapping_checker": lambda: textured("MappingChecker", "checker"),
    "mix_layer_weight": lambda: per_hit("MixLayerWeight", "mix_facing"),
    "bump_glossy": lambda: per_hit("BumpGlossy", "bump_glossy"),
}
"""Scene name -> a function making the sphere's material (in a fresh scene)."""


def needs(name) -> tuple[int, int]:
    """The oldest Blender (major, minor) that has the nodes / inputs of ``name``."""
    return {"metallic": (4, 3), "thin_wall": (5, 2)}.get(name, (4, 2))


# Scenes ---------------------------------------------------------------------------------

def sphere_scene(name, resolution=RESOLUTION):
    """The sphere of material ``name`` in the uniform world with the area light (module doc)."""
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    world = bpy.data.worlds.new("Uniform")
    scene.world = world
    background = scenes.ensure_node_tree(world).nodes["Background"]
    background.inputs["Color"].default_value = (WORLD, WORLD, WORLD, 1.0)
    background.inputs["Strength"].default_value = 1.0
    world.cycles_visibility.camera = False
    scenes.add_sphere(radius=0.5, material=MATERIALS[name](), segments=64, name="Ball")
    location = (1.6, -1.4, 1.8)
    scenes.add_light('AREA', location=location, power=LIGHT_POWER, size=0.5,
                     rotation=ref._aim(location, (0.0, 0.0, 0.0)), name="Key")
    scenes.add_camera(location=(0.0, -3.0, 0.4), look_at=(0.0, 0.0, 0.0), lens=80.0)
    return scene


def cornell_rough_metal(resolution=CORNELL_RESOLUTION):
    """The demo's Cornell box, its spheres replaced by one rough-metal sphere (Principled
    metallic 1, roughness 0.3, base 0.9 grey) at the mirror sphere's place."""
    from examples import cornell_box as box
    from tests.blender import cycles_gi_reference as gi

    scene = gi.cornell_without_spheres(resolution=resolution)
    metal = principled("RoughMetal", Metallic=1.0, Roughness=0.3,
                       **{"Base Color": (0.9, 0.9, 0.9, 1.0)})
    scenes.add_sphere(radius=box.SPHERE_RADIUS, location=box.MIRROR_CENTRE, material=metal,
                      segments=64, name="RoughMetalSphere")
    return scene


SCENES = {name: (lambda name=name: sphere_scene(name)) for name in MATERIALS}
SCENES["cornell_rough_metal"] = cornell_rough_metal


def configure_cycles_full(scene, samples, seed=0):
    """Cycles with full global illumination: BOUNCES of each kind, caustics on, the rest
    as cycles_reference.configure_cycles (CPU, box filter, no denoising, no clamping)."""
    ref.configure_cycles(scene, samples, seed, max_depth=BOUNCES)
    c = scene.cycles
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = BOUNCES
    c.caustics_reflective = True
    c.caustics_refractive = True
    return scene


def render_cycles(scene, samples, seed=0) -> np.ndarray:
    """(H, W, 3) float32 Combined radiance, row 0 at the top."""
    configure_cycles_full(scene, samples, seed)
    return scenes.render_passes(scene)["Combined"][..., :3].astype(np.float32)


def fingerprint(name) -> str:
    """Hash of the code behind scene ``name``'s reference; stale when it changes."""
    parts = [node_material, principled, configure_cycles_full, ref.configure_cycles,
             (CYCLES_SAMPLES, BOUNCES, WORLD, LIGHT_POWER, GOLD, RED)]
    if name == "cornell_rough_metal":
        parts += [ref.scene_fingerprint("demo"), cornell_rough_metal, CORNELL_RESOLUTION]
    else:
        # The material's own lambda: its line(s) of the MATERIALS table.
        parts += [name, sphere_scene, _material_source(name), RESOLUTION]
        if name.startswith(("mix_", "add_")):
            parts.append(combined)
        if name in ("noise_roughness", "mapping_checker"):
            parts.append(textured)
        if name in ("mix_layer_weight", "bump_glossy"):
            parts.append(per_hit)
    return ref.code_fingerprint(parts)


def _material_source(name) -> str:
    """The source line(s) defining ``MATERIALS[name]`` (the table entry)."""
    import inspect

    try:
        return inspect.getsource(MATERIALS[name])
    except (OSError, TypeError):
        return name


def load_reference(name) -> dict:
    """Scene ``name``'s cached Cycles render: image (H, W, 3) float32, block_sigma
    (h, w, 3). Raises AssertionError with the command to run when missing or stale."""
    regenerate = (f"re-render it with: .venv/bin/python tests/blender/"
                  f"cycles_material_reference.py {name}")
    assert PATH.exists(), f"missing Cycles reference {PATH.relative_to(ROOT)}; {regenerate}"
    with np.load(PATH) as data:
        assert f"{name}/image" in data, f"no scene {name} in {PATH.name}; {regenerate}"
        assert str(data[f"{name}/fingerprint"]) == fingerprint(name), \
            f"{PATH.name}[{name}] was made from other scene code; {regenerate}"
        return {"image": data[f"{name}/image"], "block_sigma": data[f"{name}/block_sigma"]}


def main(names=None):
    """Render the named scenes (default all) with Cycles and update the cached file."""
    import time

    stored = dict(np.load(PATH)) if PATH.exists() else {}
    version = tuple(bpy.app.version[:2])
    for name in names or SCENES:
        if version < needs(name):
            print(f"{name}: needs Blender {needs(name)}, skipped")
            continue
        started = time.perf_counter()
        a = render_cycles(SCENES[name](), CYCLES_SAMPLES, seed=1)
        b = render_cycles(SCENES[name](), CYCLES_SAMPLES, seed=2)
        stored[f"{name}/image"] = ((a + b) / 2).astype(np.float32)
        stored[f"{name}/block_sigma"] = ref.block_sigma(a, b).astype(np.float32)
        stored[f"{name}/fingerprint"] = np.str_(fingerprint(name))
        stored["blender"] = np.str_(bpy.app.version_string)
        np.savez_compressed(PATH, **stored)
        mean = ((a + b) / 2).reshape(-1, 3).mean(axis=0)
        rel = ref.block_sigma(a, b) / np.maximum(ref.block_means((a + b) / 2), 1e-6)
        print(f"{name}: 2 x {CYCLES_SAMPLES} spp in {time.perf_counter() - started:.1f} s, "
              f"mean {np.round(mean, 4)}, median block sigma {100 * np.median(rel):.2f} %",
              flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
