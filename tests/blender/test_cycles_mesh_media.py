"""Photon Map's media inside closed meshes against Cycles in the same bpy process (cached
references: tests/blender/cycles_mesh_media_reference.py, the scenes and the command that
re-renders them): a fog cube (a volume-only material: null faces) under a spot light, and
a smoke-filled glass sphere under a 1 m spot light (smoke_glass_1m: the smoke lit only
through the glass). Per-channel image means within 3 %, 8 x 8 block means within 10 %
(blocks darker than 2 % of the image mean are not counted). Once compiled, a few seconds
for the cube, ~15-20 s for the sphere's 256 spp on the shared 2 cores: in the default suite."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_media_reference as media  # noqa: E402
from tests.blender import cycles_mesh_media_reference as mesh_media  # noqa: E402
from tests.blender import cycles_reference as ref  # noqa: E402

pytestmark = [pytest.mark.blender]

def _render(name):
    return media.render_photon_map(mesh_media.SCENES[name]())


def _figures(name, passes):
    return media.figures(name, passes, mesh_media.load_reference(name))


@pytest.fixture(scope="module")
def fog_cube():
    return _render("fog_cube")


SMOKE_GLASS_SAMPLES = 256
"""Samples per pixel of the smoke_glass_1m render. The camera sees the spot light through
the sphere's top rim; at 16 spp the light's image decides the top blocks (+-17 %, seeds 1
and 2) and at 64 spp still +-11 %; at 256 spp the worst block is 4.6 / 3.2 / 4.3 % (seeds
1-3), ~15 s a render on the shared cores (docs/volumes.md, 'The smoke-filled glass
sphere's top blocks')."""


@pytest.fixture(scope="module")
def smoke_glass():
    """The 1 m light (smoke_glass_1m): at the 0.25 m light of smoke_glass the camera sees the
    light through the glass as a sub-pixel image (Cycles 1.84 and 1.95 in two rim pixels,
    a block's third) that no affordable sample count resolves: the image mean reads -2.5,
    +12.2, +5.6, +12.0 % at 16 spp (seeds 1-4), +3.1, -2.4, +1.2, +3.4 % at 64 spp."""
    scene = mesh_media.SCENES["smoke_glass_1m"]()
    return media.render_photon_map(scene, samples=SMOKE_GLASS_SAMPLES)


def test_fog_cube_channel_means_match_cycles(fog_cube):
    f = _figures("fog_cube", fog_cube)
    combined = fog_cube["Combined"][..., :3].mean()
    assert fog_cube["Volume Direct"][..., :3].mean() > 0.1 * combined
    assert fog_cube["Volume Indirect"][..., :3].mean() > 0.05 * combined
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]


def test_fog_cube_block_means_match_cycles(fog_cube):
    f = _figures("fog_cube", fog_cube)
    assert f["worst_block"] < 0.10, f["blocks"]


def test_smoke_filled_glass_channel_means_match_cycles(smoke_glass):
    f = _figures("smoke_glass_1m", smoke_glass)
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]  # measured +0.85 / +0.80 / +1.21 %


def test_smoke_filled_glass_block_means_match_cycles(smoke_glass):
    reference = mesh_media.load_reference("smoke_glass_1m")
    f = _figures("smoke_glass_1m", smoke_glass)
    counted = np.isfinite(f["blocks"])
    # Cycles' noise allows the 10 %: its 3 sigma is under 6 % of every counted block
    # (8 x 1024 spp; measured sigma at most 1.9 % of a block, median 0.46 %)
    cycles_sigma = ref.relative_block_sigma(reference)
    assert np.all(3.0 * cycles_sigma[counted] < 0.06), cycles_sigma
    assert f["worst_block"] < 0.10, f["blocks"]  # measured 4.6 / 3.2 / 4.3 % (seeds 1-3)


@pytest.mark.slow
def test_smoke_filled_glass_under_the_small_light_matches_cycles():
    """smoke_glass (the 0.25 m light) at 1024 spp, where its sub-pixel image through the glass
    averages out: channel means within 3 % (measured +0.22 / +0.42 %, seeds 1 / 2; at 64 spp
    +3.1, -2.4, +1.2, +3.4 %), and every counted block within 10 % plus 3 sigma of Cycles'
    2 x 4096 spp (its corner blocks' sigma is 18-21 %: measured there -8.1 / -12.1 %; the
    top blocks, sigma 4.2 / 5.8 %, +-3.8 %). About a minute on the shared cores."""
    passes = media.render_photon_map(mesh_media.SCENES["smoke_glass"](), samples=1024)
    reference = mesh_media.load_reference("smoke_glass")
    f = _figures("smoke_glass", passes)
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]
    cycles_sigma = ref.relative_block_sigma(reference)  # black blocks: not counted (NaN)
    assert np.all(np.nan_to_num(np.abs(f["blocks"]) - 3.0 * cycles_sigma) < 0.10), f["blocks"]
