"""Heterogeneous density against Cycles in the same bpy process (cached reference:
tests/blender/cycles_noise_media_reference.py, the scene and the command that re-renders
it): the fog cube of test_cycles_mesh_media.py with its Principled Volume Density from a
Noise Texture (Object coordinates) times 3, under the spot light, rendered with
GLOBAL_PHOTONS global photons. Per-channel image means within 3 %, 8 x 8 block means within
10 % (blocks darker than 2 % of the image mean are not counted)."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_media_reference as media  # noqa: E402
from tests.blender import cycles_noise_media_reference as noise_media  # noqa: E402

pytestmark = [pytest.mark.blender]


GLOBAL_PHOTONS = 400_000
"""Four times PHOTON_MAP_SETTINGS': at 100k (17k stored, gather radius 0.24 m) the floor's
two bottom corner blocks, lit only by the photon map (outside the spot's cone), are the
worst: photon noise (seeds 1 / 2: left +5.1 / -10.0 %, right -11.6 / -4.8 %; Cycles' sigma
there 1.2 / 1.4 %) on the density estimate's bias at the floor's open edges, whose
gather disc overhangs them (about -4 % over those blocks at 0.24 m with the cone filter,
from the geometry). At 400k (radius 0.12 m) they read +1.4 / +1.7 % and -2.2 / -2.5 %,
the worst block 4.5 % (seed 1) / 8.0 % (seed 2: a block beside the cube, -1.7 % at seed 1),
for about 10 s more of the photon pass (docs/volumes.md)."""


@pytest.fixture(scope="module")
def fog_noise():
    return media.render_photon_map(noise_media.SCENES["fog_noise"](),
                                   global_photons=GLOBAL_PHOTONS)


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
    assert f["worst_block"] < 0.10, f["blocks"]  # measured 4.5 %


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
