"""A varying Principled Volume colour against Cycles in the same bpy process (cached
reference: tests/blender/cycles_colour_media_reference.py, the scene and the command that
re-renders it): the fog cube of test_cycles_mesh_media.py with its Color from a Noise
Texture's Color and its Absorption Color from a Linear Gradient (Object coordinates),
under the spot light. Per-channel image means within 3 %, 8 x 8 block means within 10 %
(blocks darker than 2 % of the image mean are not counted)."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_colour_media_reference as colour_media  # noqa: E402
from tests.blender import cycles_media_reference as media  # noqa: E402

pytestmark = [pytest.mark.blender]


@pytest.fixture(scope="module")
def fog_colour():
    return media.render_photon_map(colour_media.SCENES["fog_colour"]())


def _figures(passes):
    return media.figures("fog_colour", passes, colour_media.load_reference("fog_colour"))


def test_colour_fog_cube_channel_means_match_cycles(fog_colour):
    f = _figures(fog_colour)
    combined = fog_colour["Combined"][..., :3].mean()
    assert fog_colour["Volume Direct"][..., :3].mean() > 0.1 * combined
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]


def test_colour_fog_cube_block_means_match_cycles(fog_colour):
    f = _figures(fog_colour)
    assert f["worst_block"] < 0.10, f["blocks"]


def test_a_linked_colour_exports_a_colour_program():
    """The cube exports one medium whose row holds the weights (sigma_s = sigma_a = 1: the
    Principled Volume outside a Mix) and a program of seven TARGET_DENSITY outputs, slots
    0-6 (density 0.8, Color, Absorption Color); no warning about the linked inputs. At the
    cube's centre the Gradient's Absorption Color is 0 (Object x = 0) and its +x face
    (x = 0.6) 0.6."""
    from core.shading import program as pg
    from tests.blender.test_export import export

    colour_media.colour_fog_scene()
    result = export()
    m = result.scene.media
    assert m.count == 1 and list(m.density_texture) == [0]
    np.testing.assert_allclose(m.sigma_s[0], 1.0)
    np.testing.assert_allclose(m.sigma_a[0], 1.0)
    (prog,) = m.programs
    assert prog.outputs.shape == (7, 4)
    assert list(prog.outputs[:, 1]) == [pg.TARGET_DENSITY] * 7
    assert list(prog.outputs[:, 3]) == list(range(7))
    assert not any("Color" in w for w in result.warnings), result.warnings
