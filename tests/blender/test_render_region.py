"""Render Region through Blender (F12's path, ``bpy.ops.render.render``): only the
region is rendered, and Blender gets it where it expects it: the cropped image, or in
place in the whole frame (Crop to Render Region off). Its pixels are compared with the
same pixels of a whole-frame render with the same seed."""

import bpy
import numpy as np
import pytest

from tests.blender import scenes

pytestmark = [pytest.mark.blender, pytest.mark.api]

W, H = 40, 30
BORDER = (0.2, 0.65, 0.3, 0.9)  # min_x, max_x, min_y, max_y (fractions, y from the bottom)


def scene_with_border():
    scene = scenes.plane_and_point_light(width=W, height=H)
    scenes.add_sphere(radius=0.4, location=(0.3, 0.2, 0.4), material=scenes.diffuse_material(
        "Red", (0.8, 0.1, 0.1)))
    scenes.use_photon_map(scene, samples=2, global_photons=3000, caustic_photons=0,
                          final_gather_rays=8, seed=5)
    return scene


def region_rows_cols(border=BORDER):
    """The border in pixels, top-first rows, where Blender puts it: each float32 fraction
    times the resolution in float32, truncated. BORDER: 0.2-0.65 of 40 and 0.3-0.9 of 30
    (exact products in float32, though 0.65 x 40 is 25.99999 in float64); SHIFTED: 0.27 x
    40 = 10.8 is column 10 (rounding would say 11 and shift the region by a pixel)."""
    x0, x1, y0, y1 = (int(np.float32(f) * np.float32(n)) for f, n in zip(border, (W, W, H, H)))
    return slice(H - y1, H - y0), slice(x0, x1)


SHIFTED = (0.27, 0.7, 0.3, 0.8)


@pytest.mark.parametrize("crop, border", [(True, BORDER), (False, BORDER), (True, SHIFTED),
                                          (False, SHIFTED)])
def test_the_region_is_the_same_pixels_as_the_whole_render(crop, border):
    scene = scene_with_border()
    whole = scenes.render_passes()["Combined"]
    r = scene.render
    r.use_border, r.use_crop_to_border = True, crop
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = border
    part = scenes.render_passes()["Combined"]
    rows, cols = region_rows_cols(border)
    if crop:  # the size Blender gave the RenderResult, filled to its edges
        assert np.all(part[..., 3] == 1.0)
        assert part.shape == (rows.stop - rows.start, cols.stop - cols.start, 4)
        inside = part
    else:
        assert part.shape == whole.shape
        inside = part[rows, cols]
        outside = np.ones(whole.shape[:2], bool)
        outside[rows, cols] = False
        assert np.all(part[outside][:, :3] == 0.0)  # Blender leaves the rest empty
    assert inside[..., :3].max() > 0
    np.testing.assert_array_equal(inside, whole[rows, cols])
