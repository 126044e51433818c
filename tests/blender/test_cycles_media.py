"""Photon Map's World fog against Cycles in the same bpy process (cached references:
tests/blender/cycles_media_reference.py, the scenes and the command that re-renders them):
a fog lit by a spot light, and a glass sphere in that fog (the volumetric caustic), also in
a fog box under a wide light.
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

def _figures(name, passes):
    return media.figures(name, passes, media.load_reference(name))


SPOT_SETTINGS = dict(global_photons=400_000)
"""fog_spot's overrides of PHOTON_MAP_SETTINGS. With 16 volume light samples (what the
automatic Volume Light Samples picks in this homogeneous fog since 2026-12-05) the cone
apex's Volume Direct noise is gone, and what is left in the worst 8 x 8 block is the
volume photons' noise at 100k global photons: worst block 12.5 / 10.0 % (seeds 1 / 2;
seed 1's bottom-left floor block); at 400k 4.6 / 6.0 / 5.2 / 6.3 % (seeds 1-4; channel
means -0.62 / -0.40 / -0.81 / -0.22 %), a 6 s render. Before, with one volume light
sample, 12.5 / 8.4 % at 100k and still 10.0 / 8.7 % at 64 spp and 1M global photons (the
apex pair, docs/volumes.md)."""


@pytest.fixture(scope="module")
def fog_spot():
    return media.render_photon_map(media.SCENES["fog_spot"](), **SPOT_SETTINGS)


def test_spot_lit_fog_channel_means_match_cycles(fog_spot):
    f = _figures("fog_spot", fog_spot)
    combined = fog_spot["Combined"][..., :3].mean()
    assert fog_spot["Volume Direct"][..., :3].mean() > 0.1 * combined
    assert fog_spot["Volume Indirect"][..., :3].mean() > 0.1 * combined
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]  # measured -0.62 / -0.40 % (seeds 1/2)


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
    matched = media.render_photon_map(scene, **SPOT_SETTINGS)["Combined"][..., :3]
    # 12 x 12 blocks within 12 %: the volume photons' noise moves the dim outer blocks (their
    # paths change where photons meet the sphere); measured at 100k global photons and one
    # volume light sample -0.65 % in the means, worst block -8.4 %; at SPOT_SETTINGS with 16
    # volume light samples -0.19 %, worst block 3.0 % (2026-12-05).
    f = ref.compare(matched, plain, block=12)
    print(f"\nIOR 1 sphere / no sphere - 1: channel means {np.round(100 * f['channel'], 2)} %, "
          f"worst 12 x 12 block {100 * f['worst_block']:.1f} %")
    assert np.all(np.abs(f["channel"]) < 0.02), f["channel"]
    assert f["worst_block"] < 0.12, f["blocks"]


CAUSTIC_1M_SETTINGS = dict(samples=64, caustic_photons=1_000_000)
"""fog_caustic_1m's overrides of PHOTON_MAP_SETTINGS. At 16 samples the few pixels that see
the 1 m light through the glass's rim (a bright, small target) decide the image mean: seed
1 read +4.75 % against Cycles, +2.6 % of it in the sphere's 16 pixels (seeds 1-4 summed
there 2.24, 1.04, 0.73, 0.71 against Cycles' 0.58; Photon Map at 1024 samples 0.56). At
100k caustic photons only ~130 are stored (gather radius 2.8 m) and the floor's caustic
reads +0.65 % of the image high; 1M (1,358 stored, radius 0.87 m) and 4M agree to 0.02 %.
docs/volumes.md, 'Where the +4.75 % was'."""


@pytest.fixture(scope="module")
def fog_caustic_1m():
    """Cycles is no reference at the tests' 0.1 m light (its shadow rays stop at glass, so it
    finds light -> glass -> fog only by phase-sampled rays through the sphere that hit the
    light; an index-matched sphere, which must change nothing, darkens its image by 13 % at
    0.1 m, 9 % at 0.4 m, 1.26 % at 1 m, 8 x 1024 spp), so these tests render fog_caustic_1m
    (1 m light; 8 x 1024 spp reference)."""
    return media.render_photon_map(media.SCENES["fog_caustic_1m"](), **CAUSTIC_1M_SETTINGS)


def test_volumetric_caustic_channel_means_match_cycles(fog_caustic_1m):
    f = _figures("fog_caustic_1m", fog_caustic_1m)
    assert fog_caustic_1m["Volume Indirect"].mean() > 0
    # measured +1.15 / +2.31 / +1.13 / +1.16 % (seeds 1-4); of it ~1 % is Cycles' own loss
    # with a sphere
    # (an IOR-1 sphere: -1.26 %, -0.80 % of it on the floor; Photon Map +0.16 %)
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]


@pytest.mark.xfail(reason="Cycles' reference loses light scattered inside the 1 m light's "
                          "sphere, which this scene's World fog fills (a fog box around "
                          "the sphere: MIS on reads 1.7 % below MIS off, a box under it: "
                          "equal; docs/volumes.md, \"Cycles' loss inside a wide light\"); "
                          "fog_box_caustic_1m is the block test with a sound reference. "
                          "Before that was known: worst 8 x 8 block 15.1 / 11.7 / 11.6 / 12.9 % (seeds "
                          "1-4); a block and its mirror differ by up to 15 % in one render "
                          "(the volume photons' noise at 100k global photons), and the top "
                          "row, symmetrised, reads +3 to +9 % high in both seeds 3 and 4 "
                          "(Cycles' sigma there 2 %): noise on a ~+5 % excess in the dim fog "
                          "above the cone that 1M global photons do not reduce (seed 3: own "
                          "mirror 2.6 %, top row still +3 to +6 %, means +2.03 %; "
                          "docs/volumes.md, 'The volumetric caustic's blocks over seeds'). "
                          "That excess is Cycles' reference: with the 1 m light's MIS "
                          "off (no light hits) Cycles' own fog_spot_1m Volume Indirect "
                          "is 2.7 % higher (top row +2.8 to +4.2 %; at 0.1 m the switch "
                          "changes nothing), and Photon Map's (1M global, 5 seeds) "
                          "matches that within 0.8 % (fog blocks within 1.5 %); the "
                          "caustic scene needs light hits, so there is no unbiased "
                          "reference yet (docs/volumes.md, \"fog_caustic_1m's top row: "
                          "which term\"). With 16 volume light samples (2026-12-05) and "
                          "400k global photons still 8.1 / 8.8 / 13.9 / 10.0 % (seeds 1-4; "
                          "the top row's blocks (0, 0), (1, 0))",
                   strict=False)
def test_volumetric_caustic_block_means_match_cycles(fog_caustic_1m):
    f = _figures("fog_caustic_1m", fog_caustic_1m)
    assert f["worst_block"] < 0.10, f["blocks"]


BOX_CAUSTIC_SETTINGS = dict(CAUSTIC_1M_SETTINGS, global_photons=2_000_000)
"""fog_box_caustic_1m's overrides of PHOTON_MAP_SETTINGS, a 16 s render. The dim top
corners' blocks carry the volume photons' noise: worst block at 400k global photons 8.8 /
6.2 / 6.4 / 13.3 % (seeds 1-4; seed 4's at 256 spp still 12.9 %: not the camera's), at 1M
8.6 / 3.7 / 4.4 / 6.2 / 5.6 % (seeds 1-5), at 2M 4.3 / 5.3 % (seeds 1, 4; the render against
its own mirror 2.9 / 2.0 %); channel means within 0.3 % at every count (2026-12-06)."""


@pytest.fixture(scope="module")
def fog_box_caustic():
    """The volumetric caustic in a fog box under the 1 m light, whose sphere holds no fog:
    Cycles' reference loses nothing there (its light's MIS on and off agree within 0.03 %
    in Volume Indirect; with the box grown around the light's sphere MIS on reads 1.7 %
    low), so the blocks have a reference."""
    return media.render_photon_map(media.SCENES["fog_box_caustic_1m"](), **BOX_CAUSTIC_SETTINGS)


def test_volumetric_caustic_in_a_fog_box_matches_cycles(fog_box_caustic):
    """Channel means within 3 % and 8 x 8 blocks within 10 %: the top row sees the fog
    just under the box's lit top face at a grazing angle, where the beam estimate's discs
    reach out of the medium (-10 to -31 % before its boundary correction, photons/beam.py)."""
    f = _figures("fog_box_caustic_1m", fog_box_caustic)
    assert fog_box_caustic["Volume Indirect"].mean() > 0
    assert np.all(np.abs(f["channel"]) < 0.03), f["channel"]
    assert f["worst_block"] < 0.10, f["blocks"]
