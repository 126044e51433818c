"""Volume shaders through the exporter (photon_engine/export_volumes.py): the World's
Volume becomes the scene's medium with Cycles' coefficients; a mesh material's Volume
fills the object, bounded by its faces (a volume-only material's faces are no surface); an
open mesh is reported by name; a fog render has the Volume Direct / Indirect passes, Combined their exact sum
with the others."""

import bpy
import numpy as np
import pytest

from tests.blender import scenes
from tests.blender.test_export import export
from tests.blender.test_export_warnings import lit as _lit

pytestmark = [pytest.mark.blender, pytest.mark.api]


def _world_volume(name, idname, **inputs):
    """A World whose active output's Volume is one ``idname`` node with ``inputs``."""
    scene = bpy.context.scene
    world = bpy.data.worlds.new(name)
    scene.world = world
    tree = scenes.ensure_node_tree(world)
    node = tree.nodes.new(idname)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    output = next(n for n in tree.nodes if n.type == 'OUTPUT_WORLD')
    tree.links.new(node.outputs[0], output.inputs["Volume"])
    return world, tree, node, output


def test_principled_volume_on_the_world_has_cycles_coefficients():
    _lit()
    _world_volume("Fog", 'ShaderNodeVolumePrincipled', **{
        "Color": (0.8, 0.5, 0.2, 1.0), "Density": 0.3, "Anisotropy": 0.4,
        "Absorption Color": (0.25, 0.0, 1.0, 1.0), "Emission Strength": 2.0,
        "Emission Color": (1.0, 0.5, 0.0, 1.0)})
    result = export()
    assert result.warnings == []
    media = result.scene.media
    assert media.count == 1 and media.world == 0 and media.names == ("Fog",)
    c, rho, a = np.array([0.8, 0.5, 0.2]), 0.3, np.sqrt([0.25, 0.0, 1.0])
    np.testing.assert_allclose(media.sigma_s[0], c * rho, rtol=1e-6)
    np.testing.assert_allclose(media.sigma_a[0], (1 - c) * (1 - a) * rho, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(media.anisotropy[0], 0.4, rtol=1e-6)
    np.testing.assert_allclose(media.emission[0], [2.0, 1.0, 0.0], rtol=1e-6)


def test_absorption_plus_scatter_add_and_a_linked_density_is_named():
    _lit()
    world, tree, scatter, output = _world_volume("Haze", 'ShaderNodeVolumeScatter', **{
        "Color": (1.0, 0.5, 0.25, 1.0), "Density": 0.2, "Anisotropy": -0.3})
    absorb = tree.nodes.new('ShaderNodeVolumeAbsorption')
    absorb.inputs["Color"].default_value = (0.5, 1.0, 0.0, 1.0)
    absorb.inputs["Density"].default_value = 0.4
    add = tree.nodes.new('ShaderNodeAddShader')
    tree.links.new(scatter.outputs[0], add.inputs[0])
    tree.links.new(absorb.outputs[0], add.inputs[1])
    tree.links.new(add.outputs[0], output.inputs["Volume"])
    noise = tree.nodes.new('ShaderNodeTexNoise')
    tree.links.new(noise.outputs["Fac"], absorb.inputs["Density"])
    result = export()
    media = result.scene.media
    np.testing.assert_allclose(media.sigma_s[0], [0.2, 0.1, 0.05], rtol=1e-6)
    np.testing.assert_allclose(media.sigma_a[0], [0.2, 0.0, 0.4], rtol=1e-6)
    np.testing.assert_allclose(media.anisotropy[0], -0.3, rtol=1e-6)  # the only lobe
    assert result.warnings == [
        f"World 'Haze': input 'Density' of node '{absorb.name}' is linked (textured or "
        f"heterogeneous media are not supported yet); using its own value"]


def test_a_volume_inside_a_mesh_is_a_medium_bounded_by_its_faces():
    _lit()
    mat = scenes.diffuse_material("Smoky Glass")
    tree = mat.node_tree
    vol = tree.nodes.new('ShaderNodeVolumeScatter')
    vol.inputs["Density"].default_value = 2.0
    vol.inputs["Anisotropy"].default_value = 0.5
    out = next(n for n in tree.nodes if n.type == 'OUTPUT_MATERIAL')
    tree.links.new(vol.outputs[0], out.inputs["Volume"])
    scenes.add_sphere(material=mat, location=(0, 0, 0.6), name="Ball", segments=16)
    result = export()
    assert result.warnings == []
    media, mesh = result.scene.media, result.scene.mesh
    assert media.count == 1 and media.names == ("Smoky Glass in Ball",)
    ball = mesh.object_names.index("Ball")
    assert media.bounds[0] == ball and media.world == -1
    np.testing.assert_allclose(media.sigma_s[0], [1.6, 1.6, 1.6], rtol=1e-6)  # 0.8 x 2
    np.testing.assert_allclose(media.anisotropy[0], 0.5, rtol=1e-6)
    # The boundary is the ball's surface triangles, wound outward
    own = mesh.triangle_vertices()[mesh.object_index == ball]
    np.testing.assert_array_equal(media.boundary, own)
    centre = media.boundary.mean(axis=1) - (np.array([0, 0, 0.6]) - mesh.origin)
    normal = np.cross(media.boundary[:, 1] - media.boundary[:, 0],
                      media.boundary[:, 2] - media.boundary[:, 0])
    assert np.all(np.einsum("ij,ij->i", normal, centre) > 0)
    assert "Smoky Glass" in result.scene.materials.names


def test_a_volume_only_cube_is_a_medium_without_surface_and_an_open_one_is_named():
    _lit()
    fog = bpy.data.materials.new("Fog")
    tree = scenes.ensure_node_tree(fog)
    for n in list(tree.nodes):
        if n.type != 'OUTPUT_MATERIAL':
            tree.nodes.remove(n)
    absorb = tree.nodes.new('ShaderNodeVolumeAbsorption')
    absorb.inputs["Density"].default_value = 0.5
    out = next(n for n in tree.nodes if n.type == 'OUTPUT_MATERIAL')
    tree.links.new(absorb.outputs[0], out.inputs["Volume"])
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 1.0))
    cube = bpy.context.active_object
    cube.name = "Box"
    cube.data.materials.append(fog)
    scenes.add_plane(size=1.0, location=(0, 0, 3), material=fog, name="Sheet")
    result = export()
    mesh, media = result.scene.mesh, result.scene.media
    assert media.names == ("Fog in Box", "Fog in Sheet")
    counts = np.bincount(media.boundary_medium)
    assert list(counts) == [12, 2]
    for name in ("Box", "Sheet"):  # no surface: no triangle of theirs is rendered
        assert not np.any(mesh.object_index == mesh.object_names.index(name))
    assert result.warnings == [
        "Medium 'Fog in Sheet': the faces of material \"Fog\" on object 'Sheet' are not a "
        "closed mesh (4 open edges); a ray that crosses it once stays in the medium for the "
        "rest of its way, as in Cycles"]


def test_a_fog_render_has_the_volume_passes_and_combined_is_their_sum():
    scene = scenes.plane_and_point_light(width=8, height=6)
    _world_volume("Fog", 'ShaderNodeVolumeScatter', **{"Density": 0.2})
    scenes.use_photon_map(scene, samples=2, global_photons=2000, caustic_photons=0,
                          final_gather_rays=4)
    passes = scenes.render_passes(scene)
    assert {"Volume Direct", "Volume Indirect"} <= set(passes)
    assert passes["Volume Direct"][..., :3].mean() > 0
    total = sum(passes[name][..., :3].astype(np.float64) for name in
                ("Emission", "Environment", "Direct", "Specular", "Caustics", "Indirect",
                 "Volume Direct", "Volume Indirect") if name in passes)
    np.testing.assert_allclose(passes["Combined"][..., :3], total, rtol=1e-5, atol=1e-7)


def test_a_varying_density_under_a_mix_shader_is_a_heterogeneous_row_beside_the_rest():
    """Mix Shader (Fac 0.25) of a Principled Volume whose Density a Noise drives and a
    Volume Absorption: the Principled's coefficients at density 1 x 0.75 with the density
    program, and the absorption x 0.25 as a homogeneous row in the same object (overlapping
    media add, as in Cycles' volume stack); nothing reported."""
    _lit()
    mat = bpy.data.materials.new("Mixed Smoke")
    tree = scenes.ensure_node_tree(mat)
    for node in list(tree.nodes):
        if node.type != 'OUTPUT_MATERIAL':
            tree.nodes.remove(node)
    out = next(n for n in tree.nodes if n.type == 'OUTPUT_MATERIAL')
    smoke = tree.nodes.new('ShaderNodeVolumePrincipled')
    smoke.inputs["Color"].default_value = (0.6, 0.6, 0.6, 1.0)
    smoke.inputs["Anisotropy"].default_value = 0.3
    noise = tree.nodes.new('ShaderNodeTexNoise')
    tree.links.new(noise.outputs["Fac"], smoke.inputs["Density"])
    absorb = tree.nodes.new('ShaderNodeVolumeAbsorption')
    absorb.inputs["Color"].default_value = (0.5, 0.5, 0.0, 1.0)
    absorb.inputs["Density"].default_value = 0.8
    mix = tree.nodes.new('ShaderNodeMixShader')
    mix.inputs["Fac"].default_value = 0.25
    tree.links.new(smoke.outputs[0], mix.inputs[1])
    tree.links.new(absorb.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Volume"])
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.6))
    bpy.context.active_object.name = "Box"
    bpy.context.active_object.data.materials.append(mat)
    result = export()
    assert result.warnings == []
    media = result.scene.media
    assert media.names == ("Mixed Smoke in Box", "Mixed Smoke in Box (homogeneous part)")
    assert media.density_texture.tolist() == [0, -1] and len(media.programs) == 1
    assert media.bounds[0] == media.bounds[1]
    np.testing.assert_array_equal(media.boundary[media.boundary_medium == 0],
                                  media.boundary[media.boundary_medium == 1])
    np.testing.assert_allclose(media.sigma_s[0], [0.45, 0.45, 0.45], rtol=1e-6)  # 0.6 x 0.75
    np.testing.assert_allclose(media.sigma_a[0], [0.3, 0.3, 0.3], rtol=1e-6)     # 0.4 x 0.75
    np.testing.assert_allclose(media.anisotropy[0], 0.3, rtol=1e-6)
    np.testing.assert_allclose(media.sigma_a[1], [0.1, 0.1, 0.2], rtol=1e-6)     # x 0.8 x 0.25
    np.testing.assert_allclose(media.sigma_s[1], 0.0)


def test_a_varying_scatter_colour_under_a_mix_shader_is_a_row_of_weights_with_a_colour_program():
    """Mix Shader (Fac 0.25) of a Volume Scatter whose Color a Noise's Color drives (Density
    2) and a Volume Absorption: the scatter's row holds the weights (sigma_s 0.75, sigma_a 0:
    the program's Color, density and weight give sigma_s = 0.75 C 2 per point) with a
    seven-output program whose density is the constant 2; the absorption x 0.25 a
    homogeneous row; a Volume Absorption's linked Color is still reported."""
    from core.shading import program as pg

    _lit()
    mat = bpy.data.materials.new("Tinted Smoke")
    tree = scenes.ensure_node_tree(mat)
    for node in list(tree.nodes):
        if node.type != 'OUTPUT_MATERIAL':
            tree.nodes.remove(node)
    out = next(n for n in tree.nodes if n.type == 'OUTPUT_MATERIAL')
    smoke = tree.nodes.new('ShaderNodeVolumeScatter')
    smoke.inputs["Density"].default_value = 2.0
    noise = tree.nodes.new('ShaderNodeTexNoise')
    tree.links.new(noise.outputs["Color"], smoke.inputs["Color"])
    absorb = tree.nodes.new('ShaderNodeVolumeAbsorption')
    absorb.inputs["Color"].default_value = (0.5, 0.5, 0.0, 1.0)
    absorb.inputs["Density"].default_value = 0.8
    mix = tree.nodes.new('ShaderNodeMixShader')
    mix.inputs["Fac"].default_value = 0.25
    tree.links.new(smoke.outputs[0], mix.inputs[1])
    tree.links.new(absorb.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Volume"])
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.6))
    bpy.context.active_object.name = "Box"
    bpy.context.active_object.data.materials.append(mat)
    result = export()
    assert result.warnings == []
    media = result.scene.media
    assert media.names == ("Tinted Smoke in Box", "Tinted Smoke in Box (homogeneous part)")
    assert media.density_texture.tolist() == [0, -1]
    np.testing.assert_allclose(media.sigma_s[0], 0.75, rtol=1e-6)
    np.testing.assert_allclose(media.sigma_a[0], 0.0)
    np.testing.assert_allclose(media.sigma_a[1], [0.1, 0.1, 0.2], rtol=1e-6)
    (prog,) = media.programs
    assert prog.outputs[:, 3].tolist() == list(range(7))
    assert set(prog.outputs[:, 1].tolist()) == {pg.TARGET_DENSITY}
    assert prog.constants[prog.outputs[0, 0]] == 2.0  # the constant density's register
    # A Volume Absorption's Color still varies only as its own value
    tree.links.new(noise.outputs["Color"], absorb.inputs["Color"])
    assert any("input 'Color' of node" in w for w in export().warnings)
