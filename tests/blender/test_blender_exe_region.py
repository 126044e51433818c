"""Render Region through a real ``blender -b`` (Debian's Blender 3.4), as a render farm
runs it: the scene (script_scenes.region_scene, built inside that Blender) saved with the
Render Region on, Crop to Render Region on or off, and without it, each rendered with

    blender -b --factory-startup --addons photon_map SCENE.blend -E PHOTON_MAP \
        -o //NAME_#### -F OPEN_EXR_MULTILAYER -f 1

The region's pixels of the saved frame are those of the whole frame, bit for bit (each is
traced from its index in the whole frame with the same seed); cropped, the file is the
region's size; in place, the rest of the frame is empty.
"""

import math

import numpy as np
import pytest

from tests.blender import debian_blender, scenes
from tests.blender import script_scenes as ss
from tests.blender.test_blender_exe import build

pytestmark = pytest.mark.blender


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """{scene name: passes of its frame 1} for the three region scenes."""
    folder = tmp_path_factory.mktemp("blender_exe_region")
    out = {}
    for name in ("region_whole", "region_crop", "region_in_place"):
        blend = build(folder, name)
        done = debian_blender.run(
            ["-b", "--factory-startup", "--addons", "photon_map", blend, "-E", "PHOTON_MAP",
             "-o", f"//{name}_####", "-F", "OPEN_EXR_MULTILAYER", "-f", "1"], folder)
        output = debian_blender.check(done)
        assert "Photon Map | Done" in output, output[-3000:]
        out[name] = scenes.read_multilayer_exr(folder / f"{name}_0001.exr")
    return out


def region_rows_cols():
    """Where Blender puts the region: each fraction times the resolution, truncated
    (0.2 x 54 = 10.8 is column 10; 0.7 x 54 = 37.8 ends before 37); rows from the top."""
    _, width, height = ss.PASSES_VIEW
    x0, x1, y0, y1 = (int(math.floor(f * n)) for f, n in
                      zip(ss.REGION_BORDER, (width, width, height, height)))
    assert (x0, x1, y0, y1) == (10, 37, 5, 14)
    return slice(height - y1, height - y0), slice(x0, x1)


@pytest.mark.parametrize("name", ["region_crop", "region_in_place"])
def test_the_region_is_the_same_pixels_as_the_whole_frame(frames, name):
    whole = frames["region_whole"]
    part = frames[name]
    rows, cols = region_rows_cols()
    for pass_name in ("Combined", "Direct", "Emission", "Specular"):
        full, image = whole[pass_name], part[pass_name]
        if name == "region_crop":
            assert image.shape[:2] == (rows.stop - rows.start, cols.stop - cols.start), pass_name
            inside = image
        else:
            assert image.shape == full.shape, pass_name
            inside = image[rows, cols]
            outside = np.ones(full.shape[:2], bool)
            outside[rows, cols] = False
            assert np.all(image[outside] == 0.0), pass_name  # Blender leaves the rest empty
        assert np.isfinite(inside).all()
        np.testing.assert_array_equal(inside, full[rows, cols], err_msg=pass_name)
    assert part["Combined"][..., :3].max() > 0
