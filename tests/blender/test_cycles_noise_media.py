"""Heterogeneous density against Cycles in the same bpy process (cached reference:
tests/blender/cycles_noise_media_reference.py, the scene and the command that re-renders
it): the fog cube of test_cycles_mesh_media.py with its Principled Volume Density from a
Noise Texture (Object coordinates) times 3, under the spot light. Per-channel image means
within 3 %, 8 x 8 block means within 10 % (blocks darker than 2 % of the image mean are not
counted)."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_media_reference as media  # noqa: E402
from tests.blender import cycles_noise_media_reference as noise_media  # noqa: E402

pytestmark = [pytest.mark.blender]


@pytest.fixture(scope="module")
def fog_noise():
    return media.render_photon_map(noise_media.SCENES["fog_noise"]())


def _figures(passes):
    return media.figures("fog_noise", passes, noise_media.load_reference("fog_noise"))


def test_noise_fog_cube_channel_means_match_cycles(fog_noise):
    f = _figures(fog_noise)
    combined = fog_noise["Combined"][..., :3].mean()
    assert fog_noise["Volume Direct"][..., :3].mean() > 0.1 * combined
    assert fog_noise["Volume Indirect"][..., :3].mean() > 0.05 * combined
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]


def test_noise_fog_cube_block_means_match_cycles(fog_noise):
    f = _figures(fog_noise)
    assert f["worst_block"] < 0.10, f["blocks"]
