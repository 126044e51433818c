"""Cycles as the reference renderer: the same bpy scene rendered by Cycles, restricted to
what Photon Map computes so far, and by Photon Map; the scenes; the comparison figures.

What Photon Map renders now is emission + direct light (shadow rays) at the first diffuse
hit + perfect specular chains (mirror, glass) up to ``max_specular_depth``. Cycles computes
exactly that with:
- diffuse_bounces = 0 (no indirect diffuse: a diffuse hit ends the path after its light
  sample), glossy and transmission bounces = max_bounces = the specular depth;
- caustics off (no glossy/refractive paths after a diffuse bounce; moot with 0 diffuse
  bounces but explicit), no glossy blur, no clamping (a mirror showing a light is an
  "indirect" sample Cycles would otherwise clamp at 10);
- a 1-pixel box filter (uniform jitter inside the pixel, as Photon Map samples), no
  denoising, no adaptive sampling, the Standard view transform (EXRs are linear anyway).

Run as a script to re-render the cached Cycles references in tests/data/ (all scenes,
or the ones named; about two minutes on 2 cores):

    .venv/bin/python tests/blender/cycles_reference.py [demo four_lights point ...]
"""

from __future__ import annotations

import hashlib
import inspect
import math
import pathlib
import sys

import numpy as np

import bpy

ROOT = pathlib.Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tests.blender import scenes  # noqa: E402

DATA = ROOT / "tests" / "data"
MAX_SPECULAR_DEPTH = 8
RESOLUTION = (64, 48)
CYCLES_SAMPLES = 1024
"""Cycles samples per pixel and seed of the cached references (two seeds are averaged)."""


def configure_cycles(scene, samples, seed=0, max_depth=MAX_SPECULAR_DEPTH):
    """Cycles on the CPU, restricted to emission + direct + specular chains (module doc)."""
    scene.render.engine = 'CYCLES'
    c = scene.cycles
    c.device = 'CPU'
    c.samples = samples
    c.seed = seed
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.max_bounces = max_depth
    c.diffuse_bounces = 0
    c.glossy_bounces = max_depth
    c.transmission_bounces = max_depth
    c.volume_bounces = 0
    c.transparent_max_bounces = max_depth
    c.caustics_reflective = False
    c.caustics_refractive = False
    c.blur_glossy = 0.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.pixel_filter_type = 'BOX'
    c.filter_width = 1.0
    scene.view_settings.view_transform = 'Standard'
    return scene


def render_cycles(scene, samples, seed=0) -> np.ndarray:
    """(H, W, 3) float32 Combined radiance, row 0 at the top."""
    configure_cycles(scene, samples, seed)
    return scenes.render_passes(scene)["Combined"][..., :3].astype(np.float32)


def render_photon_map(scene, samples, seed=0, max_depth=MAX_SPECULAR_DEPTH) -> dict:
    """All passes of a Photon Map render through the engine, (H, W, C) float32 each,
    restricted like Cycles above: no photon terms (caustics, indirect diffuse)."""
    scenes.use_photon_map(scene, samples=samples, seed=seed, max_specular_depth=max_depth,
                          caustics=False, indirect_mode='off')
    return scenes.render_passes(scene)


_PAIRS: dict = {}


def photon_map_pair(name, samples, **scene_args):
    """Photon Map's Combined image of scene ``name`` and the standard error of its block
    means: two renders of samples / 2 each (seeds 1 and 2), averaged. Memoised per
    process, so test modules share renders.

    Returns (image (H, W, 3) float32, block_sigma (h, w, 3) float64, passes of seed 1).
    """
    key = (name, samples, tuple(sorted(scene_args.items())))
    if key not in _PAIRS:
        runs = [render_photon_map(SCENES[name](**scene_args), samples // 2, seed=seed)
                for seed in (1, 2)]
        a, b = (r["Combined"][..., :3].astype(np.float64) for r in runs)
        _PAIRS[key] = (((a + b) / 2).astype(np.float32), block_sigma(a, b), runs[0])
    return _PAIRS[key]


# Scenes -------------------------------------------------------------------------------

def demo_scene(scale=1.0, offset=(0.0, 0.0, 0.0), resolution=RESOLUTION):
    """Jensen's Cornell box from examples/cornell_box.py, in a fresh scene."""
    from examples.cornell_box import build_cornell_box

    scenes.reset()
    return build_cornell_box(scale=scale, offset=offset, resolution=resolution)


LIGHT_KINDS = ("POINT", "SPOT", "SUN", "AREA")


def _aim(location, target):
    """Euler rotation pointing a light's -Z from ``location`` at ``target``."""
    from mathutils import Vector

    return (Vector(target) - Vector(location)).to_track_quat('-Z', 'Y').to_euler()


def four_lights_scene(resolution=RESOLUTION, only=None):
    """A white floor and a green-grey box lit by a point, a spot, a sun and an area light.

    only: one of LIGHT_KINDS to keep a single light (the others are not created).
    Every light has a size (soft shadows) and a colour, none is seen by the camera
    (Blender 5's default), and their contributions are of similar strength.
    """
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    scenes.add_plane(size=8.0, material=scenes.diffuse_material("Floor", (0.8, 0.8, 0.8)))
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.2, 0.3, 0.4))
    cube = bpy.context.active_object
    cube.rotation_euler = (0.0, 0.0, 0.5)
    cube.data.materials.append(scenes.diffuse_material("Box", (0.5, 0.6, 0.4)))
    lights = {
        "POINT": dict(location=(-1.6, -0.4, 1.4), power=60.0, color=(1.0, 0.85, 0.7),
                      shadow_soft_size=0.15),
        "SPOT": dict(location=(1.8, 1.0, 2.6), power=400.0, color=(0.7, 0.85, 1.0),
                     rotation=_aim((1.8, 1.0, 2.6), (0.6, 0.0, 0.0)),
                     spot_size=math.radians(55.0), spot_blend=0.3, shadow_soft_size=0.05),
        "SUN": dict(power=0.6, color=(1.0, 1.0, 0.9), rotation=(0.7, 0.2, 0.4),
                    angle=math.radians(8.0)),
        "AREA": dict(location=(-0.3, 1.8, 1.3), power=90.0, color=(1.0, 0.75, 0.85),
                     rotation=(-0.6, 0.0, 0.0), shape='RECTANGLE', size=1.0, size_y=0.4),
    }
    for kind, attrs in lights.items():
        if only in (None, kind):
            scenes.add_light(kind, name=kind.title(), **attrs)
    scenes.add_camera(location=(0.0, -4.2, 2.6), look_at=(0.0, 0.4, 0.0), lens=30.0)
    return scene


def visible_lights_scene(resolution=RESOLUTION):
    """Every kind of light seen by the camera and in a mirror sphere on a white floor.

    Sphere lights with and without Soft Falloff, a spot with a radius, a disk and an
    ellipse area light, all visible to camera rays; the sun (20 degrees wide) shows in
    the mirror only.
    """
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    scenes.add_plane(size=8.0, material=scenes.diffuse_material("Floor", (0.8, 0.8, 0.8)))
    mirror = bpy.data.materials.new("Mirror")
    nodes, links = mirror.node_tree.nodes, mirror.node_tree.links
    nodes.clear()
    glossy = nodes.new('ShaderNodeBsdfGlossy')
    glossy.inputs["Color"].default_value = (0.9, 0.9, 0.9, 1.0)
    glossy.inputs["Roughness"].default_value = 0.0
    links.new(glossy.outputs[0], nodes.new('ShaderNodeOutputMaterial').inputs["Surface"])
    scenes.add_sphere(radius=0.5, location=(0.0, 0.5, 0.5), material=mirror, segments=64)
    lights = [
        scenes.add_light('POINT', location=(-1.2, 0.0, 1.0), power=40.0, shadow_soft_size=0.15,
                         name="Sphere"),
        scenes.add_light('POINT', location=(-0.4, -0.5, 1.3), power=40.0, shadow_soft_size=0.1,
                         use_soft_falloff=False, name="HardSphere"),
        scenes.add_light('SPOT', location=(1.2, 0.0, 1.2), power=200.0, shadow_soft_size=0.1,
                         rotation=(0.3, 0.5, 0.0), name="Spot"),
        scenes.add_light('AREA', location=(0.4, -0.8, 1.5), power=30.0, shape='DISK', size=0.4,
                         rotation=(-0.5, 0.0, 0.0), name="Disk"),
        scenes.add_light('AREA', location=(-0.8, 1.5, 1.2), power=30.0, shape='ELLIPSE', size=0.6,
                         size_y=0.2, rotation=(-1.0, 0.0, 0.3), name="Ellipse"),
        scenes.add_light('SUN', power=0.5, rotation=(1.2, 0.0, 0.5), angle=math.radians(20.0),
                         name="Sun"),
    ]
    for light in lights:
        light.visible_camera = True
    scenes.add_camera(location=(0.0, -4.0, 2.0), look_at=(0.0, 0.5, 0.6), lens=28.0)
    return scene


SCENES = {"demo": demo_scene, "four_lights": four_lights_scene,
          "visible_lights": visible_lights_scene}
SCENES.update({kind.lower(): (lambda kind=kind, **kw: four_lights_scene(only=kind, **kw))
               for kind in LIGHT_KINDS})


# Comparison ---------------------------------------------------------------------------

def block_means(image, block=8) -> np.ndarray:
    """(H // block, W // block, 3) float64 means of block x block pixel squares."""
    h, w = image.shape[0] // block * block, image.shape[1] // block * block
    b = image[:h, :w].astype(np.float64).reshape(h // block, block, w // block, block, -1)
    return b.mean(axis=(1, 3))


def block_sigma(image_a, image_b, block=8) -> np.ndarray:
    """Standard error (h, w, 3) of the block means of (a + b) / 2, from two renders of
    the same scene with different seeds (each pixel's (a - b)^2 / 4 estimates the
    variance of its mean; pixels are independent)."""
    var = (image_a.astype(np.float64) - image_b) ** 2 / 4.0
    return np.sqrt(block_means(var, block) / block**2)


def relative_block_sigma(reference: dict, block=8) -> np.ndarray:
    """A cached reference's noise: its block_sigma (h, w, 3) over its block means, inf or
    NaN where a block is black (such blocks are not counted by ``compare``)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return reference["block_sigma"] / block_means(reference["image"], block)


def compare(image, reference, sigma=None, block=8, floor=0.02) -> dict:
    """Figures of ``image`` against ``reference`` (both (H, W, 3) linear radiance).

    sigma: (h, w, 3) standard error of the difference of block means (the two renders'
        noise combined); None counts as 0.
    channel: (3,) relative difference of the per-channel means.
    blocks: (h, w, 3) relative differences of block means, NaN where the reference block
        is darker than ``floor`` x the reference's mean (relative error means nothing there).
    excess: (h, w, 3) |difference| / (5 % of the reference + 3 sigma), NaN as above; a
        block passes when it is <= 1.
    """
    mean_img = image.reshape(-1, 3).mean(axis=0).astype(np.float64)
    mean_ref = reference.reshape(-1, 3).mean(axis=0).astype(np.float64)
    bi, br = block_means(image, block), block_means(reference, block)
    counted = br > floor * mean_ref
    safe = np.where(counted, br, 1.0)
    sigma = np.zeros_like(br) if sigma is None else sigma
    rel = np.where(counted, (bi - br) / safe, np.nan)
    excess = np.where(counted, np.abs(bi - br) / (0.05 * safe + 3.0 * sigma), np.nan)
    return {"channel": mean_img / mean_ref - 1.0, "blocks": rel, "excess": excess,
            "worst_block": float(np.nanmax(np.abs(rel))), "mean": mean_ref,
            "noisy_blocks": float(np.nanmean(np.where(counted, 3.0 * sigma > 0.05 * safe, np.nan)))}


def code_fingerprint(parts) -> str:
    """The stamp of a cached reference: the first 16 hex digits of the sha256 of ``parts``
    joined by newlines, where a function or class stands for its source, a str for itself
    and anything else for its repr. The code that builds a scene is part of its stamp, so a
    cache made from other code is found stale (``load_cached``)."""
    text = "\n".join(
        p if isinstance(p, str)
        else inspect.getsource(p) if inspect.isroutine(p) or inspect.isclass(p) else repr(p)
        for p in parts)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def cornell_box_sources() -> list[str]:
    """The code and constants of examples/cornell_box.py that build the demo scene (not its
    command line or render settings): what a demo reference's fingerprint covers."""
    from examples import cornell_box

    return [inspect.getsource(cornell_box.build_cornell_box),
            inspect.getsource(cornell_box._material), inspect.getsource(cornell_box._sphere),
            repr({k: getattr(cornell_box, k) for k in
                  ("WHITE", "RED", "GREEN", "MIRROR", "LIGHT_SIZE", "LIGHT_POWER",
                   "SPHERE_RADIUS", "MIRROR_CENTRE", "GLASS_CENTRE", "CAMERA_LOCATION")})]


def scene_fingerprint(name) -> str:
    """Hash of the code that builds scene ``name`` and sets Cycles up: a cached reference
    made from other code is stale."""
    if name == "demo":
        parts = cornell_box_sources()
    elif name == "visible_lights":
        parts = [visible_lights_scene]
    else:
        parts = [name, four_lights_scene, _aim]
    return code_fingerprint(parts + [configure_cycles, (RESOLUTION, MAX_SPECULAR_DEPTH)])


def reference_path(name) -> pathlib.Path:
    return DATA / f"cycles_{name}_{RESOLUTION[0]}x{RESOLUTION[1]}.npz"


def load_reference(name) -> dict:
    """The cached Cycles render of scene ``name``: image (H, W, 3), block_sigma, samples.

    Raises AssertionError with the command to run when it is missing or stale.
    """
    return load_cached(reference_path(name), scene_fingerprint(name), "cycles_reference.py")


def load_cached(path: pathlib.Path, fingerprint: str, script: str) -> dict:
    """The arrays of a cached reference ``path`` made by tests/blender/``script``; raises
    AssertionError with the command that re-renders it when it is missing or was made from
    other code (its stored fingerprint is not ``fingerprint``)."""
    regenerate = f"re-render it with: .venv/bin/python tests/blender/{script}"
    assert path.exists(), f"missing Cycles reference {path.relative_to(ROOT)}; {regenerate}"
    data = dict(np.load(path))
    assert str(data["fingerprint"]) == fingerprint, \
        f"{path.relative_to(ROOT)} was made from other scene code; {regenerate}"
    return data


def main(names=None):
    """Re-render the cached Cycles references: two seeds of CYCLES_SAMPLES each per scene."""
    import time

    DATA.mkdir(parents=True, exist_ok=True)
    for name in names or SCENES:
        build = SCENES[name]
        started = time.perf_counter()
        a = render_cycles(build(), CYCLES_SAMPLES, seed=1)
        b = render_cycles(build(), CYCLES_SAMPLES, seed=2)
        np.savez_compressed(
            reference_path(name), image=((a + b) / 2).astype(np.float32),
            block_sigma=block_sigma(a, b).astype(np.float32),
            samples=np.int64(2 * CYCLES_SAMPLES), fingerprint=np.str_(scene_fingerprint(name)),
            blender=np.str_(bpy.app.version_string))
        print(f"{reference_path(name).relative_to(ROOT)}: 2 x {CYCLES_SAMPLES} spp in "
              f"{time.perf_counter() - started:.1f} s, mean {((a + b) / 2).reshape(-1, 3).mean(axis=0)}")


if __name__ == "__main__":
    main(sys.argv[1:])
