"""Cycles as the reference for the World's fog (issue 16): two scenes, 48 x 36.

- ``fog_spot``: a grey diffuse floor (4 m, albedo 0.6) in World fog (Principled Volume:
  Color 0.7, Density 0.25, Anisotropy 0.3, Absorption Color black: sigma_s = 0.175,
  sigma_a = 0.075 per metre, albedo 0.7), lit by a spot light 2 m above the floor pointing
  down (200 W, 50 degrees, blend 0.2, radius 0.1 m: Cycles finds paths through the glass
  only to a light with a size); the camera sees the lit cone and the floor.
- ``fog_caustic``: the same, with a glass sphere (IOR 1.5, radius 0.25 m) 1.2 m above the
  floor under the spot: the volumetric caustic (the focused cone in the fog below it).
- ``fog_spot_1m``, ``fog_caustic_1m``: fog_spot and fog_caustic with the spot light's radius
  1 m (WIDE_LIGHT), where Cycles converges on the caustic (WIDE_RUNS: 8 seeds of 1024
  samples); benchmarks/tradeoff.py's fog scenes.
- ``fog_box_caustic_1m``: the glass sphere in a fog box (the same fog inside a closed mesh,
  4.2 x 4.2 m, 1.95 m high) under the 1 m spot light raised to 3 m (450 W), so that no fog
  lies inside the light's sphere: there Cycles with the light's MIS on loses light
  scattered inside it (docs/volumes.md, "Cycles' loss inside a wide light"), here its
  MIS on and off agree.

Cycles renders full transport with BOUNCES bounces of every kind (volume bounces
included, caustics on, no clamping, the 1-pixel box filter of
cycles_reference.configure_cycles), CYCLES_SEEDS seeds of CYCLES_SAMPLES each, averaged; the
standard error of the 8 x 8 block means comes from the odd and even seeds' halves. Cached in
tests/data/cycles_media_<name>_48x36.npz with a fingerprint of this module's scene code.
Re-render (both scenes, or the ones named) with:

    .venv/bin/python tests/blender/cycles_media_reference.py [fog_spot fog_caustic ...]
"""

from __future__ import annotations

import inspect
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

RESOLUTION = (48, 36)
CYCLES_SAMPLES = 2048
"""Samples per pixel and seed."""
CYCLES_SEEDS = 32
"""Renders averaged (seeds 1..CYCLES_SEEDS). Light reaching the fog through the glass sphere
is found only by phase-sampled rays that pass the sphere and hit the 0.1 m light, so the
per-render mean is heavy-tailed: 2 x 2048 spp read 0.0110, 64 x 512 spp 0.0123 +- 0.0002.
A larger light makes Cycles converge (an index-matched sphere, IOR 1, against no sphere:
-13 % at 0.1 m, -9 % at 0.4 m, -1.2 % at 1 m): the ``_1m`` scenes (WIDE_LIGHT). There
Photon Map's fog_spot is within 0.2 % of Cycles (+28 % while its photons left a
soft-falloff light as from a sphere): benchmarks/media_light_radius.py, docs/volumes.md."""
BOUNCES = 8
FOG = {"Color": (0.7, 0.7, 0.7, 1.0), "Density": 0.25, "Anisotropy": 0.3}


def fog_world(scene):
    """The World: black background, the Principled Volume FOG on its Volume output."""
    world = bpy.data.worlds.new("Fog")
    scene.world = world
    tree = scenes.ensure_node_tree(world)
    for node in list(tree.nodes):
        if node.type != 'OUTPUT_WORLD':
            tree.nodes.remove(node)
    output = next(n for n in tree.nodes if n.type == 'OUTPUT_WORLD')
    volume = tree.nodes.new('ShaderNodeVolumePrincipled')
    for key, value in FOG.items():
        volume.inputs[key].default_value = value
    tree.links.new(volume.outputs[0], output.inputs["Volume"])
    return world


def fog_spot_scene(resolution=RESOLUTION, sphere=False):
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    scenes.add_plane(size=4.0, material=scenes.diffuse_material("Floor", (0.6, 0.6, 0.6)))
    scenes.add_light('SPOT', location=(0.0, 0.0, 2.0), power=200.0, spot_size=math.radians(50.0),
                     spot_blend=0.2, shadow_soft_size=0.1, name="Spot")
    if sphere:
        glass = bpy.data.materials.new("Glass")
        tree = scenes.ensure_node_tree(glass)
        bsdf = tree.nodes.new('ShaderNodeBsdfGlass')
        bsdf.inputs["Roughness"].default_value = 0.0
        bsdf.inputs["IOR"].default_value = 1.5
        out = next(n for n in tree.nodes if n.type == 'OUTPUT_MATERIAL')
        tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
        scenes.add_sphere(radius=0.25, location=(0.0, 0.0, 1.2), material=glass, name="Ball",
                          segments=48)
    scenes.add_camera(location=(0.0, -4.5, 1.2), look_at=(0.0, 0.0, 0.8), lens=30.0)
    fog_world(scene)
    return scene


WIDE_LIGHT = 1.0
"""The spot light's radius (metres) in the ``_1m`` scenes. With it Cycles converges on the
volumetric caustic (an index-matched sphere changes its mean by -1.2 %, 2 x 512 spp)."""
WIDE_RUNS = (1024, 8)
"""(samples, seeds) of the ``_1m`` references: the caustic is soft there, 2 x 512 spp
already had the image mean to ~1 %."""


def wide_light(build):
    """``build`` with the spot light's radius set to WIDE_LIGHT."""
    def make():
        scene = build()
        bpy.data.lights["Spot"].shadow_soft_size = WIDE_LIGHT
        return scene
    return make


def fog_box_scene(resolution=RESOLUTION):
    """``fog_box_caustic_1m`` (module doc): no World, the fog a Principled Volume on a box
    whose floor lies under the floor plane, the light's 1 m sphere 5 cm above its top."""
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    scenes.add_plane(size=4.0, material=scenes.diffuse_material("Floor", (0.6, 0.6, 0.6)))
    scenes.add_light('SPOT', location=(0.0, 0.0, 3.0), power=450.0, spot_size=math.radians(50.0),
                     spot_blend=0.2, shadow_soft_size=WIDE_LIGHT, name="Spot")
    fog = bpy.data.materials.new("Fog")
    tree = scenes.ensure_node_tree(fog)
    for node in list(tree.nodes):
        if node.type != 'OUTPUT_MATERIAL':
            tree.nodes.remove(node)
    out = next(n for n in tree.nodes if n.type == 'OUTPUT_MATERIAL')
    volume = tree.nodes.new('ShaderNodeVolumePrincipled')
    for key, value in FOG.items():
        volume.inputs[key].default_value = value
    tree.links.new(volume.outputs[0], out.inputs["Volume"])
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.925))
    box = bpy.context.active_object
    box.name = "FogBox"
    box.scale = (4.2, 4.2, 1.95)
    box.data.materials.append(fog)
    # The glass and camera as fog_spot_scene's, written again: that function's source is
    # in its cached references' fingerprints.
    glass = bpy.data.materials.new("Glass")
    tree = scenes.ensure_node_tree(glass)
    bsdf = tree.nodes.new('ShaderNodeBsdfGlass')
    bsdf.inputs["Roughness"].default_value = 0.0
    bsdf.inputs["IOR"].default_value = 1.5
    out = next(n for n in tree.nodes if n.type == 'OUTPUT_MATERIAL')
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    scenes.add_sphere(radius=0.25, location=(0.0, 0.0, 1.2), material=glass, name="Ball",
                      segments=48)
    scenes.add_camera(location=(0.0, -4.5, 1.2), look_at=(0.0, 0.0, 0.8), lens=30.0)
    return scene


SCENES = {"fog_spot": lambda: fog_spot_scene(),
          "fog_caustic": lambda: fog_spot_scene(sphere=True),
          "fog_spot_1m": wide_light(lambda: fog_spot_scene()),
          "fog_caustic_1m": wide_light(lambda: fog_spot_scene(sphere=True)),
          "fog_box_caustic_1m": lambda: fog_box_scene()}


def configure_cycles_media(scene, samples, seed=0):
    """Cycles as in cycles_reference, with BOUNCES bounces of every kind and caustics on."""
    ref.configure_cycles(scene, samples, seed, max_depth=BOUNCES)
    c = scene.cycles
    c.max_bounces = c.diffuse_bounces = c.volume_bounces = BOUNCES
    c.caustics_reflective = c.caustics_refractive = True
    return scene


def fingerprint(name: str = "fog_spot") -> str:
    if name.startswith("fog_box"):
        return ref.code_fingerprint([fog_box_scene, configure_cycles_media,
                                     (RESOLUTION, BOUNCES, FOG, WIDE_LIGHT)])
    parts = [fog_world, fog_spot_scene, configure_cycles_media, (RESOLUTION, BOUNCES, FOG)]
    if name.endswith("_1m"):
        parts.append(inspect.getsource(wide_light) + repr(WIDE_LIGHT))
    return ref.code_fingerprint(parts)


PHOTON_MAP_SETTINGS = dict(samples=16, seed=1, global_photons=100_000, caustic_photons=100_000,
                           photon_max_bounces=BOUNCES, max_specular_depth=BOUNCES,
                           indirect_mode='preview', light_samples=2)
"""The Photon Map settings the media tests render with (tests/blender/test_cycles_media.py,
test_cycles_mesh_media.py)."""


def render_photon_map(scene, **overrides) -> dict:
    """Every pass of a Photon Map render of ``scene`` at PHOTON_MAP_SETTINGS, with
    ``overrides`` (settings of the same names) in their place."""
    scenes.use_photon_map(scene, **dict(PHOTON_MAP_SETTINGS, **overrides))
    return scenes.render_passes(scene)


def figures(name, passes, reference) -> dict:
    """``cycles_reference.compare`` of the Combined pass against the cached Cycles render
    ``reference`` (a ``load_reference`` dict), printed; the image must be finite and >= 0."""
    image = passes["Combined"][..., :3]
    assert np.all(np.isfinite(image)) and image.min() >= 0
    f = ref.compare(image, reference["image"])
    print(f"\n{name}: channel means PM/Cycles - 1 = {np.round(100 * f['channel'], 2)} %, "
          f"worst block {100 * f['worst_block']:.1f} %, median |block| "
          f"{100 * np.nanmedian(np.abs(f['blocks'])):.2f} %")
    return f


def save_reference(path, build, samples, seeds, stamp, extra_passes=()):
    """Render ``build()`` with Cycles (configure_cycles_media) at seeds 1..``seeds`` of
    ``samples`` each and cache the mean in ``path`` with its odd- and even-seed halves
    (image_a, image_b: their difference gives the noise), block_sigma and fingerprint
    ``stamp``; each of ``extra_passes`` (Cycles pass names, e.g. "Emission") is stored too,
    averaged over every seed, under its name in lower case."""
    import time

    started = time.perf_counter()
    runs, extras = [], {name: [] for name in extra_passes}
    for seed in range(1, seeds + 1):
        scene = configure_cycles_media(build(), samples, seed)
        passes = scenes.render_passes(scene)
        runs.append(passes["Combined"][..., :3].astype(np.float64))
        for name, stack in extras.items():
            stack.append(passes[name][..., :3].astype(np.float64))
    a = np.mean(runs[0::2], axis=0)
    b = np.mean(runs[1::2], axis=0)
    extra = {name.lower(): np.mean(stack, axis=0).astype(np.float32)
             for name, stack in extras.items()}
    np.savez_compressed(
        path, image=((a + b) / 2).astype(np.float32),
        image_a=a.astype(np.float32), image_b=b.astype(np.float32),
        block_sigma=ref.block_sigma(a, b).astype(np.float32),
        samples=np.int64(seeds * samples), fingerprint=np.str_(stamp),
        bounces=np.int64(BOUNCES), blender=np.str_(bpy.app.version_string), **extra)
    print(f"{path.relative_to(ROOT)}: {seeds} x {samples} spp in "
          f"{time.perf_counter() - started:.1f} s, mean "
          f"{((a + b) / 2).reshape(-1, 3).mean(axis=0)}"
          + "".join(f", {k} {v.reshape(-1, 3).mean(axis=0)}" for k, v in extra.items()),
          flush=True)


class Cache:
    """The cached Cycles renders of one reference module (issue 16's media references):
    tests/data/<prefix>_<name>_<W>x<H>.npz for each of its ``scenes`` ({name: build}),
    stamped with ``fingerprint(name)``, re-rendered by tests/blender/<prefix>_reference.py
    with ``save_reference`` at ``runs`` (samples per seed, seeds), or ``runs(name)`` when
    it is a function, storing ``extra_passes`` too."""

    def __init__(self, prefix, scenes, fingerprint, runs, resolution=RESOLUTION,
                 extra_passes=()):
        self.prefix, self.scenes, self.fingerprint = prefix, scenes, fingerprint
        self.runs = runs if callable(runs) else (lambda name: runs)
        self.resolution, self.extra_passes = resolution, tuple(extra_passes)

    def path(self, name) -> pathlib.Path:
        width, height = self.resolution
        return ref.DATA / f"{self.prefix}_{name}_{width}x{height}.npz"

    def load(self, name) -> dict:
        """The cached Cycles render of ``name``: image (H, W, 3), its halves image_a and
        image_b (the odd and the even seeds), block_sigma, samples, fingerprint and the
        extra passes; AssertionError with the command that re-renders it when missing or
        stale."""
        return ref.load_cached(self.path(name), self.fingerprint(name),
                               f"{self.prefix}_reference.py {name}")

    def main(self, names=None):
        """Re-render the named scenes (default: all) and cache them."""
        for name in names or list(self.scenes):
            samples, seeds = self.runs(name)
            save_reference(self.path(name), self.scenes[name], samples, seeds,
                           self.fingerprint(name), self.extra_passes)


CACHE = Cache("cycles_media", SCENES, fingerprint,
              lambda name: WIDE_RUNS if name.endswith("_1m") else (CYCLES_SAMPLES, CYCLES_SEEDS))
reference_path, load_reference, main = CACHE.path, CACHE.load, CACHE.main


if __name__ == "__main__":
    main(sys.argv[1:] or None)
