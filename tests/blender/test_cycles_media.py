"""Photon Map's World fog against Cycles in the same bpy process (cached references:
tests/blender/cycles_media_reference.py, the scenes and the command that re-renders them):
a fog lit by a spot light, and a glass sphere in that fog (the volumetric caustic).
Per-channel image means within 3 %, 8 x 8 block means within 10 % (blocks darker than 2 %
of the image mean are not counted)."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_media_reference as media  # noqa: E402
from tests.blender import cycles_reference as ref  # noqa: E402

# About 3 minutes on the shared 2 cores; the small version of the same path (a fog render
# through Blender, its passes summed) is tests/blender/test_media.py in the default suite.
pytestmark = [pytest.mark.blender, pytest.mark.slow]

def _render(name):
    return media.render_photon_map(media.SCENES[name]())


def _figures(name, passes):
    return media.figures(name, passes, media.load_reference(name))


@pytest.fixture(scope="module")
def fog_spot():
    return _render("fog_spot")


def test_spot_lit_fog_channel_means_match_cycles(fog_spot):
    f = _figures("fog_spot", fog_spot)
    combined = fog_spot["Combined"][..., :3].mean()
    assert fog_spot["Volume Direct"][..., :3].mean() > 0.1 * combined
    assert fog_spot["Volume Indirect"][..., :3].mean() > 0.1 * combined
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]  # measured -0.21 %


@pytest.mark.xfail(reason="measured: worst 8 x 8 block +12.5 % (median |block| 2.5 %; "
                          "against 32 x 2048 Cycles samples, 2 x 2048 gave +13.8 %); the "
                          "dim upper blocks are the volume photon map's noise (left-right "
                          "mirror blocks differ by 10 %), the dim side blocks +7 % its blur",
                   strict=False)
def test_spot_lit_fog_block_means_match_cycles(fog_spot):
    f = _figures("fog_spot", fog_spot)
    assert f["worst_block"] < 0.10, f["blocks"]


def test_an_index_matched_glass_sphere_changes_nothing_in_fog(fog_spot):
    """A glass sphere of IOR 1 neither reflects nor bends light, so the fog_caustic scene with
    it must render the fog_spot scene: the fog inside the sphere, the light through it into
    the fog and onto the floor, the camera's view through it (now the Specular pass)."""
    plain = fog_spot["Combined"][..., :3]
    scene = media.SCENES["fog_caustic"]()
    bpy.data.materials["Glass"].node_tree.nodes["Glass BSDF"].inputs["IOR"].default_value = 1.0
    matched = media.render_photon_map(scene)["Combined"][..., :3]
    # 12 x 12 blocks within 12 %: at 100k photons the volume photons' noise alone moves
    # the dim outer blocks by up to 10 % (their paths change where photons meet the sphere);
    # measured -0.65 % in the means, worst block -8.4 % (the outer ones; those below the
    # sphere, in its shadow cone and its light, within 2 %).
    f = ref.compare(matched, plain, block=12)
    print(f"\nIOR 1 sphere / no sphere - 1: channel means {np.round(100 * f['channel'], 2)} %, "
          f"worst 12 x 12 block {100 * f['worst_block']:.1f} %")
    assert np.all(np.abs(f["channel"]) < 0.02), f["channel"]
    assert f["worst_block"] < 0.12, f["blocks"]


@pytest.mark.xfail(reason="Cycles is no reference here (measured with the 32 x 2048 spp "
                          "reference: channel means +7.5 %): its shadow rays stop at glass, so "
                          "it finds light -> glass -> fog only by phase-sampled rays through "
                          "the sphere that hit the light, and an index-matched sphere (IOR 1), "
                          "which must change nothing, darkens its image by 13 % (0.1 m light, "
                          "8 x 2048 spp), 9 % (0.4 m, 4 x 1024 spp), 1.2 % (1 m, 2 x 512 spp). "
                          "So the test renders fog_caustic_1m (1 m light, where Cycles converges; "
                          "8 x 1024 spp reference): with the photons kept where their line "
                          "crosses the disk facing their first event, channel means +4.75 % "
                          "(+32.5 % before; fog_spot at 1 m +0.20 %, +28 % before), worst "
                          "block 18.8 % in the rows of the sphere, where the Specular pass "
                          "(the view through the glass) adds 3.5 % of the image over an IOR-1 "
                          "sphere (docs/volumes.md, 'The volumetric caustic against Cycles')",
                   strict=False)
def test_volumetric_caustic_matches_cycles():
    passes = _render("fog_caustic_1m")
    f = _figures("fog_caustic_1m", passes)
    assert passes["Volume Indirect"].mean() > 0
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]
    assert f["worst_block"] < 0.10, f["blocks"]
