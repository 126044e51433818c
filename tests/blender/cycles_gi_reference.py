"""Cycles with global illumination as the reference for Photon Map's indirect light.

The scene: the demo's Cornell box (examples/cornell_box.py) without its two spheres, so
every path is diffuse and Cycles converges quickly. Cycles renders it with diffuse
bounces on: max_bounces = diffuse_bounces = BOUNCES, the same count as Photon Map's
``photon_max_bounces`` (the box is open at the front, so the light left after BOUNCES
bounces is far below the tolerances); the other settings are those of
cycles_reference.configure_cycles (CPU, box filter, no denoising, no clamping).

Run as a script to re-render the cached reference tests/data/cycles_gi_cornell_64x48.npz
(two seeds of CYCLES_SAMPLES each, about a minute or two on 2 cores):

    .venv/bin/python tests/blender/cycles_gi_reference.py
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

BOUNCES = 8
CYCLES_SAMPLES = 1024
RESOLUTION = ref.RESOLUTION
NAME = "gi_cornell"


def cornell_without_spheres(resolution=RESOLUTION):
    """The demo's Cornell box, spheres removed (walls, area light, camera), fresh scene."""
    scene = ref.demo_scene(resolution=resolution)
    for name in ("MirrorSphere", "GlassSphere"):
        bpy.data.objects.remove(bpy.data.objects[name], do_unlink=True)
    return scene


def configure_cycles_gi(scene, samples, seed=0):
    """Cycles as in cycles_reference, with BOUNCES diffuse bounces."""
    ref.configure_cycles(scene, samples, seed, max_depth=BOUNCES)
    scene.cycles.max_bounces = BOUNCES
    scene.cycles.diffuse_bounces = BOUNCES
    return scene


def render_cycles_gi(scene, samples, seed=0) -> np.ndarray:
    """(H, W, 3) float32 Combined radiance, row 0 at the top."""
    configure_cycles_gi(scene, samples, seed)
    return scenes.render_passes(scene)["Combined"][..., :3].astype(np.float32)


def fingerprint() -> str:
    """Hash of the code behind the reference (scene, Cycles settings); stale when it changes."""
    return ref.code_fingerprint([ref.scene_fingerprint("demo"), cornell_without_spheres,
                                 configure_cycles_gi, (RESOLUTION, BOUNCES)])


def reference_path() -> pathlib.Path:
    return ref.DATA / f"cycles_{NAME}_{RESOLUTION[0]}x{RESOLUTION[1]}.npz"


def load_reference() -> dict:
    """The cached Cycles render: image (H, W, 3), block_sigma, samples, fingerprint."""
    return ref.load_cached(reference_path(), fingerprint(), "cycles_gi_reference.py")


def main():
    import time

    started = time.perf_counter()
    a = render_cycles_gi(cornell_without_spheres(), CYCLES_SAMPLES, seed=1)
    b = render_cycles_gi(cornell_without_spheres(), CYCLES_SAMPLES, seed=2)
    np.savez_compressed(
        reference_path(), image=((a + b) / 2).astype(np.float32),
        block_sigma=ref.block_sigma(a, b).astype(np.float32),
        samples=np.int64(2 * CYCLES_SAMPLES), fingerprint=np.str_(fingerprint()),
        bounces=np.int64(BOUNCES), blender=np.str_(bpy.app.version_string))
    print(f"{reference_path().relative_to(ROOT)}: 2 x {CYCLES_SAMPLES} spp in "
          f"{time.perf_counter() - started:.1f} s, mean {((a + b) / 2).reshape(-1, 3).mean(axis=0)}")


if __name__ == "__main__":
    main()
