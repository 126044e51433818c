"""Cycles as the reference for Photon Map's caustics pass: a glass sphere above a floor,
lit from the side by a small area light (so the caustic lands beside the sphere, where the
camera sees the floor directly), seen from straight above.

Cycles' caustic is the difference of two renders: caustics on (reflective and refractive)
minus caustics off, with one diffuse bounce (floor -> glass ... -> light). On the floor
pixels the camera sees directly, that difference is the L S+ D light that Photon Map's
caustics pass holds plus the L D S+ D light of the floor's own diffuse light sent back
through the sphere (the one diffuse bounce reaches it), which is in Photon Map's indirect
pass: 3 % of the difference for smooth glass, 7 % for the frosted sphere (measured
2026-12-06 with final gathering). Cycles converges on it here (a small scene, an area light
the sphere magnifies), with many samples.

Two references: the smooth sphere (``glass_sphere_scene``) and the frosted one
(``frosted_sphere_scene``: the same Glass BSDF at roughness ``FROSTED_ROUGHNESS``,
multiscatter GGX). Run as a script to re-render them (tests/data/cycles_caustic_48x48.npz,
about two minutes on 2 cores; cycles_caustic_frosted_48x48.npz, about 40 s):

    .venv/bin/python tests/blender/cycles_caustic_reference.py [smooth|frosted]
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

RESOLUTION = (48, 48)
CYCLES_SAMPLES = 16384
NAME = "caustic"
FROSTED_ROUGHNESS = 0.6
FROSTED_SAMPLES = 8192


def glass_sphere_scene(resolution=RESOLUTION):
    """A 6 m white floor, a glass sphere (r 0.3 m, IOR 1.5) 0.2 m above it, a 0.3 m area
    light 2 m high to the side aimed at the sphere, a camera 3 m above the caustic."""
    scene = scenes.reset()
    scenes.set_resolution(*resolution)
    scenes.add_plane(size=6.0, material=scenes.diffuse_material("Floor", (0.8, 0.8, 0.8)))
    glass = bpy.data.materials.new("Glass")
    nodes, links = glass.node_tree.nodes, glass.node_tree.links
    nodes.clear()
    bsdf = nodes.new('ShaderNodeBsdfGlass')
    bsdf.inputs["IOR"].default_value = 1.5
    bsdf.inputs["Roughness"].default_value = 0.0
    links.new(bsdf.outputs[0], nodes.new('ShaderNodeOutputMaterial').inputs["Surface"])
    scenes.add_sphere(radius=0.3, location=(0.0, 0.0, 0.5), material=glass, segments=64)
    scenes.add_light('AREA', location=(-1.5, 0.0, 2.0), power=300.0, size=0.3,
                     rotation=ref._aim((-1.5, 0.0, 2.0), (0.0, 0.0, 0.5)), name="Key")
    scenes.add_camera(location=(0.7, 0.0, 3.0), look_at=(0.7, 0.0, 0.0), lens=50.0)
    return scene


def frosted_sphere_scene(resolution=RESOLUTION):
    """``glass_sphere_scene`` with its Glass BSDF frosted: roughness FROSTED_ROUGHNESS,
    multiscatter GGX (the node's default distribution)."""
    scene = glass_sphere_scene(resolution)
    bsdf = bpy.data.materials["Glass"].node_tree.nodes["Glass BSDF"]
    bsdf.distribution = 'MULTI_GGX'
    bsdf.inputs["Roughness"].default_value = FROSTED_ROUGHNESS
    return scene


SCENES = {"smooth": glass_sphere_scene, "frosted": frosted_sphere_scene}
"""The references' scenes by name."""


def configure(scene, samples, seed, caustics):
    ref.configure_cycles(scene, samples, seed)
    c = scene.cycles
    c.caustics_refractive = caustics
    c.caustics_reflective = caustics
    c.diffuse_bounces = 1
    return scene


def render(samples, seed, caustics, kind="smooth") -> np.ndarray:
    scene = configure(SCENES[kind](), samples, seed, caustics)
    return scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)


def samples_of(kind: str) -> int:
    return CYCLES_SAMPLES if kind == "smooth" else FROSTED_SAMPLES


def fingerprint(kind: str = "smooth") -> str:
    if kind == "smooth":  # as it was before the frosted sphere, so its cache stays valid
        return ref.code_fingerprint([glass_sphere_scene, configure, ref.configure_cycles,
                                     ref._aim, (RESOLUTION, CYCLES_SAMPLES)])
    return ref.code_fingerprint([glass_sphere_scene, frosted_sphere_scene, configure,
                                 ref.configure_cycles, ref._aim,
                                 (RESOLUTION, FROSTED_SAMPLES, FROSTED_ROUGHNESS)])


def reference_path(kind: str = "smooth") -> pathlib.Path:
    name = NAME if kind == "smooth" else f"{NAME}_{kind}"
    return ref.DATA / f"cycles_{name}_{RESOLUTION[0]}x{RESOLUTION[1]}.npz"


def load_reference(kind: str = "smooth") -> dict:
    """caustic (H, W, 3): Cycles with caustics minus without; caustic_b: the same from a
    second pair of seeds (the difference of the two is Cycles' noise)."""
    return ref.load_cached(reference_path(kind), fingerprint(kind),
                           "cycles_caustic_reference.py")


def main(kinds=("smooth", "frosted")):
    import time

    for kind in kinds:
        started = time.perf_counter()
        samples = samples_of(kind)
        off = render(samples, 1, False, kind)
        a = render(samples, 2, True, kind) - off
        b = render(samples, 3, True, kind) - off
        np.savez_compressed(reference_path(kind), caustic=((a + b) / 2).astype(np.float32),
                            caustic_a=a.astype(np.float32), caustic_b=b.astype(np.float32),
                            samples=np.int64(samples), fingerprint=np.str_(fingerprint(kind)),
                            blender=np.str_(bpy.app.version_string))
        print(f"{reference_path(kind).relative_to(ROOT)}: in {time.perf_counter() - started:.1f} s, "
              f"caustic sum {(a + b).sum() / 2:.3f}, seeds differ by "
              f"{100 * (a.sum() / b.sum() - 1):+.2f} %")


if __name__ == "__main__":
    main(sys.argv[1:] or ("smooth", "frosted"))
