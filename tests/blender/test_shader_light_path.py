"""The Light Path and Tangent nodes against Cycles in the same bpy process.

Through emission (the pattern and tolerances of tests/blender/test_shader_nodes.py): the
Light Path outputs at camera rays (Is Camera Ray mixing two colours, Ray Length, every
flag and depth), the Tangent node (radial about X, Y, Z; UV map) and Geometry Tangent on
planes whose mesh is turned, so that the object's axes are oblique to the surface.

Through the whole engine (export, camera pass, specular continuation, shadow rays): an
emitter seen directly and through a mirror, its colour made of the Light Path outputs
(Is Camera Ray 1 then 0; Is Glossy / Singular / Reflection Ray, Ray Depth and Glossy
Depth after the mirror; Ray Length along each segment); a leaf whose Principled Alpha is
1 - 0.75 Is Shadow Ray is opaque to the camera and lets 0.75 of the sun through.
"""

import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_reference as cr, scenes  # noqa: E402
from tests.blender import shader_scenes as ss  # noqa: E402
from tests.blender.test_shader_emission_alpha import leaf_scene  # noqa: E402
from tests.blender.test_shader_nodes import check, link, node, setdef, to_color  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]


def scaled(tree, socket, k, offset=0.0):
    """socket x k + offset (Math Multiply Add)."""
    m = node(tree, "ShaderNodeMath", operation='MULTIPLY_ADD')
    link(tree, socket, m.inputs[0])
    m.inputs[1].default_value = k
    m.inputs[2].default_value = offset
    return m.outputs[0]


def weighted(tree, terms, offset=0.0):
    """sum of socket x weight over terms [(socket, weight)] + offset."""
    out = None
    for sock, w in terms:
        term = scaled(tree, sock, w, 0.0)
        if out is None:
            out = term
        else:
            add = node(tree, "ShaderNodeMath", operation='ADD')
            link(tree, out, add.inputs[0])
            link(tree, term, add.inputs[1])
            out = add.outputs[0]
    return scaled(tree, out, 1.0, offset)


def camera_mix(tree, color):
    lp = node(tree, "ShaderNodeLightPath")
    mix = node(tree, "ShaderNodeMix", data_type='RGBA')
    link(tree, lp.outputs["Is Camera Ray"], mix.inputs["Factor"])
    setdef(mix, "A_Color", (0.9, 0.1, 0.1, 1.0))
    setdef(mix, "B_Color", (0.1, 0.3, 0.8, 1.0))
    link(tree, next(o for o in mix.outputs if o.identifier == "Result_Color"), color)


def ray_length(tree, color):
    lp = node(tree, "ShaderNodeLightPath")
    to_color(tree, color, scaled(tree, lp.outputs["Ray Length"], 0.1))


def flags(tree, color):
    o = node(tree, "ShaderNodeLightPath").outputs
    to_color(tree, color,
             weighted(tree, [(o["Is Shadow Ray"], 0.5), (o["Is Diffuse Ray"], 0.25)], 0.1),
             weighted(tree, [(o["Is Glossy Ray"], 0.5), (o["Is Singular Ray"], 0.25)], 0.2),
             weighted(tree, [(o["Is Reflection Ray"], 0.5),
                             (o["Is Transmission Ray"], 0.25)], 0.3))


def depths(tree, color):
    o = node(tree, "ShaderNodeLightPath").outputs
    to_color(tree, color,
             weighted(tree, [(o["Ray Depth"], 0.5), (o["Diffuse Depth"], 0.25)], 0.1),
             weighted(tree, [(o["Glossy Depth"], 0.5), (o["Transmission Depth"], 0.25)],
                      0.2),
             scaled(tree, o["Is Camera Ray"], 0.5, 0.1))


def tangent_plane(kind):
    """The tangent mapped to a colour, t x 0.5 + 0.5 (Cycles' emission keeps negative
    values; the offset keeps both renderers' images positive)."""
    def build(tree, color):
        if kind == "Geometry":
            t = node(tree, "ShaderNodeNewGeometry").outputs["Tangent"]
        else:
            n = node(tree, "ShaderNodeTangent")
            if kind == "UV_MAP":
                n.direction_type = 'UV_MAP'
            else:
                n.direction_type = 'RADIAL'
                n.axis = kind
            t = n.outputs["Tangent"]
        m = node(tree, "ShaderNodeVectorMath", operation='MULTIPLY_ADD')
        link(tree, t, m.inputs[0])
        setdef(m, "Vector_001", (0.5, 0.5, 0.5))
        setdef(m, "Vector_002", (0.5, 0.5, 0.5))
        link(tree, m.outputs[0], color)
    return build


LIGHT_PATH_SPECS = [
    ("Is Camera Ray mixing two colours", camera_mix),
    ("Ray Length", ray_length),
    ("Shadow, diffuse, glossy, singular, reflection, transmission", flags),
    ("Depths", depths),
]
TANGENT_SPECS = [
    ("Tangent radial X", tangent_plane("X")),
    ("Tangent radial Y", tangent_plane("Y")),
    ("Tangent radial Z", tangent_plane("Z")),
    ("Tangent UV map", tangent_plane("UV_MAP")),
    ("Geometry Tangent", tangent_plane("Geometry")),
]
TURNS = [(0.5, 0.3, 0.8), (-0.4, 0.7, 0.2), (0.6, -0.5, 1.1), (0.3, 0.4, 0.9),
         (-0.7, 0.2, -0.6)]


def test_light_path_at_camera_rays_matches_cycles():
    result = ss.compare(LIGHT_PATH_SPECS)
    assert not result["warnings"], result["warnings"]
    figures = check(result, [n for n, _ in LIGHT_PATH_SPECS], tol=1e-5)
    print(figures)


def test_tangent_nodes_match_cycles():
    def turn(planes):
        for plane, rotation in zip(planes, TURNS):
            ss.turn_mesh(plane, rotation)
    result = ss.compare(TANGENT_SPECS, setup=turn)
    assert not result["warnings"], result["warnings"]
    print(check(result, [n for n, _ in TANGENT_SPECS]))


def test_unanswered_light_path_outputs_are_reported():
    # Blender 4.2's Light Path has no Is Volume Scatter Ray output
    names = ["Transparent Depth", "Is Volume Scatter Ray"]

    def build(tree, color):
        o = node(tree, "ShaderNodeLightPath").outputs
        names[:] = [n for n in names if n in o]
        to_color(tree, color, *[o[n] for n in names], o["Ray Depth"])
    scene, planes, g = ss.layout([("Unanswered", build)])
    _, warnings = ss.compile_planes(planes)
    assert len(warnings) == len(names) >= 1, warnings
    for n in names:
        assert any(f"'{n}'" in w for w in warnings), (n, warnings)


RES = 32


def _material(name):
    mat = bpy.data.materials.new(name)
    tree = scenes.ensure_node_tree(mat)
    tree.nodes.clear()
    return mat, tree, node(tree, "ShaderNodeOutputMaterial")


def mirror_scene():
    """An orthographic camera looking down (z = 5, 4 m wide); on the right a 45-degree
    mirror (x in [0.3, 1.7]) that sends the camera's rays towards -x, to a vertical
    emitter at x = -1.9 (edge-on to the camera); on the left a horizontal emitter of the
    same material at z = -1 under the mirror's rays. The emission colour: R = Is Camera
    Ray x 0.5 + Ray Length x 0.1, G = Is Glossy / Singular / Reflection / Transmission /
    Diffuse Ray weighted, B = Ray Depth and Glossy, Diffuse, Transmission Depth."""
    scene = scenes.reset()
    scenes.set_resolution(RES, RES)
    mat, tree, out = _material("LightPathEmission")
    em = node(tree, "ShaderNodeEmission")
    em.inputs["Strength"].default_value = 1.0
    link(tree, em.outputs[0], out.inputs["Surface"])
    o = node(tree, "ShaderNodeLightPath").outputs
    to_color(tree, em.inputs["Color"],
             weighted(tree, [(o["Is Camera Ray"], 0.5), (o["Ray Length"], 0.1)], 0.05),
             weighted(tree, [(o["Is Glossy Ray"], 0.4), (o["Is Singular Ray"], 0.2),
                             (o["Is Reflection Ray"], 0.1), (o["Is Transmission Ray"], 0.05),
                             (o["Is Diffuse Ray"], 0.025)], 0.05),
             weighted(tree, [(o["Ray Depth"], 0.4), (o["Glossy Depth"], 0.2),
                             (o["Diffuse Depth"], 0.1), (o["Transmission Depth"], 0.05)],
                      0.05))
    mirror, tree, out = _material("Mirror")
    gl = node(tree, "ShaderNodeBsdfGlossy")
    gl.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    gl.inputs["Roughness"].default_value = 0.0
    link(tree, gl.outputs[0], out.inputs["Surface"])
    scenes.add_plane(size=1.4, location=(1.0, 0.0, 0.0), material=mirror, name="Mirror",
                     rotation=(0.0, math.radians(-45.0), 0.0))
    scenes.add_plane(size=3.0, location=(-1.9, 0.0, 0.0), material=mat, name="Wall",
                     rotation=(0.0, math.radians(90.0), 0.0))
    scenes.add_plane(size=1.2, location=(-0.9, 0.0, -1.0), material=mat, name="Floor")
    scenes.add_camera(location=(0.0, 0.0, 5.0), look_at=(0.0, 0.0, 0.0), ortho_scale=4.0)
    return scene


def test_light_path_through_the_engine_matches_cycles():
    """Seen directly (the floor emitter: Is Camera Ray 1, depth 0) and through the mirror
    (the wall: Is Glossy, Singular and Reflection Ray 1, Ray Depth and Glossy Depth 1, Is
    Camera Ray 0, Ray Length from the mirror): per pixel within 1 % of Cycles where both
    see one surface (a pixel from every edge), the means within 0.2 %."""
    scene = mirror_scene()
    cycles = cr.render_cycles(scene, 16)
    ours = cr.render_photon_map(scene, 16)["Combined"][..., :3]
    c = (np.arange(RES) + 0.5) / RES * 4.0 - 2.0
    X, Y = np.meshgrid(c, -c)
    px = 4.0 / RES
    inner_y = np.abs(Y) < 0.7 - px
    direct = (np.abs(X + 0.9) < 0.6 - px) & (np.abs(Y) < 0.6 - px)
    mirrored = (np.abs(X - 1.0) < 0.7 / math.sqrt(1.0) * 0.7071 * 1.4 / 1.4 - px) & inner_y
    err = np.abs(ours - cycles) / np.maximum(cycles, 1e-3)
    for name, sel in (("direct", direct), ("mirror", mirrored)):
        print(name, "ours", ours[sel].mean(0), "cycles", cycles[sel].mean(0),
              "max relative error", float(err[sel].max()), "pixels", int(sel.sum()))
        assert sel.sum() >= 20
        assert err[sel].max() < 0.01
        np.testing.assert_allclose(ours[sel].mean(0), cycles[sel].mean(0), rtol=2e-3)
    # what the flags are: Is Camera Ray directly, glossy + singular + reflection after
    np.testing.assert_allclose(ours[direct][:, 1], 0.05, rtol=1e-5)
    np.testing.assert_allclose(ours[direct][:, 2], 0.05, rtol=1e-5)
    np.testing.assert_allclose(ours[mirrored][:, 1], 0.05 + 0.4 + 0.2 + 0.1, rtol=1e-5)
    np.testing.assert_allclose(ours[mirrored][:, 2], 0.05 + 0.4 + 0.2, rtol=1e-5)


def test_is_shadow_ray_alpha_casts_a_partial_shadow_like_cycles():
    """Principled Alpha = 1 - 0.75 Is Shadow Ray on a leaf at z = 1 under a 45-degree sun:
    the camera sees it opaque; its shadow on the floor (y in [1, 3]) is 0.75 of the sun
    in both renderers."""
    def shadow_alpha(tree):
        lp = node(tree, "ShaderNodeLightPath")
        return scaled(tree, lp.outputs["Is Shadow Ray"], -0.75, 1.0)

    scene = leaf_scene(shadow_alpha)
    cycles = cr.render_cycles(scene, 16)
    ours = cr.render_photon_map(scene, 16)["Combined"][..., :3]
    c = (np.arange(RES) + 0.5) / RES * 4.0 - 2.0
    X, Y = np.meshgrid(c, -c)
    px = 4.0 / RES
    shadow = (Y > 1.0 + px) & (Y < 3.0 - px) & (np.abs(X) < 1.0 - px)
    lit = (Y < -1.0 - px) & (np.abs(X) < 1.0 - px)
    leaf = (np.abs(X) < 1.0 - px) & (np.abs(Y) < 1.0 - px)
    ratio = {name: float(img[shadow][:, 0].mean() / img[lit][:, 0].mean())
             for name, img in (("ours", ours), ("cycles", cycles))}
    print("shadow / lit", ratio, "leaf", ours[leaf].mean(0), cycles[leaf].mean(0))
    assert abs(ratio["ours"] - 0.75) < 1e-3
    assert abs(ratio["ours"] / ratio["cycles"] - 1) < 0.01
    # opaque to the camera: the leaf's own colour, not the floor's
    np.testing.assert_allclose(ours[leaf].mean(0), cycles[leaf].mean(0), rtol=0.02)
