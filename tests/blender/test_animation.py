"""Animation: every frame of a range is exported from its own depsgraph and traced.

script_scenes.animated_scene: a red cube slides over a grey floor (x = -1, 0, 1 m at
frames 1-3) while the orthographic camera, straight above, follows more slowly
(x = 0, 0.5, 1 m). So the cube must appear at x_cube - x_camera in each picture; a frame
rendered with a stale object (x_cube of frame 1) or a stale camera lands elsewhere. The
floor is uniform under a sun straight down, so pixels away from the cube agree between
frames and pixels the cube moved over differ.

Rendered twice: by the headless CLI (``--frames 1-3``, bpy 5.0) and by a real Blender
executable (``blender -b ... -s 1 -e 3 -a``, Debian's 3.4; skipped without one).
"""

import subprocess
import sys

import bpy
import numpy as np
import pytest

from tests.blender import debian_blender, scenes
from tests.blender import script_scenes as ss
from tests.conftest import ROOT

pytestmark = pytest.mark.blender


# The oracle below is direct light only (a uniform floor under the sun): the photon terms
# are switched off, or the cube's colour bleeding would (rightly) tint the floor near it.
DIRECT_ONLY_CLI = ("--set", "indirect_mode=off", "--set", "caustics=false")
DIRECT_ONLY_EXPR = ("import bpy; p = bpy.context.scene.photon_map; "
                    "p.indirect_mode = 'off'; p.caustics = False")


def render_with_cli(folder):
    ss.animated_scene()
    blend = folder / "anim.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    done = subprocess.run([sys.executable, "-m", "photon_engine", "render", str(blend),
                           "-o", str(folder / "anim_####"), "--frames", "1-3",
                           "--set", "samples=4", *DIRECT_ONLY_CLI],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert done.stdout.count("wrote ") == 3, done.stdout
    return done.stdout


def render_with_blender_exe(folder):
    blend = folder / "animated_scene.blend"
    debian_blender.check(debian_blender.run(
        ["-b", "--factory-startup", "--python-exit-code", "1", "--python",
         ROOT / "tests" / "blender" / "script_scenes.py", "--", "animated_scene", blend],
        folder, timeout=120))
    done = debian_blender.run(
        ["-b", "--factory-startup", "--addons", "photon_map", blend, "-E", "PHOTON_MAP",
         "--python-expr", DIRECT_ONLY_EXPR, "-o", "//anim_####", "-F", "OPEN_EXR_MULTILAYER", "-s", "1", "-e", "3", "-a"],
        folder)
    return debian_blender.check(done)


@pytest.fixture(scope="module", params=["cli", "blender_exe"])
def frames(request, tmp_path_factory):
    """Combined (H, W, 4) of frames 1, 2, 3, rendered by the CLI or ``blender -b -a``."""
    folder = tmp_path_factory.mktemp(f"anim_{request.param}")
    output = {"cli": render_with_cli, "blender_exe": render_with_blender_exe}[request.param](folder)
    written = sorted(p.name for p in folder.glob("anim_*"))
    assert written == [f"anim_{f:04d}.exr" for f in ss.FRAMES], output[-3000:]
    return [scenes.read_multilayer_exr(folder / name)["Combined"] for name in written]


def _cube_mask(image):
    red, green = image[..., 0], image[..., 1]
    return (red > 2.0 * green) & (red > 0.2)


def _column_metres(columns):
    scale, width, _ = ss.ANIMATION_VIEW
    return (np.asarray(columns) + 0.5) / width * scale - scale / 2


def test_cube_is_where_object_and_camera_put_it(frames):
    scale, width, _ = ss.ANIMATION_VIEW
    pixel = scale / width
    area = (ss.CUBE_SIZE / pixel) ** 2
    for image, cube_x, camera_x in zip(frames, ss.CUBE_X, ss.CAMERA_X):
        assert np.isfinite(image).all() and image[..., :3].min() >= 0.0
        rows, columns = np.nonzero(_cube_mask(image))
        assert 0.85 * area < rows.size < 1.15 * area, rows.size
        centre = _column_metres(columns).mean()
        assert abs(centre - (cube_x - camera_x)) < 0.5 * pixel, (centre, cube_x, camera_x)
        assert abs(rows.mean() + 0.5 - image.shape[0] / 2) < 0.5


def test_frames_agree_away_from_the_cube_and_differ_where_it_moved(frames):
    masks = [_cube_mask(image) for image in frames]
    # One pixel of margin: pixels on the cube's edge mix cube and floor.
    near = [np.pad(m, 1)[:-2, 1:-1] | np.pad(m, 1)[2:, 1:-1] | np.pad(m, 1)[1:-1, :-2]
            | np.pad(m, 1)[1:-1, 2:] | m for m in masks]
    floor = np.array(ss.FLOOR_ALBEDO) * ss.SUN_STRENGTH / np.pi
    for i in range(len(frames)):
        for j in range(i + 1, len(frames)):
            away = ~(near[i] | near[j])
            np.testing.assert_allclose(frames[i][away][:, :3], frames[j][away][:, :3],
                                       rtol=1e-6, atol=1e-7)
            moved = masks[i] & ~near[j]
            assert moved.sum() > 10
            difference = np.abs(frames[i][moved][:, :3] - frames[j][moved][:, :3]).max(axis=1)
            assert difference.min() > 0.1
    # Away from the cube is the lit floor: albedo x irradiance / pi.
    away = ~near[0]
    np.testing.assert_allclose(frames[0][away][:, :3], np.broadcast_to(floor, (away.sum(), 3)),
                               rtol=1e-4)


@pytest.mark.parametrize("text, frames", [
    ("7", [7]), ("1-3", [1, 2, 3]), ("1..3", [1, 2, 3]), ("1,3,5-7", [1, 3, 5, 6, 7]),
    ("-2..1", [-2, -1, 0, 1]), ("-4", [-4]), ("2-2", [2]),
])
def test_frame_lists(text, frames):
    from tests.conftest import load_extension_package

    load_extension_package()
    from photon_map.photon_engine.cli import parse_frames

    assert parse_frames(text) == frames


@pytest.mark.parametrize("text, message", [
    ("3-1", "frame range '3-1' ends before it starts"),
    ("1-", "bad frame '1-' in '1-'"),
    ("1,,2", "bad frame '' in '1,,2'"),
    ("a", "bad frame 'a'"),
])
def test_bad_frame_list_is_a_usage_error(tmp_path, text, message):
    done = subprocess.run([sys.executable, "-m", "photon_engine", "render",
                           str(tmp_path / "x.blend"), "--frames", text],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert message in done.stderr and "Traceback" not in done.stderr
