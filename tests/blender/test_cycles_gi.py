"""Photon Map's indirect light against Cycles with diffuse bounces: the demo's Cornell box
without spheres (every path diffuse), 64 x 48, the same bounce count on both sides
(cycles_gi_reference.py: the scene, Cycles' settings, the cached reference and the
command that re-renders it).

Photon Map renders with final gathering (the final mode) and default photon settings;
its noise and the photon map's bias must stay within: per-channel image means 3 %,
8 x 8 block means 8 % (blocks darker than 2 % of the image mean are not counted).
"""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_gi_reference as gi  # noqa: E402
from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes  # noqa: E402

pytestmark = pytest.mark.blender

SAMPLES = 32
GATHER_RAYS = 256


@pytest.fixture(scope="module")
def photon_map_gi():
    scene = gi.cornell_without_spheres()
    scenes.use_photon_map(scene, samples=SAMPLES, seed=1, final_gather_rays=GATHER_RAYS,
                          photon_max_bounces=gi.BOUNCES, indirect_mode='final_gather')
    return scenes.render_passes(scene)


def test_cornell_box_indirect_light_matches_cycles(photon_map_gi):
    cycles = gi.load_reference()
    passes = photon_map_gi
    image = passes["Combined"][..., :3]
    assert np.all(np.isfinite(image)) and image.min() >= 0
    figures = ref.compare(image, cycles["image"])
    print(f"\nCornell box GI: channel means PM/Cycles - 1 = "
          f"{np.round(100 * figures['channel'], 2)} %, worst block "
          f"{100 * figures['worst_block']:.1f} %, median |block| "
          f"{100 * np.nanmedian(np.abs(figures['blocks'])):.2f} %")
    # The indirect term is a large part of this image: the comparison tests it.
    assert passes["Indirect"].mean() > 0.3 * passes["Direct"].mean()
    assert np.all(np.abs(figures["channel"]) < 0.03), figures["channel"]
    assert figures["worst_block"] < 0.08, figures["blocks"]


def test_no_caustics_without_specular_surfaces(photon_map_gi):
    assert np.all(photon_map_gi["Caustics"] == 0.0)
