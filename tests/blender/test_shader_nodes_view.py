"""More shader nodes against Cycles, through emission (the pattern and tolerances of
tests/blender/test_shader_nodes.py): Fresnel and Layer Weight (a varying Normal input, and
the shading normal), Texture Coordinate Camera / Window / Reflection / Object from another
object, Separate / Combine Color HSL, Vector Curves, Wavelength, Voronoi N-Sphere Radius.

The planes face an orthographic camera, so the incoming direction is +Z everywhere; the
view-dependent nodes vary through their Normal input (a tilted unit vector from the UV, all
angles to grazing) and the shading-normal planes check the unlinked default.
"""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import shader_scenes as ss  # noqa: E402
from tests.blender.test_shader_nodes import (  # noqa: E402
    check, link, node, setdef, to_color, two_colors, uv_scalars, voronoi_plane)

pytestmark = [pytest.mark.blender, pytest.mark.api]


def tilted_normal(tree):
    """A unit vector from the UV: normalize(3 (u - 0.5), 3 (v - 0.5), 0.4): from facing
    the viewer (+Z) at the centre to nearly grazing at the corners."""
    tc = node(tree, "ShaderNodeTexCoord")
    m = node(tree, "ShaderNodeMapping", vector_type='POINT')
    link(tree, tc.outputs["UV"], m.inputs["Vector"])
    setdef(m, "Location", (-1.5, -1.5, 0.4))
    setdef(m, "Scale", (3.0, 3.0, 0.0))
    nrm = node(tree, "ShaderNodeVectorMath", operation='NORMALIZE')
    link(tree, m.outputs[0], nrm.inputs[0])
    return nrm.outputs["Vector"]


def fresnel_plane(ior=1.45, linked_normal=True, ior_from_uv=False):
    def build(tree, color):
        f = node(tree, "ShaderNodeFresnel")
        f.inputs["IOR"].default_value = ior
        if ior_from_uv:
            link(tree, uv_scalars(tree, sx=2.0, ox=0.2)[0], f.inputs["IOR"])
        if linked_normal:
            link(tree, tilted_normal(tree), f.inputs["Normal"])
        link(tree, f.outputs[0], color)
    return build


def layer_weight_plane(blend, linked_normal=True, blend_from_uv=False):
    def build(tree, color):
        lw = node(tree, "ShaderNodeLayerWeight")
        lw.inputs["Blend"].default_value = blend
        if blend_from_uv:
            link(tree, uv_scalars(tree, sx=1.0, ox=0.0)[1], lw.inputs["Blend"])
        if linked_normal:
            link(tree, tilted_normal(tree), lw.inputs["Normal"])
        to_color(tree, color, lw.outputs["Fresnel"], lw.outputs["Facing"])
    return build


def tex_coord_plane(output, scale=0.3):
    """Texture Coordinate ``output`` (scaled into a visible range) into the colour."""
    def build(tree, color):
        tc = node(tree, "ShaderNodeTexCoord")
        m = node(tree, "ShaderNodeVectorMath", operation='SCALE')
        link(tree, tc.outputs[output], m.inputs[0])
        setdef(m, "Scale", scale)
        link(tree, m.outputs["Vector"], color)
    return build


def other_object_plane(tree, color):
    """Texture Coordinate Object of an empty, moved, rotated and scaled."""
    other = bpy.data.objects.new("Other", None)
    bpy.context.scene.collection.objects.link(other)
    other.location = (0.7, -1.2, 0.4)
    other.rotation_euler = (0.3, -0.2, 0.9)
    other.scale = (1.5, 0.8, 1.2)
    bpy.context.view_layer.update()
    tc = node(tree, "ShaderNodeTexCoord")
    tc.object = other
    link(tree, tc.outputs["Object"], color)


def hsl_plane(tree, color):
    a, b, _ = two_colors(tree)
    sep = node(tree, "ShaderNodeSeparateColor", mode='HSL')
    link(tree, b, sep.inputs[0])
    comb = node(tree, "ShaderNodeCombineColor", mode='HSL')
    link(tree, sep.outputs[1], comb.inputs[0])
    link(tree, sep.outputs[2], comb.inputs[1])
    link(tree, sep.outputs[0], comb.inputs[2])
    link(tree, comb.outputs[0], color)


def hsl_separate_plane(tree, color):
    a, b, _ = two_colors(tree)
    sep = node(tree, "ShaderNodeSeparateColor", mode='HSL')
    link(tree, b, sep.inputs[0])
    to_color(tree, color, sep.outputs[0], sep.outputs[1], sep.outputs[2])


def vector_curves_plane(extrapolate):
    def build(tree, color):
        tc = node(tree, "ShaderNodeTexCoord")
        m = node(tree, "ShaderNodeMapping", vector_type='POINT')  # object coords, -1.3..1.3
        link(tree, tc.outputs["Object"], m.inputs["Vector"])
        setdef(m, "Scale", (1.3, 1.3, 1.0))
        setdef(m, "Location", (0.0, 0.0, 0.2))
        c = node(tree, "ShaderNodeVectorCurve")
        cm = c.mapping
        cm.extend = 'EXTRAPOLATED' if extrapolate else 'HORIZONTAL'
        cm.curves[0].points.new(0.2, 0.5)
        cm.curves[1].points[1].location = (0.8, 0.6)
        cm.curves[2].points.new(-0.3, 0.1)
        cm.update()
        setdef(c, "Fac", 0.9)
        link(tree, m.outputs[0], c.inputs["Vector"])
        link(tree, c.outputs[0], color)
    return build


def wavelength_plane(tree, color):
    sa, _ = uv_scalars(tree, sx=440.0, ox=360.0)  # 360-800 nm: both ends outside
    w = node(tree, "ShaderNodeWavelength")
    link(tree, sa, w.inputs["Wavelength"])
    link(tree, w.outputs[0], color)


VIEW_SPECS = [
    ("Fresnel IOR 1.45", fresnel_plane(1.45)),
    ("Fresnel IOR 0.7 (below 1)", fresnel_plane(0.7)),
    ("Fresnel IOR from UV", fresnel_plane(ior_from_uv=True)),
    ("Fresnel shading normal", fresnel_plane(1.45, linked_normal=False)),
    ("Layer Weight blend 0.3", layer_weight_plane(0.3)),
    ("Layer Weight blend 0.5", layer_weight_plane(0.5)),
    ("Layer Weight blend 0.8", layer_weight_plane(0.8)),
    ("Layer Weight blend from UV", layer_weight_plane(0.0, blend_from_uv=True)),
    ("Layer Weight shading normal", layer_weight_plane(0.3, linked_normal=False)),
    ("Texture Coordinate Camera", tex_coord_plane("Camera", 0.1)),
    ("Texture Coordinate Window", tex_coord_plane("Window", 1.0)),
    ("Texture Coordinate Reflection", tex_coord_plane("Reflection", 1.0)),
    ("Texture Coordinate Object from another object", other_object_plane),
]

COLOR_SPECS = [
    ("Separate/Combine Color HSL", hsl_plane),
    ("Separate Color HSL", hsl_separate_plane),
    ("Vector Curves", vector_curves_plane(False)),
    ("Vector Curves extrapolated", vector_curves_plane(True)),
    ("Wavelength", wavelength_plane),
    ("Voronoi 2D N-Sphere Radius", voronoi_plane("2D", "N_SPHERE_RADIUS", output="Radius")),
    ("Voronoi 3D N-Sphere Radius", voronoi_plane("3D", "N_SPHERE_RADIUS", output="Radius",
                                                 Randomness=0.8)),
]


def test_fresnel_layer_weight_and_texture_coordinates_match_cycles():
    result = ss.compare(VIEW_SPECS)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in VIEW_SPECS])


def test_hsl_vector_curves_wavelength_and_n_sphere_radius_match_cycles():
    result = ss.compare(COLOR_SPECS)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in COLOR_SPECS])


def test_window_coordinates_in_a_render_follow_the_camera():
    """End to end (export_scene's camera view, the render frame's origin, the program at
    camera hits): a sun-lit diffuse plane whose colour is (Window x, Window y, 0.5) renders,
    averaged over each 8 x 8 pixel block, that colour at the block's centre x E cos / pi
    (a linear colour: the block mean is its centre value)."""
    from tests.blender import test_textures as tt

    def material():
        mat = bpy.data.materials.new("Window")
        tree = ss.scenes.ensure_node_tree(mat)
        tree.nodes.clear()
        out = node(tree, "ShaderNodeOutputMaterial")
        bsdf = node(tree, "ShaderNodeBsdfDiffuse")
        link(tree, bsdf.outputs[0], out.inputs["Surface"])
        tc = node(tree, "ShaderNodeTexCoord")
        sep = node(tree, "ShaderNodeSeparateXYZ")
        link(tree, tc.outputs["Window"], sep.inputs[0])
        comb = node(tree, "ShaderNodeCombineXYZ")
        link(tree, sep.outputs[0], comb.inputs[0])
        link(tree, sep.outputs[1], comb.inputs[1])
        comb.inputs[2].default_value = 0.5
        link(tree, comb.outputs[0], bsdf.inputs["Color"])
        return mat

    scene = tt.sun_plane_scene(material)
    scene.camera.location = (0.05, -0.05, 3.0)  # off the world origin, still inside the plane
    img = tt.render_photon_map(scene)
    n = tt.RES // 8
    blocks = img.reshape(n, 8, n, 8, 3).mean(axis=(1, 3))  # row 0 at the top
    centre = (np.arange(n) + 0.5) / n
    want = np.empty((n, n, 3))
    want[..., 0] = centre[None, :]
    want[..., 1] = centre[::-1, None]
    want[..., 2] = 0.5
    want *= tt.SUN * np.cos(tt.TILT) / np.pi
    rel = np.abs(blocks - want) / want
    print(f"\nworst block {100 * rel.max():.3f} % off (Window x, y, 0.5) x E cos / pi")
    assert rel.max() < 0.01
