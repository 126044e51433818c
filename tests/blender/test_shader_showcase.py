"""The shader showcase (examples/shader_showcase.py: procedural wood with bump, a
normal-mapped brick wall, a metal with a noise roughness, colour-attribute props, an area
light and a sky) at 64 x 48 against Cycles in the same bpy process, global illumination
on both sides (8 bounces): per-channel image means within 3 %, 8 x 8 block means within
5 % + 4 sigma of Cycles' noise (sigma from two Cycles seeds)."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from examples import shader_showcase as showcase  # noqa: E402
from tests.blender import cycles_gi_reference as gi  # noqa: E402
from tests.blender import cycles_reference as cr  # noqa: E402
from tests.blender import scenes  # noqa: E402

pytestmark = pytest.mark.blender

RESOLUTION = (64, 48)
CYCLES_SAMPLES = 64
SAMPLES = 16


def test_shader_showcase_matches_cycles():
    scene = scenes.reset()
    showcase.build_showcase(RESOLUTION, scene)
    cycles = []
    for seed in (0, 1):
        gi.configure_cycles_gi(scene, CYCLES_SAMPLES, seed)
        scene.cycles.caustics_reflective = True
        cycles.append(scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64))
    scenes.use_photon_map(scene, samples=SAMPLES, seed=1, final_gather_rays=256,
                          photon_max_bounces=gi.BOUNCES, indirect_mode='final_gather')
    passes = scenes.render_passes(scene)
    ours = passes["Combined"][..., :3].astype(np.float64)
    assert np.all(np.isfinite(ours)) and ours.min() >= 0
    reference = 0.5 * (cycles[0] + cycles[1])
    sigma = cr.block_sigma(cycles[0], cycles[1])
    channel = ours.reshape(-1, 3).mean(0) / reference.reshape(-1, 3).mean(0) - 1.0
    bo, br = cr.block_means(ours), cr.block_means(reference)
    counted = br > 0.02 * reference.reshape(-1, 3).mean(0)
    excess = np.where(counted, np.abs(bo - br) / (0.05 * br + 4.0 * sigma), 0.0)
    rel = np.where(counted, bo / np.where(counted, br, 1.0) - 1.0, 0.0)
    print(f"\nshader showcase: channel means PM/Cycles - 1 = {np.round(100 * channel, 2)} %, "
          f"worst block {100 * np.abs(rel).max():.1f} %, worst excess {excess.max():.2f}, "
          f"indirect / direct {passes['Indirect'].mean() / passes['Direct'].mean():.2f}")
    # The textures are seen: the wall's bricks and the floor's planks vary per pixel.
    assert reference.std() > 0.2 * reference.mean()
    assert np.all(np.abs(channel) < 0.03), channel
    assert excess.max() <= 1.0, (rel, excess)
