"""Image Texture sampling (core/shading/images.py) against values worked out by hand from
Cycles' definitions: texel centres, the four extensions, Closest, sRGB decoded after
filtering, alpha unassociated, UDIM tiles and the missing-image magenta; and the
ProgramImages contract."""

import numpy as np
import pytest

from core.scene.checks import SceneError
from core.scene.images import ProgramImages
from core.shading.images import EXTENSIONS, image_sample

A, B = 51, 255  # a 2 x 1 byte image: texel 0 = 0.2, texel 1 = 1.0 (every channel)


def row_image(encoding=0, alpha=255):
    t = np.zeros((1, 2, 4), np.uint8)
    t[0, 0, :3], t[0, 1, :3] = A, B
    t[..., 3] = alpha
    return ProgramImages.pack([[(0, t, encoding)]], ["Row"])


def sample(images, x, y=0.5, interp=1, ext="REPEAT", slot=0, unassociate=False):
    out = np.zeros(4)
    image_sample(images.bytes, images.shorts, images.floats, images.tiles, images.slot_first,
                 images.slot_count, slot, x, y, interp, EXTENSIONS[ext], unassociate, out)
    return out


@pytest.mark.parametrize("ext, want", [("REPEAT", 0.6), ("EXTEND", 0.2), ("CLIP", 0.1),
                                       ("MIRROR", 0.2)])
def test_linear_at_the_left_edge_follows_the_extension(ext, want):
    # x = 0 is half-way between texel -1 and texel 0
    assert sample(row_image(), 0.0, ext=ext)[0] == pytest.approx(want, abs=1e-12)


def test_linear_texel_centres_and_midpoint_and_closest():
    im = row_image()
    assert sample(im, 0.25)[0] == pytest.approx(0.2, abs=1e-12)
    assert sample(im, 0.75)[0] == pytest.approx(1.0, abs=1e-12)
    assert sample(im, 0.5)[0] == pytest.approx(0.6, abs=1e-12)
    assert sample(im, 0.49, interp=0)[0] == pytest.approx(0.2, abs=1e-12)
    assert sample(im, 0.51, interp=0)[0] == pytest.approx(1.0, abs=1e-12)
    assert sample(im, 1.2, interp=0, ext="CLIP")[0] == 0.0


def test_srgb_is_decoded_after_filtering():
    got = sample(row_image(encoding=1), 0.5)[0]
    assert got == pytest.approx(((0.6 + 0.055) / 1.055) ** 2.4, rel=1e-12)


def test_alpha_is_unassociated_after_filtering_unless_0_or_1():
    im = row_image(alpha=102)  # alpha 0.4
    assert sample(im, 0.5)[0] == pytest.approx(0.6, abs=1e-12)
    assert sample(im, 0.5, unassociate=True)[0] == pytest.approx(0.6 / 0.4, rel=1e-12)
    assert sample(im, 0.5, unassociate=True)[3] == pytest.approx(0.4, rel=1e-12)


def test_udim_tiles_and_missing_images_are_magenta():
    one = np.full((1, 1, 4), 255, np.uint8)
    two = np.full((1, 1, 4), 51, np.uint8)
    im = ProgramImages.pack([[(1001, one, 0), (1012, two, 0)]], ["Tiles"])
    im.validate()
    assert sample(im, 0.3, 0.3)[0] == pytest.approx(1.0)
    assert sample(im, 1.3, 1.7)[0] == pytest.approx(0.2)
    np.testing.assert_array_equal(sample(im, 1.3, 0.3), [1.0, 0.0, 1.0, 1.0])  # no 1002
    np.testing.assert_array_equal(sample(im, -0.3, 0.3), [1.0, 0.0, 1.0, 1.0])
    np.testing.assert_array_equal(sample(im, 0.3, 0.3, slot=-1), [1.0, 0.0, 1.0, 1.0])


def test_native_storage_and_validation():
    b = np.zeros((2, 3, 4), np.uint8)
    s = np.zeros((2, 3, 4), np.uint16)
    f = np.zeros((2, 3, 4), np.float32)
    im = ProgramImages.pack([[(0, b, 1)], [(0, s, 1)], [(0, f, 0)]], ["b", "s", "f"])
    im.validate()
    assert im.nbytes == 6 * (4 + 8 + 16) and im.texels() == 18
    bad = ProgramImages(im.bytes, im.shorts, im.floats, im.tiles * np.array([1, 1, 9, 1, 1, 1]),
                        im.slot_first, im.slot_count, im.names)
    with pytest.raises(SceneError, match="tiles row 0"):
        bad.validate()
    with pytest.raises(SceneError, match="uint8, uint16 or float32"):
        ProgramImages.pack([[(0, np.zeros((2, 2, 3), np.uint8), 0)]])
