"""Photon Map's emissive media against Cycles in the same bpy process (cached reference:
tests/blender/cycles_emissive_media_reference.py, the scene and the command that
re-renders it): a glowing Principled Volume cube (low density, Emission Strength 2) over a
white floor, no light: the floor is lit by the medium's photons only (400k global
photons, preview indirect). Per-channel image
means within 3 %, 8 x 8 block means within 10 % (blocks darker than 2 % of the image mean
are not counted)."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_emissive_media_reference as emissive  # noqa: E402
from tests.blender import cycles_media_reference as media  # noqa: E402
from tests.blender import scenes  # noqa: E402

pytestmark = [pytest.mark.blender]


GLOBAL_PHOTONS = 400_000
"""The media tests' settings with 4 x their global photons: the floor is lit by the
medium's photons alone (no shadow ray reaches a medium), and at 100k the dim floor blocks
at the image's edges read -12.7 % (seed 1) and +3.0 % (seed 2): noise."""


@pytest.fixture(scope="module")
def glow_cube():
    scene = emissive.SCENES["glow_cube"]()
    scenes.use_photon_map(scene, **dict(media.PHOTON_MAP_SETTINGS, global_photons=GLOBAL_PHOTONS))
    return scenes.render_passes(scene)


def _figures(passes):
    return media.figures("glow_cube", passes, emissive.load_reference("glow_cube"))


def test_glow_cube_channel_means_match_cycles(glow_cube):
    f = _figures(glow_cube)
    combined = glow_cube["Combined"][..., :3].mean()
    # the cube's glow is seen (Emission) and lights the floor (its photons: Indirect)
    assert glow_cube["Emission"][..., :3].mean() > 0.1 * combined
    assert glow_cube["Indirect"][..., :3].mean() > 0.1 * combined
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]


def test_glow_cube_block_means_match_cycles(glow_cube):
    f = _figures(glow_cube)
    assert f["worst_block"] < 0.10, f["blocks"]
