"""Attribute and Color Attribute nodes against Cycles through emission
(tests/blender/shader_scenes.py): mesh attributes on the corner, point and face domains,
float and byte colours, vectors and floats, read by the exporter
(``export.read_attributes``) and interpolated over each triangle like the renderer does;
a missing attribute is 0 in both, reported by the exporter."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import scenes, shader_scenes as ss  # noqa: E402
from tests.blender import test_textures as tt  # noqa: E402
from tests.blender.test_shader_nodes import check, link, node, to_color  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]

LAYERS = [("ColCorner", "FLOAT_COLOR", "CORNER"), ("ColPoint", "FLOAT_COLOR", "POINT"),
          ("ByteCorner", "BYTE_COLOR", "CORNER"), ("BytePoint", "BYTE_COLOR", "POINT"),
          ("VecCorner", "FLOAT_VECTOR", "CORNER"), ("FloatPoint", "FLOAT", "POINT"),
          ("FloatFace", "FLOAT", "FACE")]


def add_layers(planes):
    rng = np.random.default_rng(5)
    for plane in planes:
        me = plane.data
        for name, dtype, domain in LAYERS:
            if dtype.endswith("COLOR"):
                att = me.color_attributes.new(name, dtype, domain)
                vals = rng.uniform(0.0, 1.0, (len(att.data), 4))
                att.data.foreach_set("color", vals.astype(np.float32).ravel())
            else:
                att = me.attributes.new(name, dtype, domain)
                width = 3 if dtype == "FLOAT_VECTOR" else 1
                vals = rng.uniform(-1.0, 2.0, (len(att.data), width))
                att.data.foreach_set("vector" if width == 3 else "value",
                                     vals.astype(np.float32).ravel())
        me.color_attributes.render_color_index = 2  # ByteCorner: the "" name


def color_attribute(name, output="Color"):
    def build(tree, color):
        n = node(tree, "ShaderNodeVertexColor", layer_name=name)
        if output == "Color":
            link(tree, n.outputs["Color"], color)
        else:
            to_color(tree, color, n.outputs[output], n.outputs[output])
    return build


def attribute(name, output):
    def build(tree, color):
        n = node(tree, "ShaderNodeAttribute", attribute_name=name)
        if output in ("Color", "Vector"):
            link(tree, n.outputs[output], color)
        else:
            to_color(tree, color, n.outputs[output], n.outputs[output], n.outputs[output])
    return build


def test_attributes_match_cycles():
    specs = [("Color Attribute corner", color_attribute("ColCorner")),
             ("Color Attribute point", color_attribute("ColPoint")),
             ("Color Attribute byte corner", color_attribute("ByteCorner")),
             ("Color Attribute byte point", color_attribute("BytePoint")),
             ("Color Attribute render", color_attribute("")),
             ("Color Attribute alpha", color_attribute("ColCorner", "Alpha")),
             ("Attribute vector", attribute("VecCorner", "Vector")),
             ("Attribute float", attribute("FloatPoint", "Fac")),
             ("Attribute float colour", attribute("FloatPoint", "Color")),
             ("Attribute colour fac", attribute("ColPoint", "Fac")),
             ("Attribute face", attribute("FloatFace", "Fac")),
             ("Attribute missing", attribute("Nowhere", "Color"))]
    result = ss.compare(specs, setup=add_layers)
    assert not result["warnings"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})
    g = result["grid"]
    r, c = divmod(len(specs) - 1, g)
    missing = result["ours"][r * ss.PIXELS:(r + 1) * ss.PIXELS, c * ss.PIXELS:(c + 1) * ss.PIXELS]
    np.testing.assert_array_equal(missing, 0.0)


def test_a_missing_attribute_is_reported_by_object_and_name():
    scenes.reset()
    plane = scenes.add_plane(name="Bare")
    warnings = []
    local = ss.read_mesh(plane.data)
    out = ss.read_attributes(plane.data, ["Nowhere"], local, "Object 'Bare'", warnings)
    assert out.shape == (2, 3, 1, 4) and not out.any()
    assert warnings == ["Object 'Bare': attribute 'Nowhere' not found; 0 is used, as Cycles"]


def test_vertex_colours_driving_base_colour_render_albedo_times_irradiance_over_pi():
    """The sun-lit plane of tests/blender/test_textures.py, its Base Color a corner colour
    attribute: each pixel is the interpolated colour x E cos / pi (direct light only: a
    lone plane), the colour computed from the exporter's corners at the pixel centre."""

    def material():
        mat = bpy.data.materials.new("Painted")
        tree = scenes.ensure_node_tree(mat)
        tree.nodes.clear()
        bsdf = node(tree, "ShaderNodeBsdfPrincipled")
        bsdf.inputs["Specular IOR Level"].default_value = 0.0
        out = node(tree, "ShaderNodeOutputMaterial")
        link(tree, bsdf.outputs[0], out.inputs["Surface"])
        link(tree, node(tree, "ShaderNodeVertexColor", layer_name="Paint").outputs["Color"],
             bsdf.inputs["Base Color"])
        return mat

    scene = tt.sun_plane_scene(material)
    plane = bpy.data.objects["Floor"]
    att = plane.data.color_attributes.new("Paint", "FLOAT_COLOR", "CORNER")
    rng = np.random.default_rng(9)
    att.data.foreach_set("color", np.c_[rng.uniform(0.2, 0.9, (4, 3)),
                                        np.ones(4)].astype(np.float32).ravel())
    img = tt.render_photon_map(scene)
    i = (np.arange(tt.RES) + 0.5) / tt.RES * 2.0 - 1.0
    X, Y = np.meshgrid(i, -i)
    pts = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], 1)
    albedo = ss.plane_attributes(plane, pts, ["Paint"])[0, :, :3].reshape(tt.RES, tt.RES, 3)
    want = albedo * tt.SUN * np.cos(tt.TILT) / np.pi
    rel = np.abs(img - want) / want
    print(f"\nworst pixel {100 * rel.max():.3f} %, mean {100 * rel.mean():.4f} %")
    assert rel.max() < 0.02


# --- UV maps by name ---------------------------------------------------------------------

def add_second_uv_map(planes):
    """A second, non-active UV map "Second" with random corner values on every plane (the
    active render map stays Blender's default "UVMap")."""
    rng = np.random.default_rng(11)
    for plane in planes:
        layer = plane.data.uv_layers.new(name="Second")
        layer.data.foreach_set("uv", rng.uniform(-0.5, 1.5, 2 * len(layer.data))
                               .astype(np.float32))
        plane.data.uv_layers["UVMap"].active_render = True


def uv_map(name, through=None):
    """A UV Map node naming ``name`` into the Emission colour, directly or as the Vector
    of a ``through`` texture node (its Color output)."""
    def build(tree, color):
        n = node(tree, "ShaderNodeUVMap", uv_map=name)
        if through is None:
            link(tree, n.outputs["UV"], color)
            return
        tex = node(tree, through)
        link(tree, n.outputs["UV"], tex.inputs["Vector"])
        if through == "ShaderNodeTexChecker":
            tex.inputs["Scale"].default_value = 3.0
        link(tree, tex.outputs[0], color)
    return build


def test_uv_maps_by_name_match_cycles():
    """A UV Map node reads the map it names, not the active one: per pixel against
    Cycles (the map directly, through a Checker, through a Gradient); the active map by
    name and a missing name (0, 0 as Cycles, reported by material and name)."""
    specs = [("UV Second", uv_map("Second")),
             ("UV Second checker", uv_map("Second", "ShaderNodeTexChecker")),
             ("UV Second gradient", uv_map("Second", "ShaderNodeTexGradient")),
             ("UV active by name", uv_map("UVMap")),
             ("UV missing", uv_map("Nowhere"))]
    result = ss.compare(specs, setup=add_second_uv_map)
    assert result["warnings"] == [
        "Material 'UV missing': UV map 'Nowhere' not found on object 'Plane4'; "
        "(0, 0) is used, as Cycles"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})
    # the second map differs from the active one, so reading the wrong map would fail
    g = result["grid"]
    r, c = divmod(3, g)
    second = result["ours"][:ss.PIXELS, :ss.PIXELS]
    active = result["ours"][r * ss.PIXELS:(r + 1) * ss.PIXELS, c * ss.PIXELS:(c + 1) * ss.PIXELS]
    assert np.abs(second - active).max() > 0.3
    r, c = divmod(len(specs) - 1, g)
    missing = result["ours"][r * ss.PIXELS:(r + 1) * ss.PIXELS, c * ss.PIXELS:(c + 1) * ss.PIXELS]
    np.testing.assert_array_equal(missing, 0.0)


def test_named_uv_maps_cross_the_contract_to_the_hits():
    """The exporter exports the UV map a Base Color program names (``Mesh.uv_maps``) at
    the right corners of every triangle (the map is a function of position, so a corner
    order mistake shows), and the HitShader reads it at a hit as index 1 of
    ``ShadingInputs.uv`` (the active map is index 0)."""
    from tests.blender import export_probe
    from photon_map.core.prepared import prepare

    scene = scenes.reset()
    mat = bpy.data.materials.new("Mapped")
    tree = scenes.ensure_node_tree(mat)
    tree.nodes.clear()
    bsdf = node(tree, "ShaderNodeBsdfPrincipled")
    out = node(tree, "ShaderNodeOutputMaterial")
    link(tree, bsdf.outputs[0], out.inputs["Surface"])
    link(tree, node(tree, "ShaderNodeUVMap", uv_map="Second").outputs["UV"],
         bsdf.inputs["Base Color"])
    plane = scenes.add_plane(size=2.0, location=(0.3, -0.2, 0.0), material=mat)
    scenes.add_camera(location=(0.0, 0.0, 5.0), look_at=(0.0, 0.0, 0.0))

    def second(p):  # the map as a function of the world position
        return np.stack([0.25 + 0.1 * p[..., 0], 0.5 - 0.2 * p[..., 1]], -1)

    layer = plane.data.uv_layers.new(name="Second")
    co = np.array([plane.data.vertices[lp.vertex_index].co[:] for lp in plane.data.loops])
    layer.data.foreach_set("uv", second(co + np.array(plane.location)).astype(np.float32)
                           .ravel())
    plane.data.uv_layers["UVMap"].active_render = True
    result = export_probe.export(scene, origin=np.zeros(3))
    mesh = result.scene.mesh
    assert not [w for w in result.warnings if "UV" in w], result.warnings
    assert mesh.uv_map_names == ("Second",)
    corners = mesh.vertices[mesh.triangles].astype(np.float64)
    np.testing.assert_allclose(mesh.uv_maps[:, :, 0], second(corners), atol=1e-6)
    with prepare(result.scene, threads=1) as prepared:
        prim = np.zeros(3, np.int32)
        u = np.array([0.2, 0.5, 0.1])
        v = np.array([0.3, 0.1, 0.6])
        d = np.tile([0.0, 0.0, -1.0], (3, 1))
        ins, _ = prepared.hit_shader.inputs(prim, u, v, d)
        assert ins.uv.shape == (2, 3, 2)
        np.testing.assert_allclose(ins.uv[1], second(ins.position), atol=1e-5)


def test_geometry_parametric_matches_cycles():
    """Geometry Parametric: (1 - u - v, u, 0) of the hit's barycentrics in each of the
    plane's two triangles (the exporter's per-corner attribute), directly and on a plane
    turned in its mesh (another corner order)."""
    def parametric(tree, color):
        geo = node(tree, "ShaderNodeNewGeometry")
        link(tree, geo.outputs["Parametric"], color)

    def turn(planes):
        ss.turn_mesh(planes[1], (0.0, 0.0, 0.7))
    specs = [("Parametric", parametric), ("Parametric turned", parametric)]
    result = ss.compare(specs, setup=turn)
    assert not result["warnings"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})
