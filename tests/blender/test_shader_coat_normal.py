"""The Principled BSDF's Coat Normal through Blender (Cycles: the coat closure's own N): a
plane under a sun seen straight down, a dark base with a strong glossy coat whose Coat
Normal is a Normal Map of a Checker of two tilted normals (the plane of
test_shader_normals.py) or a Bump of a Noise Texture. The coat's highlight then follows
the coat normal square by square (the half vector is 15 degrees from the vertical: one
square's coat normal 5 degrees from it, the other's 38), while the base keeps the flat
normal; each square (or block) matches Cycles rendered in this bpy process (direct light
only: one plane, no world)."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import scenes  # noqa: E402
from tests.blender.export_probe import export  # noqa: E402
from tests.blender.test_shader_normals import (  # noqa: E402
    render_cycles, render_photon_map, square_interiors, sun_plane, tilted_checker_normal_map)

pytestmark = [pytest.mark.blender, pytest.mark.api]

BASE = 0.05
COAT_ROUGHNESS = 0.2


def coat_material(coat_normal="NORMAL_MAP"):
    """Principled: base BASE grey (roughness 0.5, flat normal), coat weight 1 of roughness
    COAT_ROUGHNESS whose Coat Normal is a tangent-space Normal Map of the tilted-normal
    Checker ("NORMAL_MAP"), a Bump of a Noise Texture ("BUMP") or unlinked (None); or
    unlinked with that Bump into the Principled's Normal input instead ("BUMPED_BASE")."""
    mat = bpy.data.materials.new(f"Coat {coat_normal}")
    tree = scenes.ensure_node_tree(mat)
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (BASE, BASE, BASE, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.5
    bsdf.inputs["Coat Weight"].default_value = 1.0
    bsdf.inputs["Coat Roughness"].default_value = COAT_ROUGHNESS
    if coat_normal == "NORMAL_MAP":
        nm = tilted_checker_normal_map(tree)
        tree.links.new(nm.outputs["Normal"], bsdf.inputs["Coat Normal"])
    elif coat_normal in ("BUMP", "BUMPED_BASE"):
        tc = tree.nodes.new("ShaderNodeTexCoord")
        noise = tree.nodes.new("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 1.5
        noise.inputs["Detail"].default_value = 1.0
        bump = tree.nodes.new("ShaderNodeBump")
        bump.inputs["Distance"].default_value = 0.3
        tree.links.new(tc.outputs["Object"], noise.inputs["Vector"])
        tree.links.new(noise.outputs["Fac"], bump.inputs["Height"])
        tree.links.new(bump.outputs["Normal"],
                       bsdf.inputs["Coat Normal" if coat_normal == "BUMP" else "Normal"])
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def test_a_normal_mapped_coat_normal_moves_the_coat_highlight_as_cycles():
    scene = sun_plane(coat_material)
    exported = export(scene)
    assert not [w for w in exported.warnings if "Normal" in w], exported.warnings
    ours = square_interiors(render_photon_map(scene))
    cycles = square_interiors(render_cycles(scene))
    rel = np.abs(ours - cycles) / cycles
    print(f"\ncoat normal map: squares ours "
          f"{sorted({round(float(v), 4) for v in ours[..., 0].ravel()})}"
          f", Cycles {sorted({round(float(v), 4) for v in cycles[..., 0].ravel()})}; worst "
          f"{100 * rel.max():.3f} %")
    # the highlight follows the coat normal: the two kinds of square differ 3.6 times
    assert ours[..., 0].max() > 3.0 * ours[..., 0].min()
    assert rel.max() < 0.03


def blocks_against_cycles(make_material, label):
    """The sun plane of make_material at 64 samples a pixel, ours and Cycles', by 8 x 8
    pixel blocks: (Cycles' blocks (4, 4, 3), our relative error there (4, 4, 3), (our
    image mean, Cycles')), printed under label."""
    scene = sun_plane(make_material)
    exported = export(scene)
    assert not [w for w in exported.warnings if "Normal" in w], exported.warnings
    ours = render_photon_map(scene, 64)
    cycles = render_cycles(scene, 64)
    blocks = lambda im: im.reshape(4, 8, 4, 8, 3).mean(axis=(1, 3))  # noqa: E731
    b_ours, b_cycles = blocks(ours), blocks(cycles)
    rel = np.abs(b_ours - b_cycles) / b_cycles
    print(f"\n{label}: 8 x 8 px blocks vs Cycles worst {100 * rel.max():.2f} %, median "
          f"{100 * np.median(rel):.2f} %; means ours {ours.mean():.5f}, Cycles "
          f"{cycles.mean():.5f}; blocks span {b_cycles.min():.4f}..{b_cycles.max():.4f}")
    return b_cycles, rel, (ours.mean(), cycles.mean())


def test_a_bumped_coat_normal_matches_cycles_block_by_block():
    """The coat's highlight varies within a pixel here: 64 samples a pixel on both
    sides, 8 x 8 pixel blocks. Blender before 4.5 has no Filter Width input and reads the
    height a whole ray differential away up to 4.3 (compat.BUMP_FILTER_WIDTH): with 0.1
    under bpy 4.2.23 the worst block was 41.5 % off (means ours 0.13539, Cycles 0.12708)."""
    b_cycles, rel, _ = blocks_against_cycles(lambda: coat_material("BUMP"), "bumped coat")
    assert b_cycles.max() > 2.0 * b_cycles.min()  # the bumps show in the coat
    assert rel.max() < 0.05


def test_an_unlinked_coat_normal_under_a_bumped_normal_keeps_the_smooth_normal_as_cycles():
    """Issue 14: the Bump into the Principled's Normal input, Coat Normal unlinked. Cycles
    links an unlinked Coat Normal to the geometry's normal (sd->N), which the Bump does not
    change: the coat's highlight stays flat while the base follows the bumps. Shading the
    coat about the bumped normal, as before the fix (bpy 5.2.3, 64 samples): the worst
    block 238 % off, median 54 %, means ours 0.13808 against Cycles' 0.08080; with it 0.68 %,
    0.18 %, 0.08081 / 0.08080."""
    mat = lambda: coat_material("BUMPED_BASE")  # noqa: E731
    _, rel, means = blocks_against_cycles(mat, "bumped base, unlinked coat normal")
    assert rel.max() < 0.05
    assert abs(means[0] / means[1] - 1.0) < 0.02
