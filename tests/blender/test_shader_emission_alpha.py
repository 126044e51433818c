"""Textured emission and programmed cut-outs through the whole engine (export, camera
pass, shadow rays) against Cycles in the same bpy process: an Emission plane whose Color
and Strength come from Checker textures and a Principled plane whose Emission Color is
an image (per pixel: the checker and image edges lie on pixel borders, so every pixel is
uniform and neither render has noise); a leaf whose Principled Alpha is a checker casts
a patterned shadow on a floor under a sun (per pixel beside the leaf: both renders'
shadow rays take the transparency deterministically)."""

import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_reference as cr, scenes  # noqa: E402
from tests.blender.test_shader_nodes import link, node  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]

RES = 32


def _material(name):
    mat = bpy.data.materials.new(name)
    tree = scenes.ensure_node_tree(mat)
    tree.nodes.clear()
    out = node(tree, "ShaderNodeOutputMaterial")
    return mat, tree, out


def checker_emission():
    mat, tree, out = _material("CheckerLamp")
    em = node(tree, "ShaderNodeEmission")
    link(tree, em.outputs[0], out.inputs["Surface"])
    colour = node(tree, "ShaderNodeTexChecker")
    colour.inputs["Scale"].default_value = 4.0
    colour.inputs["Color1"].default_value = (0.9, 0.3, 0.1, 1.0)
    colour.inputs["Color2"].default_value = (0.1, 0.4, 0.8, 1.0)
    link(tree, colour.outputs["Color"], em.inputs["Color"])
    fac = node(tree, "ShaderNodeTexChecker")
    fac.inputs["Scale"].default_value = 2.0
    strength = node(tree, "ShaderNodeMath", operation='MULTIPLY_ADD')
    link(tree, fac.outputs["Fac"], strength.inputs[0])
    strength.inputs[1].default_value = 2.0
    strength.inputs[2].default_value = 0.5
    link(tree, strength.outputs[0], em.inputs["Strength"])
    return mat


def image_emission():
    mat, tree, out = _material("ImageLamp")
    bsdf = node(tree, "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    link(tree, bsdf.outputs[0], out.inputs["Surface"])
    rng = np.random.default_rng(3)
    img = bpy.data.images.new("Lamp4x4", 4, 4)
    img.colorspace_settings.name = "Non-Color"
    img.pixels.foreach_set(np.c_[rng.uniform(0.1, 1.0, (16, 3)), np.ones(16)]
                           .astype(np.float32).ravel())
    tex = node(tree, "ShaderNodeTexImage", interpolation='Closest')
    tex.image = img
    link(tree, tex.outputs["Color"], bsdf.inputs["Emission Color"])
    bsdf.inputs["Emission Strength"].default_value = 2.0
    return mat


def emission_scene(make_material):
    scene = scenes.reset()
    scenes.set_resolution(RES, RES)
    scenes.add_plane(size=2.0, material=make_material(), name="Lamp")
    scenes.add_camera(location=(0.0, 0.0, 3.0), look_at=(0.0, 0.0, 0.0), ortho_scale=2.0)
    return scene


@pytest.mark.parametrize("make", [checker_emission, image_emission], ids=["checker", "image"])
def test_textured_emission_seen_matches_cycles(make):
    scene = emission_scene(make)
    cycles = cr.render_cycles(scene, 4)
    ours = cr.render_photon_map(scene, 4)["Combined"][..., :3]
    err = (np.abs(ours - cycles) / np.maximum(cycles, 1e-3)).max(-1)
    # the texture's edges lie on every 8th pixel border: the pixels along them may get
    # a sample of the neighbouring square (Cycles' texture coordinates are float32)
    i = np.arange(RES) % 8
    inner = ((i != 0) & (i != 7))[:, None] & ((i != 0) & (i != 7))[None, :]
    print(make.__name__, "max relative error inside the squares", float(err[inner].max()),
          "pixels beyond 1e-3 on the edges", int((err[~inner] > 1e-3).sum()), "of",
          int((~inner).sum()), "channel means", ours.mean((0, 1)), cycles.mean((0, 1)))
    assert cycles.max() > 0.4
    # measured: the image plane exact (8e-8); the checker plane 0 on all but a few
    # pixels, whose error is 0.5 (one square's value for the other's; not understood yet)
    assert (err > 1e-3).mean() < 0.02 and np.percentile(err, 95) < 1e-3
    np.testing.assert_allclose(ours.mean((0, 1)), cycles.mean((0, 1)), rtol=0.01)


def checker_alpha(tree):
    """A Checker of opacity 0.8 / 0.2 (its colour's luminance): the leaf's default Alpha."""
    checker = node(tree, "ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 2.0
    checker.inputs["Color1"].default_value = (0.8, 0.8, 0.8, 1.0)
    checker.inputs["Color2"].default_value = (0.2, 0.2, 0.2, 1.0)
    return checker.outputs["Color"]


def leaf_scene(alpha=checker_alpha):
    """A 2 m leaf (Principled, no specular) at z = 1 over an 8 m grey floor, under a sun
    45 degrees from the vertical (its shadow at y in [1, 3]), seen from above by a 4 m
    orthographic camera; alpha(tree) -> the socket linked to the leaf's Alpha."""
    scene = scenes.reset()
    scenes.set_resolution(RES, RES)
    floor_mat, tree, out = _material("Floor")
    d = node(tree, "ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    link(tree, d.outputs[0], out.inputs["Surface"])
    scenes.add_plane(size=8.0, material=floor_mat, name="Floor")
    leaf_mat, tree, out = _material("Leaf")
    bsdf = node(tree, "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    link(tree, bsdf.outputs[0], out.inputs["Surface"])
    link(tree, alpha(tree), bsdf.inputs["Alpha"])
    scenes.add_plane(size=2.0, location=(0.0, 0.0, 1.0), material=leaf_mat, name="Leaf")
    sun = scenes.add_light('SUN', power=3.0, rotation=(math.radians(45.0), 0.0, 0.0))
    sun.data.angle = 0.0
    scenes.add_camera(location=(0.0, 0.0, 5.0), look_at=(0.0, 0.0, 0.0), ortho_scale=4.0)
    return scene


def test_checker_alpha_leaf_casts_its_pattern_matching_cycles():
    """Leaf at z = 1 over the floor, sun 45 degrees from the vertical: the shadow lies at
    y in [1, 3] beside the leaf's [-1, 1]; its checker of opacity 0.8 / 0.2 (the
    colour's luminance) gives floor pixels of 0.2 / 0.8 of the sun in both renders."""
    scene = leaf_scene()
    cycles = cr.render_cycles(scene, 4)
    ours = cr.render_photon_map(scene, 4)["Combined"][..., :3]
    c = (np.arange(RES) + 0.5) / RES * 4.0 - 2.0
    X, Y = np.meshgrid(c, -c)
    px = 4.0 / RES
    away = lambda a, edges: np.all([np.abs(a - e) > px for e in edges], axis=0)  # noqa: E731
    shadow = (Y > 1.0) & (Y < 2.0) & (np.abs(X) < 1.0) & away(X, (-1, 0, 1)) \
        & away(Y, (1, 2))  # the shadow beside the leaf, a pixel from every edge
    lit = (Y < -1.0 - px) & (np.abs(X) < 1.0)
    err = np.abs(ours - cycles) / np.maximum(cycles, 1e-3)
    print("shadow: ours", ours[shadow].mean(0), "cycles", cycles[shadow].mean(0),
          "max relative error", float(err[shadow | lit].max()))
    values = np.unique(np.round(cycles[shadow][:, 0] / cycles[lit][:, 0].mean(), 2))
    assert np.isclose(values, 0.2).any() and np.isclose(values, 0.8).any(), values
    # measured: 0 on most pixels; a few Cycles pixels at 0.76 of the sun where ours are
    # 0.8 (max 5.3 %); the shadow's mean 0.7 % brighter than Cycles'
    assert np.percentile(err[shadow | lit], 90) < 1e-3
    np.testing.assert_allclose(ours[shadow].mean(0), cycles[shadow].mean(0), rtol=0.02)


def test_textured_emissive_quad_lights_a_floor_like_cycles():
    """The checker Emission plane (1 m, 0.5 m over a white floor) as the only light: the
    floor around it (seen from above) by light sampling of the textured triangles, block
    means (8 x 8 pixels) and channel means against Cycles."""
    scene = scenes.reset()
    scenes.set_resolution(RES, RES)
    floor_mat, tree, out = _material("White")
    d = node(tree, "ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    link(tree, d.outputs[0], out.inputs["Surface"])
    scenes.add_plane(size=8.0, material=floor_mat, name="Floor")
    scenes.add_plane(size=1.0, location=(0.0, 0.0, 0.5), material=checker_emission(),
                     name="Lamp")
    scenes.add_camera(location=(0.0, 0.0, 5.0), look_at=(0.0, 0.0, 0.0), ortho_scale=4.0)
    cycles = cr.render_cycles(scene, 64)
    ours = cr.render_photon_map(scene, 64)["Combined"][..., :3]
    c = (np.arange(RES) + 0.5) / RES * 4.0 - 2.0
    X, Y = np.meshgrid(c, -c)
    floor = (np.abs(X) > 0.5) | (np.abs(Y) > 0.5)
    means = [(ours[..., k][floor].mean(), cycles[..., k][floor].mean()) for k in range(3)]
    blocks = []
    for r in range(0, RES, 8):
        for q in range(0, RES, 8):
            sel = floor[r:r + 8, q:q + 8]
            if sel.all():
                blocks.append((ours[r:r + 8, q:q + 8].mean(), cycles[r:r + 8, q:q + 8].mean()))
    blocks = np.array(blocks)
    worst = float(np.max(np.abs(blocks[:, 0] / blocks[:, 1] - 1)))
    print("channel means (ours, cycles)", means, "worst block", worst, "blocks", len(blocks))
    # Measured, R / G / B: +1.7 / +0.2 / -0.9 % with bpy 5.2.3, R +2.07 % with 4.2.23 (Cycles
    # live at 64 spp): whether R's excess is Cycles' noise or a bias of the textured-emitter
    # estimator is not settled (issue 14's note), hence 3 %, not 2 %.
    for o, cy in means:
        assert abs(o / cy - 1) < 0.03
    assert worst < 0.05
