"""Volume shaders through the exporter (photon_engine/export_volumes.py): the World's
Volume becomes the scene's medium with Cycles' coefficients; a mesh material's Volume
fills the object, bounded by its faces (a volume-only material's faces are no surface); an
open mesh is reported by name; a fog render has the Volume Direct / Indirect passes, Combined their exact sum
with the others."""

import bpy
import numpy as np
import pytest

from core.shading import program as pg
from tests.blender import scenes
from tests.blender.test_export import export
from tests.blender.test_export_warnings import lit as _lit
from tests.conftest import load_extension_package

photon_map = load_extension_package()
from photon_map.core.media.density import principled_volume_coefficients  # noqa: E402
from photon_map.core.shading.inputs import ShadingInputs  # noqa: E402
from photon_map.core.shading.interpreter import evaluate  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]


def test_principled_volume_on_the_world_has_cycles_coefficients():
    _lit()
    scenes.world_volume("Fog", 'ShaderNodeVolumePrincipled', **{
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
    world, tree, scatter, output = scenes.world_volume("Haze", 'ShaderNodeVolumeScatter', **{
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
    # The World holds one medium row, so a varying node beside other volume shaders
    # falls back to the inputs' own values: the reason, then the node and input
    assert result.warnings == [
        "World 'Haze': a volume node of varying density or colour beside other volume "
        "shaders (Add / Mix) is not supported on the World; using the inputs' own values",
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
    def absorb(tree):
        node = tree.nodes.new('ShaderNodeVolumeAbsorption')
        node.inputs["Density"].default_value = 0.5
        return node

    _lit()
    _volume_material("Fog", absorb)
    fog = bpy.data.materials["Fog"]
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
    scenes.world_volume("Fog", 'ShaderNodeVolumeScatter', **{"Density": 0.2})
    scenes.use_photon_map(scene, samples=2, global_photons=2000, caustic_photons=0,
                          final_gather_rays=4)
    passes = scenes.render_passes(scene)
    assert {"Volume Direct", "Volume Indirect"} <= set(passes)
    assert passes["Volume Direct"][..., :3].mean() > 0
    total = sum(passes[name][..., :3].astype(np.float64) for name in
                ("Emission", "Environment", "Direct", "Specular", "Caustics", "Indirect",
                 "Volume Direct", "Volume Indirect") if name in passes)
    np.testing.assert_allclose(passes["Combined"][..., :3], total, rtol=1e-5, atol=1e-7)


def _volume_material(name, make_volume):
    """A material ``name`` (no surface) on a 1 m cube 'Box' at (0, 0, 0.6) whose Volume is
    the node ``make_volume(tree)`` returns; returns the tree."""
    mat = bpy.data.materials.new(name)
    tree = scenes.ensure_node_tree(mat)
    for node in list(tree.nodes):
        if node.type != 'OUTPUT_MATERIAL':
            tree.nodes.remove(node)
    out = next(n for n in tree.nodes if n.type == 'OUTPUT_MATERIAL')
    tree.links.new(make_volume(tree).outputs[0], out.inputs["Volume"])
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.6))
    bpy.context.active_object.name = "Box"
    bpy.context.active_object.data.materials.append(mat)
    return tree


def _mixed_with_absorption(name, make_varying):
    """``_volume_material`` of a Mix Shader (Fac 0.25) of the volume node
    ``make_varying(tree)`` adds and a Volume Absorption (Color (0.5, 0.5, 0), Density 0.8);
    returns (tree, the absorption node)."""
    nodes = {}

    def mixed(tree):
        absorb = nodes["absorb"] = tree.nodes.new('ShaderNodeVolumeAbsorption')
        absorb.inputs["Color"].default_value = (0.5, 0.5, 0.0, 1.0)
        absorb.inputs["Density"].default_value = 0.8
        mix = tree.nodes.new('ShaderNodeMixShader')
        mix.inputs["Fac"].default_value = 0.25
        tree.links.new(make_varying(tree).outputs[0], mix.inputs[1])
        tree.links.new(absorb.outputs[0], mix.inputs[2])
        return mix
    tree = _volume_material(name, mixed)
    return tree, nodes["absorb"]


def test_a_varying_density_under_a_mix_shader_is_a_heterogeneous_row_beside_the_rest():
    """Mix Shader (Fac 0.25) of a Principled Volume whose Density a Noise drives and a
    Volume Absorption: the Principled's coefficients at density 1 x 0.75 with the density
    program, and the absorption x 0.25 as a homogeneous row in the same object (overlapping
    media add, as in Cycles' volume stack); nothing reported."""
    def smoke(tree):
        node = tree.nodes.new('ShaderNodeVolumePrincipled')
        node.inputs["Color"].default_value = (0.6, 0.6, 0.6, 1.0)
        node.inputs["Anisotropy"].default_value = 0.3
        noise = tree.nodes.new('ShaderNodeTexNoise')
        tree.links.new(noise.outputs["Fac"], node.inputs["Density"])
        return node

    _lit()
    _mixed_with_absorption("Mixed Smoke", smoke)
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
    noise = None

    def smoke(tree):
        nonlocal noise
        node = tree.nodes.new('ShaderNodeVolumeScatter')
        node.inputs["Density"].default_value = 2.0
        noise = tree.nodes.new('ShaderNodeTexNoise')
        tree.links.new(noise.outputs["Color"], node.inputs["Color"])
        return node

    _lit()
    tree, absorb = _mixed_with_absorption("Tinted Smoke", smoke)
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


def _program_at(result, row, points):
    """The density program of medium ``row`` of an export at world points (K, 3) (no
    object: Object and Generated are the position, as for the World) -> (K, outputs)."""
    media = result.scene.media
    prog = media.programs[int(media.density_texture[row])]
    up = np.tile([0.0, 0.0, 1.0], (points.shape[0], 1))
    return evaluate(prog, ShadingInputs.build(points, up), result.scene.program_images)


POINTS = np.array([[x, y, 0.5] for x in (-0.5, 0.1, 0.35, 0.8, 1.5) for y in (-0.3, 0.4)])


def test_a_world_fog_of_gradient_density_exports_its_program_and_renders():
    """A World Principled Volume (Color 0.8) whose Density is a Linear Gradient of the
    Object coordinates (the World's are the position, as Cycles without an object): one
    World medium with the coefficients at density 1 (sigma_s 0.8, sigma_a 0.2) and a
    program, not a constant: clamp(x, 0, 1) at world points; nothing reported. A render
    through it has Volume Direct light, finite and non-negative everywhere, and brighter
    fog on the x > 0 side (half the plane's width of the image on either side)."""
    scene = scenes.plane_and_point_light(width=16, height=12)
    _world, tree, node, _ = scenes.world_volume("Graded Fog", 'ShaderNodeVolumePrincipled',
                                                **{"Color": (0.8, 0.8, 0.8, 1.0)})
    coords = tree.nodes.new('ShaderNodeTexCoord')
    gradient = tree.nodes.new('ShaderNodeTexGradient')
    tree.links.new(coords.outputs["Object"], gradient.inputs["Vector"])
    tree.links.new(gradient.outputs["Fac"], node.inputs["Density"])
    result = export()
    assert result.warnings == []
    media = result.scene.media
    assert media.count == 1 and media.world == 0 and media.density_texture.tolist() == [0]
    np.testing.assert_allclose(media.sigma_s[0], 0.8, rtol=1e-6)
    np.testing.assert_allclose(media.sigma_a[0], 0.2, rtol=1e-6)
    (prog,) = media.programs
    assert prog.outputs.shape == (1, 4) and prog.outputs[0, 1] == pg.TARGET_DENSITY
    rho = _program_at(result, 0, POINTS)[:, 0]
    np.testing.assert_allclose(rho, np.clip(POINTS[:, 0], 0.0, 1.0), atol=1e-6)
    scenes.use_photon_map(scene, samples=2, global_photons=2000, caustic_photons=0,
                          final_gather_rays=4)
    passes = scenes.render_passes(scene)
    for name in ("Combined", "Volume Direct", "Volume Indirect"):
        assert np.all(np.isfinite(passes[name])) and passes[name].min() >= 0.0, name
    direct = passes["Volume Direct"][..., :3].mean(axis=(0, 2))  # per image column
    assert direct.mean() > 0
    half = direct.shape[0] // 2
    assert direct[half:].mean() > direct[:half].mean()  # the camera's +x: the denser side


def test_a_volume_absorptions_linked_color_varies_as_cycles_defines_it():
    """A Volume Absorption (Density 2) whose Color a Gradient's Color drives: a row of
    weights (sigma_a 1, sigma_s 0) and a seven-output program (density 2, Color = the
    gradient's colour, Absorption Color 0), so that sigma_a = max(1 - C, 0) rho per point
    (Cycles' svm_closure.h) through principled_volume_coefficients; nothing reported."""
    def ink(tree):
        absorb = tree.nodes.new('ShaderNodeVolumeAbsorption')
        absorb.inputs["Density"].default_value = 2.0
        coords = tree.nodes.new('ShaderNodeTexCoord')
        gradient = tree.nodes.new('ShaderNodeTexGradient')
        tree.links.new(coords.outputs["Object"], gradient.inputs["Vector"])
        tree.links.new(gradient.outputs["Color"], absorb.inputs["Color"])
        return absorb

    _lit()
    _volume_material("Tinted Ink", ink)
    result = export()
    assert result.warnings == []
    media = result.scene.media
    assert media.names == ("Tinted Ink in Box",) and media.density_texture.tolist() == [0]
    np.testing.assert_allclose(media.sigma_a[0], 1.0)
    np.testing.assert_allclose(media.sigma_s[0], 0.0)
    v = _program_at(result, 0, POINTS)
    assert v.shape == (POINTS.shape[0], 7)
    colour = np.clip(POINTS[:, 0], 0.0, 1.0)
    np.testing.assert_allclose(v[:, 0], 2.0)
    np.testing.assert_allclose(v[:, 1:4], np.repeat(colour[:, None], 3, 1), atol=1e-6)
    np.testing.assert_allclose(v[:, 4:7], 0.0)
    sigma_a, sigma_s = principled_volume_coefficients(v[:, 0], v[:, 1:4], v[:, 4:7])
    np.testing.assert_allclose(sigma_a * media.sigma_a[0],
                               np.repeat(((1 - colour) * 2.0)[:, None], 3, 1), atol=1e-6)
    np.testing.assert_allclose(sigma_s * media.sigma_s[0], 0.0)


def _scatter(tree, density=None):
    """A Volume Scatter (Color (0.9, 0.6, 0.3), Anisotropy 0.2) of Density ``density`` (a
    float or an output socket), a Noise's Fac when None."""
    node = tree.nodes.new('ShaderNodeVolumeScatter')
    node.inputs["Color"].default_value = (0.9, 0.6, 0.3, 1.0)
    node.inputs["Anisotropy"].default_value = 0.2
    if density is None:
        density = tree.nodes.new('ShaderNodeTexNoise').outputs["Fac"]
    if isinstance(density, float):
        node.inputs["Density"].default_value = density
    else:
        tree.links.new(density, node.inputs["Density"])
    return node


def _sigma_s_at(result, points):
    """The summed sigma_s (K, 3) of an export's media at world points (the varying row's
    weights x its density, plus the homogeneous rows)."""
    media = result.scene.media
    total = np.zeros((points.shape[0], 3))
    for r in range(media.count):
        rho = _program_at(result, r, points)[:, 0] if media.density_texture[r] >= 0 else 1.0
        total += np.outer(np.maximum(rho, 0.0) * np.ones(points.shape[0]), media.sigma_s[r])
    return total


@pytest.mark.parametrize("shader", ["add", "mix"])
def test_a_varying_density_under_add_or_mix_is_the_single_shader_of_the_summed_density(shader):
    """Add Shader of two Volume Scatters (same Color and Anisotropy) of densities a (a
    Noise's Fac) and b = 0.7 is one scatter of density a + b (a Math Add): the summed
    sigma_s of the exports (the varying row x its program, plus the homogeneous part)
    agree at points inside the cube within float32; Mix Shader (Fac 0.25) of them is one
    of density 0.75 a + 0.25 b (Math Multiply Add). The anisotropy is the same."""
    _lit()

    def two(tree):
        join = tree.nodes.new('ShaderNodeAddShader' if shader == "add" else 'ShaderNodeMixShader')
        first = 0 if shader == "add" else 1
        if shader == "mix":
            join.inputs["Fac"].default_value = 0.25
        tree.links.new(_scatter(tree).outputs[0], join.inputs[first])
        tree.links.new(_scatter(tree, 0.7).outputs[0], join.inputs[first + 1])
        return join
    _volume_material("Two Scatters", two)
    split = export()
    assert split.warnings == []
    assert split.scene.media.density_texture.tolist() == [0, -1]

    def one(tree):
        noise = tree.nodes.new('ShaderNodeTexNoise')
        total = tree.nodes.new('ShaderNodeMath')
        total.operation = 'MULTIPLY_ADD'  # Fac x w_a + w_b b
        w_a, w_b = (1.0, 1.0) if shader == "add" else (0.75, 0.25)
        tree.links.new(noise.outputs["Fac"], total.inputs[0])
        total.inputs[1].default_value = w_a
        total.inputs[2].default_value = w_b * 0.7
        return _scatter(tree, total.outputs[0])
    _lit()  # a new scene
    _volume_material("One Scatter", one)
    single = export()
    assert single.warnings == []
    assert single.scene.media.density_texture.tolist() == [0]
    np.testing.assert_allclose(_sigma_s_at(split, POINTS), _sigma_s_at(single, POINTS),
                               rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(split.scene.media.anisotropy, 0.2, rtol=1e-6)
    np.testing.assert_allclose(single.scene.media.anisotropy, 0.2, rtol=1e-6)
