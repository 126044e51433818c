"""The shader nodes against Cycles: for each node, a plane whose Emission colour is driven
by it (through Texture Coordinate, Geometry or UV inputs), rendered by Cycles in this bpy
process at the pixel centres, and the node graph compiled by photon_engine/export_shader.py
and run by the core interpreter at the same surface points (tests/blender/shader_scenes.py).

Agreement: |ours - Cycles| / max(1, |Cycles|) <= 1e-3 per pixel and channel (beyond our
own value's variation within the filter's +-0.005 pixel footprint), on the pixels where
our value does not jump by more than 0.02 within that footprint (a discontinuity: floor,
a Voronoi cell edge, a checker square's border; at most 30 % of a plane). Cycles places a few samples (measured:
8 of 2048 pixels at 4 samples) up to ~0.15 pixel off the centre even with a 0.01-pixel
filter, so 99 % of each plane's pixels must agree to 1e-3, and all of them within 1e-3
beyond our value's variation within 0.2 pixel of the centre.
"""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import shader_scenes as ss  # noqa: E402

pytestmark = [pytest.mark.blender]

TOL = 1e-3


# --- graph helpers ---------------------------------------------------------------------

def node(tree, idname, **props):
    n = tree.nodes.new(idname)
    for k, v in props.items():
        setattr(n, k, v)
    return n


def link(tree, out, into):
    tree.links.new(out, into)


def uv_scalars(tree, sx=4.0, ox=-2.0, sy=3.0, oy=-1.0):
    """Two scalars from the UV: a = sx * u + ox, b = sy * v + oy (Math nodes)."""
    tc = node(tree, "ShaderNodeTexCoord")
    sep = node(tree, "ShaderNodeSeparateXYZ")
    link(tree, tc.outputs["UV"], sep.inputs[0])
    out = []
    for comp, s, o in ((0, sx, ox), (1, sy, oy)):
        m = node(tree, "ShaderNodeMath", operation='MULTIPLY_ADD')
        link(tree, sep.outputs[comp], m.inputs[0])
        m.inputs[1].default_value = s
        m.inputs[2].default_value = o
        out.append(m.outputs[0])
    return out


def to_color(tree, color, r, g=None, b=None):
    comb = node(tree, "ShaderNodeCombineXYZ")
    for i, s in enumerate((r, g, b)):
        if s is not None:
            link(tree, s, comb.inputs[i])
    link(tree, comb.outputs[0], color)


def check(result, names, tol=TOL):
    """Every plane: 99 % of the non-edge pixels within tol, all within tol beyond the
    0.2-pixel variation, at most 30 % edge pixels; returns {name: (max error, 99th
    percentile, edge fraction, max loose error)} on the non-edge pixels."""
    figures = ss.per_plane(result, lambda e, edge, loose: (
        float(e[~edge].max()) if (~edge).any() else 0.0,
        float(np.percentile(e[~edge], 99)) if (~edge).any() else 0.0,
        float(edge.mean()),
        float(loose[~edge].max()) if (~edge).any() else 0.0))
    bad = {}
    for name, (worst, p99, edge, loose) in zip(names, figures):
        if p99 > tol or loose > tol or edge > 0.3:
            bad[name] = (worst, p99, edge, loose)
    assert not bad, f"planes off Cycles (max, p99, edge fraction, loose max): {bad}"
    return dict(zip(names, figures))


# --- Math, inputs ----------------------------------------------------------------------

MATH_OPS = ["ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "MULTIPLY_ADD", "POWER", "LOGARITHM",
            "SQRT", "INVERSE_SQRT", "ABSOLUTE", "EXPONENT", "MINIMUM", "MAXIMUM",
            "LESS_THAN", "GREATER_THAN", "SIGN", "COMPARE", "SMOOTH_MIN", "SMOOTH_MAX",
            "ROUND", "FLOOR", "CEIL", "TRUNC", "FRACT", "MODULO", "FLOORED_MODULO", "WRAP",
            "SNAP", "PINGPONG", "SINE", "COSINE", "TANGENT", "ARCSINE", "ARCCOSINE",
            "ARCTANGENT", "ARCTAN2", "SINH", "COSH", "TANH", "RADIANS", "DEGREES"]


def math_plane(ops, use_clamp=False):
    def build(tree, color):
        a, b = uv_scalars(tree, sy=1.5, oy=0.5)
        outs = []
        for op in ops:
            m = node(tree, "ShaderNodeMath", operation=op, use_clamp=use_clamp)
            link(tree, a, m.inputs[0])
            link(tree, b, m.inputs[1])
            m.inputs[2].default_value = 0.7
            outs.append(m.outputs[0])
        to_color(tree, color, *outs)
    return build


def input_plane(kind):
    def build(tree, color):
        if kind in ("Generated", "Normal", "UV", "Object"):
            tc = node(tree, "ShaderNodeTexCoord")
            link(tree, tc.outputs[kind], color)
        elif kind == "UVMap":
            uvm = node(tree, "ShaderNodeUVMap", uv_map="UVMap")
            link(tree, uvm.outputs[0], color)
        elif kind == "Location":
            oi = node(tree, "ShaderNodeObjectInfo")
            link(tree, oi.outputs["Location"], color)
        else:
            geo = node(tree, "ShaderNodeNewGeometry")
            link(tree, geo.outputs[kind], color)
    return build


INPUTS = ["Generated", "Normal", "UV", "Object", "UVMap", "Position", "True Normal",
          "Incoming", "Backfacing", "Location"]


def test_inputs_and_every_math_operation_match_cycles():
    specs = [(f"In {k}", input_plane(k)) for k in INPUTS]
    groups = [MATH_OPS[i:i + 3] for i in range(0, len(MATH_OPS), 3)]
    specs += [("Math " + "/".join(g), math_plane(g)) for g in groups]
    specs += [("Math clamp", math_plane(["SUBTRACT", "MULTIPLY", "SINH"], use_clamp=True))]
    result = ss.compare(specs)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in specs])


# --- Vector Math -------------------------------------------------------------------------

VECTOR_OPS = ["ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "MULTIPLY_ADD", "CROSS_PRODUCT",
              "PROJECT", "REFLECT", "REFRACT", "FACEFORWARD", "DOT_PRODUCT", "DISTANCE",
              "LENGTH", "SCALE", "NORMALIZE", "ABSOLUTE", "POWER", "SIGN", "MINIMUM",
              "MAXIMUM", "FLOOR", "CEIL", "FRACTION", "MODULO", "WRAP", "SNAP", "ROUND",
              "SINE", "COSINE", "TANGENT"]


def vector_plane(op):
    def build(tree, color):
        tc = node(tree, "ShaderNodeTexCoord")
        m1 = node(tree, "ShaderNodeMapping", vector_type='POINT')
        link(tree, tc.outputs["Object"], m1.inputs["Vector"])
        m1.inputs["Scale"].default_value = (1.7, 1.3, 1.0)
        m1.inputs["Location"].default_value = (0.2, -0.1, 0.4)
        vm = node(tree, "ShaderNodeVectorMath", operation=op)
        link(tree, m1.outputs[0], vm.inputs[0])
        m2 = node(tree, "ShaderNodeMapping", vector_type='POINT')  # b in [0.5, 1.5]: no
        link(tree, tc.outputs["Generated"], m2.inputs["Vector"])  # chaotic a mod ~0
        m2.inputs["Location"].default_value = (0.5, 0.5, 0.0)
        link(tree, m2.outputs[0], vm.inputs[1])
        if vm.inputs.get("Vector_002") is not None or len(vm.inputs) > 2:
            vm.inputs[2].default_value = (0.3, -0.5, 0.8)
        if vm.inputs.get("Scale") is not None:
            vm.inputs["Scale"].default_value = 0.6
        out = vm.outputs["Value"] if op in ("DOT_PRODUCT", "DISTANCE", "LENGTH") \
            else vm.outputs["Vector"]
        link(tree, out, color)
    return build


def test_every_vector_math_operation_matches_cycles():
    specs = [(f"VMath {op}", vector_plane(op)) for op in VECTOR_OPS]
    result = ss.compare(specs)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in specs])
