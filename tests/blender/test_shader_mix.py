"""A Mix Shader whose Factor is a node graph (issue 14, per-hit closure weights): a plane
under a sun made of Mix(Diffuse, Emission, Factor = Checker of the UV). Each checker square
is either the Lambert plane (E cos(theta) / pi) or the emission colour, analytic values
written out here, and matches Cycles rendered in this bpy process (direct light only: one
plane, no world). Without per-hit weights every square would be the 50 / 50 mixture of the
socket's own factor. The sphere with Mix(Diffuse, Glossy, Factor = Layer Weight Facing) is
a scene of test_cycles_materials.py (``mix_layer_weight``)."""

import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import scenes  # noqa: E402
from tests.blender.export_probe import export  # noqa: E402
from tests.blender.test_shader_normals import ALBEDO, LIGHT, SUN, render_cycles, \
    render_photon_map, square_interiors, sun_plane  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]

EMIT = (0.2, 0.5, 1.0)


def checker_mix_material():
    """Mix Shader: Diffuse (ALBEDO, Lambert) and Emission (EMIT, strength 1), Factor = the
    Checker Texture's Fac of the UV (scale 4: 4 x 4 squares over the view)."""
    mat = bpy.data.materials.new("Checker mix")
    tree = scenes.ensure_node_tree(mat)
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (ALBEDO, ALBEDO, ALBEDO, 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (*EMIT, 1.0)
    emission.inputs["Strength"].default_value = 1.0
    checker = tree.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 4.0
    uv = tree.nodes.new("ShaderNodeTexCoord")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(uv.outputs["UV"], checker.inputs["Vector"])
    tree.links.new(checker.outputs["Fac"], mix.inputs[0])
    tree.links.new(diffuse.outputs[0], mix.inputs[1])
    tree.links.new(emission.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def block_means(image, block=8):
    h, w, _ = image.shape
    return image.reshape(h // block, block, w // block, block, 3).mean(axis=(1, 3))


def test_a_checker_mix_of_diffuse_and_emission_matches_the_analytic_squares_and_cycles():
    scene = sun_plane(checker_mix_material)
    exported = export(scene)
    assert not [w for w in exported.warnings if "Mix" in w or "Checker" in w], \
        exported.warnings
    ours_image = render_photon_map(scene)
    cycles_image = render_cycles(scene)
    ours, cycles = square_interiors(ours_image), square_interiors(cycles_image)
    lit = ALBEDO * SUN * float(LIGHT[2]) / math.pi
    # each square is the lit Lambert plane or the emission, half of the squares each
    diffuse = np.all(np.abs(ours - lit) < 1e-3 * lit, axis=-1)
    emitting = np.all(np.abs(ours - np.asarray(EMIT)) < 1e-3, axis=-1)
    assert np.all(diffuse | emitting) and diffuse.sum() == 8, (ours[..., 0], lit)
    rel = np.abs(ours - cycles) / cycles
    a, b = block_means(ours_image), block_means(cycles_image)
    blocks = np.abs(a - b) / b
    means = ours_image.reshape(-1, 3).mean(0) / cycles_image.reshape(-1, 3).mean(0) - 1
    print(f"\nchecker mix: channel means ours/Cycles - 1 = {np.round(100 * means, 2)} %, "
          f"worst 8 x 8 block {100 * blocks.max():.2f} %, worst square interior "
          f"{100 * rel.max():.2f} %")
    assert rel.max() < 0.03
    assert np.all(np.abs(means) < 0.01)


def test_nested_linked_factors_give_each_closure_the_product_along_its_path():
    """Mix(Factor = U) of [Add(Mix(Factor = V) of [Diffuse, Glossy], Sheen), Emission]:
    per hit Diffuse (1 - V)(1 - U), Glossy V (1 - U), Sheen (1 - U) (one TARGET_WEIGHT
    output per closure, the constant weights 1) and the emission U x 2 (TARGET_EMISSION),
    the program run by the core interpreter at known UVs."""
    from photon_map.core.shading import program as pg
    from photon_map.core.shading.inputs import ShadingInputs
    from photon_map.core.shading.interpreter import closure_params, evaluate

    scenes.reset()
    scenes.set_resolution(16, 16)
    scenes.add_camera(location=(0.0, -6.0, 2.0))
    mat = bpy.data.materials.new("Nested")
    tree = scenes.ensure_node_tree(mat)
    tree.nodes.clear()
    n = tree.nodes.new
    out = n("ShaderNodeOutputMaterial")
    diffuse, glossy, sheen = n("ShaderNodeBsdfDiffuse"), n("ShaderNodeBsdfGlossy"), \
        n("ShaderNodeBsdfSheen")
    emit = n("ShaderNodeEmission")
    emit.inputs["Strength"].default_value = 2.0
    inner, outer, add = n("ShaderNodeMixShader"), n("ShaderNodeMixShader"), \
        n("ShaderNodeAddShader")
    coords, sep = n("ShaderNodeTexCoord"), n("ShaderNodeSeparateXYZ")
    link = tree.links.new
    link(coords.outputs["UV"], sep.inputs[0])
    link(sep.outputs[1], inner.inputs[0])
    link(sep.outputs[0], outer.inputs[0])
    link(diffuse.outputs[0], inner.inputs[1])
    link(glossy.outputs[0], inner.inputs[2])
    link(inner.outputs[0], add.inputs[0])
    link(sheen.outputs[0], add.inputs[1])
    link(add.outputs[0], outer.inputs[1])
    link(emit.outputs[0], outer.inputs[2])
    link(outer.outputs[0], out.inputs["Surface"])
    scenes.add_plane(size=1.0, material=mat, name="P0")
    result = export()
    assert not [w for w in result.warnings if "Mix" in w], result.warnings
    mats = result.scene.materials
    prog = mats.programs[0]
    table = mats.closure_table()
    assert table["count"][0] == 3
    np.testing.assert_allclose(table["weight"][:3], 1.0)  # the factors are the program's
    weights = prog.outputs[prog.outputs[:, 1] == pg.TARGET_WEIGHT]
    assert sorted(weights[:, 2].tolist()) == [0, 1, 2]
    k = 5
    u, v = np.linspace(0.05, 0.95, k), np.linspace(0.9, 0.1, k)
    ins = ShadingInputs.build(np.zeros((k, 3)), np.tile([0.0, 0.0, 1.0], (k, 1)),
                              uv=np.stack([u, v], axis=1)[None].astype(np.float32))
    params = np.asarray(table["params"][:3], np.float32)
    got = closure_params(prog, ins, params)["weight"]
    want = np.stack([(1 - v) * (1 - u), v * (1 - u), 1 - u], axis=1)
    np.testing.assert_allclose(got, want, atol=1e-6)
    cols = np.flatnonzero(prog.outputs[:, 1] == pg.TARGET_EMISSION)
    np.testing.assert_allclose(evaluate(prog, ins)[:, cols], 2.0 * u[:, None] * np.ones(3),
                               atol=1e-6)
