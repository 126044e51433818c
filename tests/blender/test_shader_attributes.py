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
