"""A real ``blender -b`` (Debian's Blender 3.4) renders with Photon Map, as a render farm would.

The scene is built by a script inside that Blender (3.4 cannot open files saved by 5.0),
saved, then rendered with the command line of issue 6:

    blender -b --factory-startup --addons photon_map SCENE.blend -E PHOTON_MAP \
        -o //frame_#### -F OPEN_EXR_MULTILAYER -f 1

The expected pixels are analytic (tests/blender/script_scenes.py, passes_scene): a sun of
irradiance pi straight down and a uniform world W over a Lambert square of albedo rho give
Direct = rho (1 + W); the emissive square shows colour x strength in Emission; the mirror
shows its tint x W in Specular. Those squares use Principled BSDFs with Blender 3.4's
socket names, so the exporter's 3.x fallbacks are checked on real 3.4 data.
"""

import json

import numpy as np
import pytest

from tests.blender import debian_blender, scenes
from tests.blender import script_scenes as ss

pytestmark = pytest.mark.blender

SCRIPT = debian_blender.ROOT / "tests" / "blender" / "script_scenes.py"


def build(folder, name):
    """Build script_scenes.NAME inside the Blender executable; returns the .blend path."""
    path = folder / f"{name}.blend"
    done = debian_blender.run(["-b", "--factory-startup", "--python-exit-code", "1",
                               "--python", SCRIPT, "--", name, path], folder, timeout=120)
    debian_blender.check(done)
    assert path.is_file()
    return path


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """(passes of frame 1, Blender's output) for passes_scene rendered by ``blender -b``."""
    folder = tmp_path_factory.mktemp("blender_exe")
    blend = build(folder, "passes_scene")
    done = debian_blender.run(
        ["-b", "--factory-startup", "--addons", "photon_map", blend, "-E", "PHOTON_MAP",
         "-o", "//frame_####", "-F", "OPEN_EXR_MULTILAYER", "-f", "1"], folder)
    output = debian_blender.check(done)
    written = sorted(p.name for p in folder.glob("frame_*"))
    assert written == ["frame_0001.exr"], output[-3000:]
    return scenes.read_multilayer_exr(folder / "frame_0001.exr"), output


def test_render_log_names_the_engine(rendered):
    _, output = rendered
    assert "Photon Map | Done" in output  # our stats line, so it was not EEVEE
    assert "Saved:" in output and "frame_0001.exr" in output


def test_exr_has_the_passes(rendered):
    passes, _ = rendered
    assert {"Combined", "Emission", "Direct", "Specular"} <= set(passes), sorted(passes)
    width, height = ss.PASSES_VIEW[1:]
    assert passes["Combined"].shape == (height, width, 4)
    for name, image in passes.items():
        if name != "Combined":
            assert image.shape == (height, width, 3), name
        assert np.isfinite(image).all() and image.min() >= 0.0, name
    np.testing.assert_array_equal(passes["Combined"][..., 3], 1.0)
    light = sum(image for name, image in passes.items() if name != "Combined")
    np.testing.assert_allclose(passes["Combined"][..., :3], light, rtol=1e-5, atol=1e-6)


def _square(image, index):
    """Pixels well inside square ``index`` (0 left, 1 middle, 2 right), (N, C)."""
    scale, width, _ = ss.PASSES_VIEW
    metres = (np.arange(width) + 0.5) / width * scale - scale / 2
    columns = np.abs(metres - ss.SQUARE_CENTRES[index]) < 0.5 - 2.5 * scale / width
    return image[:, columns].reshape(-1, image.shape[2])


def assert_uniform(pixels, expected, rtol):
    np.testing.assert_allclose(pixels, np.broadcast_to(expected, pixels.shape), rtol=rtol)


def test_pixels_match_the_analytic_values(rendered):
    passes, _ = rendered
    world = np.array(ss.WORLD_RADIANCE)
    # Left: Principled 'Base Color', lit by the sun (rho S / pi) and the world (rho W).
    assert_uniform(_square(passes["Direct"], 0),
                   np.array(ss.ALBEDO) * (ss.SUN_STRENGTH / np.pi + world), rtol=2e-3)
    # Middle: 3.4's 'Emission' colour x 'Emission Strength' over a black base.
    assert_uniform(_square(passes["Emission"], 1),
                   np.array(ss.EMISSION) * ss.EMISSION_STRENGTH, rtol=1e-4)
    assert _square(passes["Direct"], 1).max() < 1e-6
    # Right: metallic 1, roughness 0 is a mirror of tint MIRROR reflecting the world.
    assert_uniform(_square(passes["Specular"], 2), np.array(ss.MIRROR) * world, rtol=1e-4)
    assert _square(passes["Direct"], 2).max() < 1e-6
    # The squares fill the view: the background is never seen directly.
    assert passes.get("Environment", np.zeros(1)).max() == 0.0
