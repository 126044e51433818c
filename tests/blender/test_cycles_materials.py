"""Photon Map's materials against Cycles (issue 13): a sphere of each material in a uniform
world plus an area light, and a rough-metal sphere in the Cornell box
(cycles_material_reference.py: the scenes, Cycles' settings, the cached references and
the command that re-renders them).

Photon Map renders each scene through the engine with its default settings, twice (seeds
1 and 2, SAMPLES / 2 each), which gives its own noise. Tolerances of the issue: image
means per channel within 2 %; 8 x 8 block means within 5 % + 3 sigma (sigma: both
renderers' noise of that block; blocks darker than 2 % of the image mean are not
counted, see cycles_reference.compare).

Scenes the core cannot render yet (a lobe it lacks) are expected failures: ``PENDING``
names the missing piece; they run and print their figures (``-rA -s``) all the same.
"""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_material_reference as mr  # noqa: E402
from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes  # noqa: E402

pytestmark = pytest.mark.blender

SAMPLES = 128
"""Photon Map camera samples per pixel over both seeds."""

SAMPLES_FOR = {"glass": 1024, "rough_glass": 1024, "thin_wall": 1024}
"""Scenes whose noise needs more samples for the comparison to mean something: the light
seen through rough glass after internal bounces comes as rare bright samples, which two
64-sample seeds catch too seldom for their difference to estimate the blocks' noise (at
2 x 64 the glass sphere's highlight blocks came out +27 % / -17 % / -44 % from run to run,
"over" by sigmas that were too small; at 2 x 512 every block is within 5 % + 3 sigma and the
channel means move by under 0.5 %)."""

# What still differs from Cycles, as measured on this core (channel means PM / Cycles - 1;
# the note of issue 13 has every figure). The other scenes are plain tests. Strict: a case
# that starts passing must leave this list.
PENDING = {}


def photon_map_pair(name):
    """(image (H, W, 3) float32, block sigma (h, w, 3)) of two Photon Map renders of
    scene ``name`` (seeds 1 and 2, SAMPLES (or SAMPLES_FOR[name]) / 2 samples each),
    averaged."""
    runs = []
    samples = SAMPLES_FOR.get(name, SAMPLES)
    for seed in (1, 2):
        scene = mr.SCENES[name]()
        scenes.use_photon_map(scene, samples=samples // 2, seed=seed,
                              max_specular_depth=mr.BOUNCES, photon_max_bounces=mr.BOUNCES)
        runs.append(scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64))
    a, b = runs
    return ((a + b) / 2).astype(np.float32), ref.block_sigma(a, b)


def _case(name):
    marks = []
    if name in PENDING:
        marks.append(pytest.mark.xfail(strict=True, reason=PENDING[name]))
    if tuple(bpy.app.version[:2]) < mr.needs(name):
        marks.append(pytest.mark.skip(reason=f"needs Blender {mr.needs(name)}"))
    return pytest.param(name, marks=marks, id=name)


@pytest.mark.parametrize("name", [_case(name) for name in mr.SCENES])
def test_material_matches_cycles(name):
    cycles = mr.load_reference(name)
    image, sigma_pm = photon_map_pair(name)
    assert np.all(np.isfinite(image)) and image.min() >= 0
    sigma = np.sqrt(sigma_pm**2 + cycles["block_sigma"].astype(np.float64) ** 2)
    figures = ref.compare(image, cycles["image"], sigma)
    bad = np.argwhere(figures["excess"] > 1.0)
    print(f"\n{name}: channel means PM/Cycles - 1 = {np.round(100 * figures['channel'], 2)} %, "
          f"worst block {100 * figures['worst_block']:.1f} %, median |block| "
          f"{100 * np.nanmedian(np.abs(figures['blocks'])):.2f} %, blocks over 5 % + 3 sigma: "
          f"{len(bad)} of {int(np.sum(np.isfinite(figures['excess'])))}, noise-limited blocks "
          f"{100 * figures['noisy_blocks']:.0f} %")
    assert np.all(np.abs(figures["channel"]) < 0.02), figures["channel"]
    assert bad.size == 0, (f"blocks (row, col, channel) off by more than 5 % + 3 sigma: "
                           f"{bad.tolist()[:12]}, relative differences "
                           f"{[round(float(figures['blocks'][tuple(b)]), 3) for b in bad[:12]]}")
