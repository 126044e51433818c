"""Shader nodes -> closure rows (photon_engine/export_shaders.py), against the node inputs
set by hand: each node kind's closure holds exactly the inputs in its slots
(core/scene/closures.py), Mix / Add become weights, images the closure's texture; and the
warnings of issue 11 (part 4): linked Normal inputs, IOR <= 0, values out of range,
subsurface, thin film, volume-only materials (their faces bound a medium, not a surface). Runs on every
supported Blender (marker ``api``): inputs a version lacks are expected at their defaults.
"""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import scenes  # noqa: E402
from tests.blender.export_probe import export  # noqa: E402
from tests.conftest import load_extension_package  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]

photon_map = load_extension_package()
from photon_map.core.scene import closures as cl  # noqa: E402
from photon_map.core.shading import program as pg  # noqa: E402
from photon_map.photon_engine.compat import ensure_node_tree  # noqa: E402

VERSION = tuple(bpy.app.version[:2])


def new_scene():
    scenes.reset()
    scenes.set_resolution(16, 16)
    scenes.add_camera(location=(0.0, -6.0, 2.0))


def material(name):
    mat = bpy.data.materials.new(name)
    tree = ensure_node_tree(mat)
    tree.nodes.clear()
    out = tree.nodes.new('ShaderNodeOutputMaterial')
    return mat, tree, out


def shader(name, idname, inputs=(), **props):
    """A material with one ``idname`` node into the output; ``inputs``: (socket, value)
    pairs set only where this Blender has the socket; ``props``: node properties."""
    mat, tree, out = material(name)
    node = tree.nodes.new(idname)
    for key, value in props.items():  # first: they choose which inputs are shown
        setattr(node, key, value)
    for key, value in dict(inputs).items():
        if key in node.inputs:
            node.inputs[key].default_value = value
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat, node


def export_planes(*mats):
    """One plane per material; returns (result, [closure rows of each material])."""
    for i, mat in enumerate(mats):
        scenes.add_plane(size=1.0, location=(2.0 * i, 0.0, 0.0), material=mat, name=f"P{i}")
    result = export()
    mesh, m = result.scene.mesh, result.scene.materials
    table = m.closure_table()
    rows = []
    for i in range(len(mats)):
        idx = int(mesh.material_index[mesh.object_index == mesh.object_names.index(f"P{i}")][0])
        lo, n = table["first"][idx], table["count"][idx]
        rows.append([{"kind": int(table["kind"][j]), "weight": table["weight"][j],
                      "params": table["params"][j], "texture": int(table["texture"][j])}
                     for j in range(lo, lo + n)])
    return result, rows


def assert_params(actual, **expected):
    """``actual`` (PARAM_COUNT,) equals closures.params(**expected), every slot."""
    np.testing.assert_allclose(actual, cl.params(**expected), rtol=1e-6, atol=1e-7)


# Every node kind ------------------------------------------------------------------------------

PRINCIPLED_INPUTS = {
    "Base Color": (0.5, 0.4, 0.2, 1.0), "Metallic": 0.25, "Roughness": 0.35, "IOR": 1.33,
    "Specular IOR Level": 0.7, "Specular Tint": (0.9, 0.8, 0.7, 1.0),
    "Transmission Weight": 0.4, "Coat Weight": 0.6, "Coat Roughness": 0.2, "Coat IOR": 1.6,
    "Coat Tint": (0.7, 0.8, 0.9, 1.0), "Sheen Weight": 0.3, "Sheen Roughness": 0.45,
    "Sheen Tint": (0.6, 0.5, 0.4, 1.0), "Anisotropic": 0.55, "Anisotropic Rotation": 0.125,
    "Diffuse Roughness": 0.65, "Thin Wall": True,
}


def test_principled_inputs_fill_every_slot():
    new_scene()
    mat, node = shader("AllInputs", 'ShaderNodeBsdfPrincipled', PRINCIPLED_INPUTS.items(),
                       distribution='GGX')
    result, [[c]] = export_planes(mat)
    assert result.warnings == []
    assert c["kind"] == cl.CLOSURE_PRINCIPLED and c["texture"] == -1
    np.testing.assert_allclose(c["weight"], 1.0)
    has = {name: name in node.inputs for name in ("Diffuse Roughness", "Thin Wall")}
    assert has["Diffuse Roughness"] == (VERSION >= (4, 3))
    assert has["Thin Wall"] == (VERSION >= (5, 2))
    assert_params(c["params"], color=(0.5, 0.4, 0.2), metallic=0.25, roughness=0.35, ior=1.33,
                  specular_level=0.7, specular_tint=(0.9, 0.8, 0.7), transmission=0.4,
                  coat_weight=0.6, coat_roughness=0.2, coat_ior=1.6, coat_tint=(0.7, 0.8, 0.9),
                  sheen_weight=0.3, sheen_roughness=0.45, sheen_tint=(0.6, 0.5, 0.4),
                  anisotropic=0.55, anisotropic_rotation=0.125,
                  diffuse_roughness=0.65 if has["Diffuse Roughness"] else 0.0,
                  thin_wall=1.0 if has["Thin Wall"] else 0.0,
                  distribution=cl.DISTRIBUTION_GGX)


def test_default_principled_is_the_default_row():
    new_scene()
    mat, _ = shader("Default", 'ShaderNodeBsdfPrincipled')
    result, [[c]] = export_planes(mat)
    assert result.warnings == []
    # Blender's defaults are the contract's (core/scene/closures.default_params).
    assert_params(c["params"])


def _plain_cases():
    cases = [
        ("ShaderNodeBsdfDiffuse", {"Color": (0.1, 0.2, 0.3, 1.0), "Roughness": 0.4}, {},
         cl.CLOSURE_DIFFUSE, dict(color=(0.1, 0.2, 0.3), roughness=0.4)),
        ("ShaderNodeBsdfGlossy", {"Color": (0.9, 0.8, 0.7, 1.0), "Roughness": 0.3,
                                  "Anisotropy": -0.4, "Rotation": 0.2},
         {"distribution": 'BECKMANN'}, cl.CLOSURE_GLOSSY,
         dict(color=(0.9, 0.8, 0.7), roughness=0.3, anisotropic=-0.4, anisotropic_rotation=0.2,
              distribution=cl.DISTRIBUTION_BECKMANN)),
        ("ShaderNodeBsdfGlossy", {"Roughness": 0.1}, {"distribution": 'ASHIKHMIN_SHIRLEY'},
         cl.CLOSURE_GLOSSY, dict(color=0.8, roughness=0.1,
                                 distribution=cl.DISTRIBUTION_ASHIKHMIN_SHIRLEY)),
        ("ShaderNodeBsdfGlass", {"Color": (1.0, 0.9, 0.8, 1.0), "Roughness": 0.2, "IOR": 1.7},
         {"distribution": 'GGX'}, cl.CLOSURE_GLASS,
         dict(color=(1.0, 0.9, 0.8), roughness=0.2, ior=1.7, distribution=cl.DISTRIBUTION_GGX)),
        ("ShaderNodeBsdfRefraction", {"Color": (0.9, 1.0, 0.9, 1.0), "Roughness": 0.15,
                                      "IOR": 1.33}, {}, cl.CLOSURE_REFRACTION,
         dict(color=(0.9, 1.0, 0.9), roughness=0.15, ior=1.33,
              distribution=cl.DISTRIBUTION_BECKMANN)),  # Refraction's default: Beckmann
        ("ShaderNodeBsdfTranslucent", {"Color": (0.3, 0.6, 0.2, 1.0)}, {},
         cl.CLOSURE_TRANSLUCENT, dict(color=(0.3, 0.6, 0.2))),
        ("ShaderNodeBsdfSheen", {"Color": (0.7, 0.2, 0.4, 1.0), "Roughness": 0.25}, {},
         cl.CLOSURE_SHEEN, dict(color=(0.7, 0.2, 0.4), roughness=0.25)),
    ]
    if VERSION >= (4, 3):
        cases += [
            ("ShaderNodeBsdfMetallic", {"Base Color": (0.9, 0.6, 0.3, 1.0),
                                        "Edge Tint": (0.95, 0.8, 0.6, 1.0), "Roughness": 0.2,
                                        "Anisotropy": 0.3, "Rotation": 0.1},
             {"fresnel_type": 'F82', "distribution": 'GGX'}, cl.CLOSURE_METALLIC,
             dict(color=(0.9, 0.6, 0.3), specular_tint=(0.95, 0.8, 0.6), roughness=0.2,
                  anisotropic=0.3, anisotropic_rotation=0.1, distribution=cl.DISTRIBUTION_GGX,
                  fresnel_type=cl.FRESNEL_F82)),
            ("ShaderNodeBsdfMetallic", {"IOR": (0.2, 0.9, 1.1), "Extinction": (3.9, 2.4, 2.2),
                                        "Roughness": 0.4},
             {"fresnel_type": 'PHYSICAL_CONDUCTOR'}, cl.CLOSURE_METALLIC,
             # Base Color and Edge Tint are hidden: the contract's defaults.
             dict(roughness=0.4, fresnel_type=cl.FRESNEL_CONDUCTOR, metal_n=(0.2, 0.9, 1.1),
                  metal_k=(3.9, 2.4, 2.2))),
        ]
    return cases


@pytest.mark.parametrize("idname, inputs, props, kind, expected", _plain_cases(),
                         ids=lambda v: v if isinstance(v, str) else None)
def test_plain_node_is_one_closure_with_its_inputs(idname, inputs, props, kind, expected):
    new_scene()
    mat, _ = shader("Plain", idname, inputs.items(), **props)
    result, [[c]] = export_planes(mat)
    if props.get("distribution") == "ASHIKHMIN_SHIRLEY":  # rendered as GGX: said once
        assert len(result.warnings) == 1, result.warnings
        assert '"Plain"' in result.warnings[0] and "ASHIKHMIN_SHIRLEY" in result.warnings[0]
    else:
        assert result.warnings == []
    assert c["kind"] == kind and c["texture"] == -1
    np.testing.assert_allclose(c["weight"], 1.0)
    assert_params(c["params"], **expected)


def test_mix_of_two_principled_is_two_weighted_closures_and_add_sums():
    new_scene()
    mat, tree, out = material("Layered")
    a = tree.nodes.new('ShaderNodeBsdfPrincipled')
    a.inputs["Base Color"].default_value = (0.8, 0.1, 0.1, 1.0)
    a.inputs["Roughness"].default_value = 0.2
    b = tree.nodes.new('ShaderNodeBsdfPrincipled')
    b.inputs["Metallic"].default_value = 1.0
    b.inputs["Roughness"].default_value = 0.6
    mix = tree.nodes.new('ShaderNodeMixShader')
    mix.inputs[0].default_value = 0.3
    reroute = tree.nodes.new('NodeReroute')
    sheen = tree.nodes.new('ShaderNodeBsdfSheen')
    add = tree.nodes.new('ShaderNodeAddShader')
    emit = tree.nodes.new('ShaderNodeEmission')
    emit.inputs["Strength"].default_value = 2.0
    outer = tree.nodes.new('ShaderNodeMixShader')
    outer.inputs[0].default_value = 0.5
    tree.links.new(a.outputs[0], mix.inputs[1])
    tree.links.new(b.outputs[0], reroute.inputs[0])
    tree.links.new(reroute.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], add.inputs[0])
    tree.links.new(sheen.outputs[0], add.inputs[1])
    tree.links.new(add.outputs[0], outer.inputs[1])
    tree.links.new(emit.outputs[0], outer.inputs[2])
    tree.links.new(outer.outputs[0], out.inputs["Surface"])
    result, [cs] = export_planes(mat)
    assert result.warnings == []
    assert [c["kind"] for c in cs] == [cl.CLOSURE_PRINCIPLED, cl.CLOSURE_PRINCIPLED,
                                       cl.CLOSURE_SHEEN]
    np.testing.assert_allclose([c["weight"] for c in cs],
                               [[0.5 * 0.7] * 3, [0.5 * 0.3] * 3, [0.5] * 3], rtol=1e-6)
    assert_params(cs[0]["params"], color=(0.8, 0.1, 0.1), roughness=0.2)
    assert_params(cs[1]["params"], metallic=1.0, roughness=0.6)
    # Emission is the material's (half of 1 x 2 W/(m^2 sr)), not a closure.
    np.testing.assert_allclose(result.scene.materials.emission[0], 1.0, rtol=1e-6)


def _image(name, rgb=(0.25, 0.5, 0.75)):
    image = bpy.data.images.new(name, 2, 2, float_buffer=True)
    image.pixels.foreach_set(np.tile([*rgb, 1.0], 4).astype(np.float32))
    return image


@pytest.mark.parametrize("idname, socket", [("ShaderNodeBsdfPrincipled", "Base Color"),
                                            ("ShaderNodeBsdfGlossy", "Color"),
                                            ("ShaderNodeBsdfSheen", "Color")])
def test_image_into_the_colour_is_the_closure_texture(idname, socket):
    new_scene()
    mat, node = shader("Textured", idname)
    tex = mat.node_tree.nodes.new('ShaderNodeTexImage')
    tex.image = _image("Checker")
    mat.node_tree.links.new(tex.outputs["Color"], node.inputs[socket])
    result, [[c]] = export_planes(mat)
    assert result.warnings == []
    assert c["texture"] == 0 and result.scene.textures.count == 1
    np.testing.assert_allclose(c["params"][cl.COLOR:cl.COLOR + 3], 1.0)  # image factored out


def test_alpha_keeps_the_closure_weights_of_the_surface():
    new_scene()
    mat, _ = shader("Leaf", 'ShaderNodeBsdfPrincipled', {"Alpha": 0.25}.items())
    result, [[c]] = export_planes(mat)
    # The opacity is the material's; the closure is the surface met with probability 0.25.
    assert result.scene.materials.alpha[0] == pytest.approx(0.25)
    np.testing.assert_allclose(c["weight"], 1.0, rtol=1e-6)


# Warnings (issue 11, part 4) ------------------------------------------------------------------

def _only_warning(result, material):
    msgs = [w for w in result.warnings if f'"{material}"' in w]
    assert len(msgs) == 1, result.warnings
    return msgs[0]


def test_linked_coat_normal_input_is_compiled_into_the_coat_normal_slots():
    # Normal is compiled into the material's program (test_shader_normals.py); so is Coat
    # Normal, into the closure's COAT_NORMAL slots (tests/blender/test_shader_coat_normal.py).
    new_scene()
    mat, node = shader("Bumpy", 'ShaderNodeBsdfPrincipled', {"Coat Weight": 1.0}.items())
    bump = mat.node_tree.nodes.new('ShaderNodeBump')
    mat.node_tree.links.new(bump.outputs["Normal"], node.inputs["Coat Normal"])
    result, _ = export_planes(mat)
    assert not [w for w in result.warnings if "Bumpy" in w], result.warnings
    program = result.scene.materials.programs[0]
    out = program.outputs[program.outputs[:, 1] == pg.TARGET_CLOSURE]
    assert sorted(out[:, 3]) == [cl.COAT_NORMAL, cl.COAT_NORMAL + 1, cl.COAT_NORMAL + 2]


def test_ior_not_positive_is_read_as_one_with_a_warning():
    new_scene()
    mat, _ = shader("Vacuum", 'ShaderNodeBsdfGlass', {"IOR": -0.5}.items())
    result, [[c]] = export_planes(mat)
    msg = _only_warning(result, "Vacuum")
    assert '"IOR"' in msg and "-0.5" in msg and "IOR 1" in msg
    assert c["params"][cl.IOR] == 1.0 and result.scene.materials.ior[0] == 1.0


def test_roughness_past_its_range_from_a_value_node_is_clamped_with_a_warning():
    new_scene()
    mat, node = shader("Driven", 'ShaderNodeBsdfGlossy')
    value = mat.node_tree.nodes.new('ShaderNodeValue')
    value.outputs[0].default_value = 1.75
    mat.node_tree.links.new(value.outputs[0], node.inputs["Roughness"])
    result, [[c]] = export_planes(mat)
    msg = _only_warning(result, "Driven")
    assert '"Roughness"' in msg and "1.75" in msg and "clamped" in msg
    assert c["params"][cl.ROUGHNESS] == 1.0


def test_subsurface_is_rendered_as_diffuse_with_a_warning():
    new_scene()
    mat, _ = shader("Skin", 'ShaderNodeBsdfPrincipled', {"Subsurface Weight": 0.5}.items())
    result, [[c]] = export_planes(mat)
    msg = _only_warning(result, "Skin")
    assert "subsurface" in msg and "diffuse" in msg
    assert c["params"][cl.SUBSURFACE_WEIGHT] == 0.5


def test_thin_film_is_reported_and_ignored():
    new_scene()
    mat, _ = shader("Soap", 'ShaderNodeBsdfPrincipled', {"Thin Film Thickness": 400.0}.items())
    result, _ = export_planes(mat)
    msg = _only_warning(result, "Soap")
    assert "thin film" in msg and "ignored" in msg


def test_volume_only_material_leaves_its_faces_out_of_the_surfaces():
    new_scene()
    smoke, tree, out = material("Smoke")
    volume = tree.nodes.new('ShaderNodeVolumePrincipled')
    tree.links.new(volume.outputs[0], out.inputs["Volume"])
    floor = scenes.diffuse_material("Floor")
    scenes.add_plane(size=1.0, material=floor, name="Floor")
    scenes.add_plane(size=1.0, location=(0, 0, 1), material=smoke, name="Fog")
    scenes.add_plane(size=1.0, location=(0, 0, 2), material=smoke, name="Fog2")
    bpy.ops.mesh.primitive_cube_add(location=(3.0, 0.0, 0.0))  # half smoke, half floor
    cube = bpy.context.active_object
    cube.name = "Half"
    cube.data.materials.append(floor)
    cube.data.materials.append(smoke)
    cube.data.polygons.foreach_set("material_index", [0, 1, 1, 0, 1, 0])
    result = export()
    assert all("not a closed mesh" in w for w in result.warnings)  # planes, half a cube
    assert result.scene.media.names == ("Smoke in Fog", "Smoke in Fog2", "Smoke in Half")
    mesh = result.scene.mesh
    counts = np.bincount(mesh.object_index, minlength=len(mesh.object_names))
    per_object = dict(zip(mesh.object_names, counts.tolist()))
    assert per_object["Fog"] == 0 and per_object["Fog2"] == 0  # no surface, only a boundary
    assert per_object["Floor"] == 2 and per_object["Half"] == 6  # three floor quads


def test_volume_beside_a_surface_renders_the_surface_and_the_medium():
    new_scene()
    mat, _ = shader("Murky", 'ShaderNodeBsdfDiffuse', {"Color": (0.2, 0.3, 0.4, 1.0)}.items())
    volume = mat.node_tree.nodes.new('ShaderNodeVolumeAbsorption')
    mat.node_tree.links.new(volume.outputs[0],
                            mat.node_tree.nodes["Material Output"].inputs["Volume"])
    result, [[c]] = export_planes(mat)
    msg = _only_warning(result, "Murky")
    assert "not a closed mesh" in msg  # a plane
    assert result.scene.media.count == 1 and result.scene.media.names[0].startswith("Murky in")
    assert c["kind"] == cl.CLOSURE_DIFFUSE and result.scene.mesh.triangle_count == 2


def test_ior_from_a_driver_is_checked_like_a_typed_one():
    new_scene()
    mat, node = shader("DrivenGlass", 'ShaderNodeBsdfGlass', {"IOR": 1.5}.items())
    node.inputs["IOR"].driver_add("default_value").driver.expression = "-2.0"
    result, [[c]] = export_planes(mat)
    msg = _only_warning(result, "DrivenGlass")
    assert '"IOR" = -2' in msg and "IOR 1" in msg
    assert c["params"][cl.IOR] == 1.0


def test_new_nodes_keep_main_rendering_through_the_legacy_lobes():
    """Until the core's passes read the closure table, each row also carries the lobes they
    read (docs/export.md, "The legacy lobes")."""
    new_scene()
    mats = [shader("Refr", 'ShaderNodeBsdfRefraction', {"Color": (0.9, 0.8, 0.7, 1.0),
                                                        "IOR": 1.33, "Roughness": 0.0}.items())[0],
            shader("Transl", 'ShaderNodeBsdfTranslucent',
                   {"Color": (0.3, 0.6, 0.2, 1.0)}.items())[0],
            shader("Sss", 'ShaderNodeSubsurfaceScattering',
                   {"Color": (0.7, 0.5, 0.4, 1.0)}.items())[0]]
    result, _ = export_planes(*mats)
    m, mesh = result.scene.materials, result.scene.mesh
    row = {name: mesh.material_index[mesh.object_index == mesh.object_names.index(f"P{i}")][0]
           for i, name in enumerate(("Refr", "Transl", "Sss"))}
    np.testing.assert_allclose(m.transmission[row["Refr"]], [0.9, 0.8, 0.7], rtol=1e-6)
    assert m.ior[row["Refr"]] == pytest.approx(1.33)
    np.testing.assert_allclose(m.diffuse[row["Transl"]], [0.3, 0.6, 0.2], rtol=1e-6)
    np.testing.assert_allclose(m.diffuse[row["Sss"]], [0.7, 0.5, 0.4], rtol=1e-6)
    assert any('"Sss"' in w and "diffuse approximation" in w for w in result.warnings)
    if VERSION >= (4, 3):
        new_scene()
        n, k = np.array([0.2, 0.9, 1.1]), np.array([3.9, 2.4, 2.2])
        metal, _ = shader("Conductor", 'ShaderNodeBsdfMetallic',
                          {"IOR": tuple(n), "Extinction": tuple(k)}.items(),
                          fresnel_type='PHYSICAL_CONDUCTOR')
        result, _ = export_planes(metal)
        # Normal-incidence reflectance of a conductor of complex IOR n + ik.
        f0 = ((n - 1) ** 2 + k ** 2) / ((n + 1) ** 2 + k ** 2)
        np.testing.assert_allclose(result.scene.materials.specular[0], f0, rtol=1e-5)
