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

pytestmark = [pytest.mark.blender, pytest.mark.api]  # passes on 4.2 and 5.2

TOL = 1e-3


# --- graph helpers ---------------------------------------------------------------------

def node(tree, idname, **props):
    n = tree.nodes.new(idname)
    for k, v in props.items():
        setattr(n, k, v)
    return n


def inp(n, identifier):
    """The input socket of node n with this identifier (bpy's [key] looks up names)."""
    return next(s for s in n.inputs if s.identifier == identifier)


def setdef(n, identifier, value):
    """Set an input's default when the node declares it in its current mode (5.x drops
    unavailable sockets)."""
    sock = next((s for s in n.inputs if s.identifier == identifier), None)
    if sock is not None:
        sock.default_value = value


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
    """Every plane: 99 % of the non-edge pixels within tol, at most 0.5 % (5 of 1024)
    beyond tol even allowing the 0.2-pixel variation, at most 30 % edge pixels; returns
    {name: (max error, 99th percentile, edge fraction, fraction beyond the 0.2-pixel
    variation)} on the non-edge pixels."""
    figures = ss.per_plane(result, lambda e, edge, loose: (
        float(e[~edge].max()) if (~edge).any() else 0.0,
        float(np.percentile(e[~edge], 99)) if (~edge).any() else 0.0,
        float(edge.mean()),
        float((loose[~edge] > tol).mean()) if (~edge).any() else 0.0))
    bad = {}
    for name, (worst, p99, edge, loose) in zip(names, figures):
        if p99 > tol or loose > 0.005 or edge > 0.3:
            bad[name] = (worst, p99, edge, loose)
    assert not bad, f"planes off Cycles (max, p99, edge fraction, fraction beyond 0.2 px): {bad}"
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
    ops = available("ShaderNodeMath", "operation", MATH_OPS)
    groups = [ops[i:i + 3] for i in range(0, len(ops), 3)]
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


def available(idname, prop, names):
    """The names this Blender's enum ``prop`` of node type ``idname`` offers (4.2 has no
    Vector Math Power, Sign, Round)."""
    items = getattr(bpy.types, idname).bl_rna.properties[prop].enum_items.keys()
    return [n for n in names if n in items]


def vector_plane(op):
    def build(tree, color):
        tc = node(tree, "ShaderNodeTexCoord")
        m1 = node(tree, "ShaderNodeMapping", vector_type='POINT')
        link(tree, tc.outputs["Object"], m1.inputs["Vector"])
        setdef(m1, "Scale", (1.7, 1.3, 1.0))
        setdef(m1, "Location", (0.2, -0.1, 0.4))
        vm = node(tree, "ShaderNodeVectorMath", operation=op)
        link(tree, m1.outputs[0], vm.inputs[0])
        m2 = node(tree, "ShaderNodeMapping", vector_type='POINT')  # b in [0.5, 1.5]: no
        link(tree, tc.outputs["Generated"], m2.inputs["Vector"])  # chaotic a mod ~0
        setdef(m2, "Location", (0.5, 0.5, 0.0))
        link(tree, m2.outputs[0], vm.inputs[1])
        if vm.inputs.get("Vector_002") is not None or len(vm.inputs) > 2:
            vm.inputs[2].default_value = (0.3, -0.5, 0.8)
        if vm.inputs.get("Scale") is not None:
            setdef(vm, "Scale", 0.6)
        out = vm.outputs["Value"] if op in ("DOT_PRODUCT", "DISTANCE", "LENGTH") \
            else vm.outputs["Vector"]
        link(tree, out, color)
    return build


def test_every_vector_math_operation_matches_cycles():
    specs = [(f"VMath {op}", vector_plane(op))
             for op in available("ShaderNodeVectorMath", "operation", VECTOR_OPS)]
    result = ss.compare(specs)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in specs])


# --- converters and colour ---------------------------------------------------------------

BLENDS = ["MIX", "DARKEN", "MULTIPLY", "BURN", "LIGHTEN", "SCREEN", "DODGE", "ADD",
          "OVERLAY", "SOFT_LIGHT", "LINEAR_LIGHT", "DIFFERENCE", "EXCLUSION", "SUBTRACT",
          "DIVIDE", "HUE", "SATURATION", "COLOR", "VALUE"]


def two_colors(tree):
    """Colour A = (u, v, 0.3) and colour B = a rotated, scaled copy: smooth, in [0, 1.2]."""
    tc = node(tree, "ShaderNodeTexCoord")
    a = node(tree, "ShaderNodeMapping", vector_type='POINT')
    link(tree, tc.outputs["UV"], a.inputs["Vector"])
    setdef(a, "Location", (0.0, 0.0, 0.3))
    bm = node(tree, "ShaderNodeMapping", vector_type='POINT')
    link(tree, tc.outputs["Generated"], bm.inputs["Vector"])
    setdef(bm, "Rotation", (0.3, 0.2, 0.9))
    setdef(bm, "Scale", (0.8, 1.1, 0.7))
    setdef(bm, "Location", (0.2, 0.1, 0.0))
    return a.outputs[0], bm.outputs[0], tc


def mix_color_plane(blend, clamp_result=False, factor=0.65):
    def build(tree, color):
        a, b, _ = two_colors(tree)
        m = node(tree, "ShaderNodeMix", data_type='RGBA', blend_type=blend,
                 clamp_result=clamp_result)
        setdef(m, "Factor_Float", factor)
        link(tree, a, inp(m, "A_Color"))
        link(tree, b, inp(m, "B_Color"))
        link(tree, next(o for o in m.outputs if o.identifier == "Result_Color"), color)
    return build


def mix_plane(data_type, nonuniform=False):
    def build(tree, color):
        a, b, tc = two_colors(tree)
        m = node(tree, "ShaderNodeMix", data_type=data_type, clamp_factor=False)
        if data_type == 'FLOAT':
            sa, sb = uv_scalars(tree)
            link(tree, sa, inp(m, "Factor_Float"))
            setdef(m, "A_Float", 0.2)
            link(tree, sb, inp(m, "B_Float"))
            link(tree, next(o for o in m.outputs if o.identifier == "Result_Float"), color)
            return
        m.factor_mode = 'NON_UNIFORM' if nonuniform else 'UNIFORM'
        if nonuniform:
            link(tree, tc.outputs["Generated"], inp(m, "Factor_Vector"))
        else:
            link(tree, uv_scalars(tree)[0], inp(m, "Factor_Float"))
        link(tree, a, inp(m, "A_Vector"))
        link(tree, b, inp(m, "B_Vector"))
        link(tree, next(o for o in m.outputs if o.identifier == "Result_Vector"), color)
    return build


def map_range_plane(kind, vector=False, clamp=True):
    def build(tree, color):
        m = node(tree, "ShaderNodeMapRange", interpolation_type=kind, clamp=clamp,
                 data_type='FLOAT_VECTOR' if vector else 'FLOAT')
        if vector:
            a, _, _ = two_colors(tree)
            link(tree, a, m.inputs["Vector"])
            setdef(m, "From_Min_FLOAT3", (0.2, 0.9, 0.1))
            setdef(m, "From_Max_FLOAT3", (0.8, 0.1, 0.5))
            setdef(m, "To_Min_FLOAT3", (-0.5, 0.0, 1.0))
            setdef(m, "To_Max_FLOAT3", (1.5, 2.0, 0.0))
            setdef(m, "Steps_FLOAT3", (4.0, 3.0, 5.0))
            link(tree, m.outputs["Vector"], color)
            return
        sa, sb = uv_scalars(tree)
        link(tree, sa, m.inputs["Value"])
        setdef(m, "From Min", -1.0)
        setdef(m, "From Max", 1.5)
        setdef(m, "To Min", 2.0)
        setdef(m, "To Max", -0.5)
        setdef(m, "Steps", 5.0)
        to_color(tree, color, m.outputs["Result"], sb)
    return build


def clamp_plane(kind):
    def build(tree, color):
        sa, sb = uv_scalars(tree)
        c = node(tree, "ShaderNodeClamp", clamp_type=kind)
        link(tree, sa, c.inputs["Value"])
        setdef(c, "Min", 0.8)
        link(tree, sb, c.inputs["Max"])
        to_color(tree, color, c.outputs[0])
    return build


def separate_combine_plane(mode):
    def build(tree, color):
        a, b, _ = two_colors(tree)
        sep = node(tree, "ShaderNodeSeparateColor", mode=mode)
        link(tree, b, sep.inputs[0])
        comb = node(tree, "ShaderNodeCombineColor", mode=mode)
        link(tree, sep.outputs[1], comb.inputs[0])
        link(tree, sep.outputs[2], comb.inputs[1])
        link(tree, sep.outputs[0], comb.inputs[2])
        link(tree, comb.outputs[0], color)
    return build


def ramp_plane(interpolation, alpha=False):
    def build(tree, color):
        sa, _ = uv_scalars(tree, sx=1.2, ox=-0.1)
        r = node(tree, "ShaderNodeValToRGB")
        ramp = r.color_ramp
        ramp.interpolation = interpolation
        ramp.elements[0].position = 0.1
        ramp.elements[0].color = (0.9, 0.1, 0.2, 0.3)
        ramp.elements[1].position = 0.85
        ramp.elements[1].color = (0.1, 0.7, 1.0, 1.0)
        e = ramp.elements.new(0.4)
        e.color = (0.2, 0.9, 0.05, 0.6)
        link(tree, sa, r.inputs[0])
        link(tree, r.outputs["Alpha" if alpha else "Color"], color)
    return build


def mapping_plane(kind):
    def build(tree, color):
        tc = node(tree, "ShaderNodeTexCoord")
        m = node(tree, "ShaderNodeMapping", vector_type=kind)
        link(tree, tc.outputs["Object"], m.inputs["Vector"])
        if m.inputs.get("Location") is not None and m.inputs["Location"].enabled:
            setdef(m, "Location", (0.3, -0.2, 0.1))
        setdef(m, "Rotation", (0.4, -0.7, 1.1))
        setdef(m, "Scale", (1.5, 0.6, 2.0))
        link(tree, m.outputs[0], color)
    return build


def color_node_plane(idname, values):
    def build(tree, color):
        _, b, _ = two_colors(tree)
        n = node(tree, idname)
        link(tree, b, n.inputs["Color"])
        for k, v in values.items():
            n.inputs[k].default_value = v
        link(tree, n.outputs[0], color)
    return build


def test_mix_map_range_ramp_mapping_and_colour_nodes_match_cycles():
    specs = [(f"Mix {b}", mix_color_plane(b)) for b in BLENDS]
    specs += [("Mix clamped", mix_color_plane("LINEAR_LIGHT", clamp_result=True, factor=1.3)),
              ("Mix float", mix_plane('FLOAT')), ("Mix vector", mix_plane('VECTOR')),
              ("Mix vector non-uniform", mix_plane('VECTOR', nonuniform=True))]
    for kind in ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP"):
        specs += [(f"Map Range {kind}", map_range_plane(kind)),
                  (f"Map Range vector {kind}", map_range_plane(kind, vector=True))]
    specs += [("Map Range unclamped", map_range_plane("LINEAR", clamp=False)),
              ("Clamp MINMAX", clamp_plane("MINMAX")), ("Clamp RANGE", clamp_plane("RANGE")),
              ("Separate/Combine RGB", separate_combine_plane("RGB")),
              ("Separate/Combine HSV", separate_combine_plane("HSV"))]
    specs += [(f"Ramp {i}", ramp_plane(i)) for i in ("LINEAR", "CONSTANT", "EASE",
                                                     "CARDINAL", "B_SPLINE")]
    specs += [("Ramp alpha", ramp_plane("LINEAR", alpha=True))]
    specs += [(f"Mapping {k}", mapping_plane(k)) for k in ("POINT", "TEXTURE", "VECTOR",
                                                         "NORMAL")]
    specs += [("Invert", color_node_plane("ShaderNodeInvert", {"Fac": 0.7})),
              ("Gamma", color_node_plane("ShaderNodeGamma", {"Gamma": 2.2})),
              ("Hue/Saturation/Value", color_node_plane(
                  "ShaderNodeHueSaturation", {"Hue": 0.3, "Saturation": 1.4, "Value": 0.8,
                                              "Fac": 0.9})),
              ("Brightness/Contrast", color_node_plane(
                  "ShaderNodeBrightContrast", {"Bright": 0.1, "Contrast": 0.4})),
              ("RGB to BW", color_node_plane("ShaderNodeRGBToBW", {}))]
    result = ss.compare(specs)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in specs])


# --- textures ------------------------------------------------------------------------------

def object_coords(tree, scale=1.0):
    tc = node(tree, "ShaderNodeTexCoord")
    m = node(tree, "ShaderNodeMapping", vector_type='POINT')
    link(tree, tc.outputs["Object"], m.inputs["Vector"])
    setdef(m, "Scale", (scale, scale, scale))
    setdef(m, "Location", (0.37, -0.21, 0.13))
    return m.outputs[0], tc


def noise_plane(dims="3D", kind="FBM", output="Color", normalize=True, **values):
    def build(tree, color):
        vec, tc = object_coords(tree)
        n = node(tree, "ShaderNodeTexNoise", noise_dimensions=dims, noise_type=kind,
                 normalize=normalize)
        if n.inputs.get("Vector") is not None:
            link(tree, vec, n.inputs["Vector"])
        if dims in ("1D", "4D"):
            link(tree, uv_scalars(tree, sx=1.3, ox=0.2)[0], n.inputs["W"])
        for k, v in {"Scale": 2.5, "Detail": 2.5, "Roughness": 0.6, "Lacunarity": 2.1,
                     **values}.items():
            setdef(n, k, v)
        link(tree, n.outputs[{"Factor": 0, "Color": 1}[output]], color)  # 4.x: "Fac"
    return build


def voronoi_plane(dims="3D", feature="F1", metric="EUCLIDEAN", output="Color", **values):
    def build(tree, color):
        vec, _ = object_coords(tree)
        v = node(tree, "ShaderNodeTexVoronoi", voronoi_dimensions=dims, feature=feature,
                 distance=metric)
        link(tree, vec, v.inputs["Vector"])
        for k, val in {"Scale": 3.0, **values}.items():
            setdef(v, k, val)
        link(tree, v.outputs[output], color)
    return build


def test_noise_matches_cycles():
    specs = [(f"Noise {d}", noise_plane(d)) for d in ("1D", "2D", "3D", "4D")]
    specs += [(f"Noise {d} distorted", noise_plane(d, Distortion=0.7)) for d in ("2D", "3D")]
    specs += [("Noise fac", noise_plane(output="Factor")),
              ("Noise unnormalized", noise_plane(normalize=False, output="Factor")),
              ("Noise detail 0", noise_plane(Detail=0.0, output="Factor"))]
    for kind in ("MULTIFRACTAL", "HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL",
                 "HETERO_TERRAIN"):
        specs += [(f"Noise {kind}", noise_plane("3D", kind, output="Factor", Offset=0.8,
                                                Gain=1.3, Roughness=0.5)),
                  (f"Noise {kind} 2D", noise_plane("2D", kind, output="Factor", Offset=0.6,
                                                   Gain=0.9, Roughness=0.4))]
    result = ss.compare(specs)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in specs])


def test_voronoi_matches_cycles():
    specs = []
    for dims in ("2D", "3D"):
        for feature in ("F1", "F2", "SMOOTH_F1"):
            specs += [(f"Voronoi {dims} {feature} colour", voronoi_plane(dims, feature)),
                      (f"Voronoi {dims} {feature} distance",
                       voronoi_plane(dims, feature, output="Distance"))]
        specs += [(f"Voronoi {dims} edge", voronoi_plane(dims, "DISTANCE_TO_EDGE",
                                                        output="Distance"))]
    for metric in ("MANHATTAN", "CHEBYCHEV", "MINKOWSKI"):
        specs += [(f"Voronoi {metric}", voronoi_plane("3D", "F1", metric, output="Distance",
                                                      Exponent=1.5))]
    specs += [("Voronoi position", voronoi_plane("3D", "F1", output="Position")),
              ("Voronoi fractal", voronoi_plane("3D", "F1", output="Distance", Detail=1.5,
                                                Roughness=0.6, Lacunarity=2.2)),
              ("Voronoi fractal edge", voronoi_plane("2D", "DISTANCE_TO_EDGE",
                                                     output="Distance", Detail=2.0)),
              ("Voronoi random 0.4", voronoi_plane("2D", "F2", Randomness=0.4))]
    result = ss.compare(specs)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in specs])


def checker_plane(tree, color):
    vec, _ = object_coords(tree)
    c = node(tree, "ShaderNodeTexChecker")
    link(tree, vec, c.inputs["Vector"])
    setdef(c, "Scale", 3.0)
    setdef(c, "Color1", (0.9, 0.3, 0.1, 1.0))
    setdef(c, "Color2", (0.1, 0.2, 0.8, 1.0))
    link(tree, c.outputs[0], color)


def gradient_plane(kind):
    def build(tree, color):
        vec, _ = object_coords(tree, scale=0.9)
        g = node(tree, "ShaderNodeTexGradient", gradient_type=kind)
        link(tree, vec, g.inputs["Vector"])
        link(tree, g.outputs[0], color)
    return build


def white_noise_plane(dims):
    def build(tree, color):
        vec, _ = object_coords(tree, scale=4.0)
        fl = node(tree, "ShaderNodeVectorMath", operation='FLOOR')  # exact float inputs
        link(tree, vec, fl.inputs[0])
        w = node(tree, "ShaderNodeTexWhiteNoise", noise_dimensions=dims)
        if w.inputs.get("Vector") is not None:
            link(tree, fl.outputs[0], w.inputs["Vector"])
        sep = node(tree, "ShaderNodeSeparateXYZ")
        link(tree, fl.outputs[0], sep.inputs[0])
        if w.inputs.get("W") is not None:
            link(tree, sep.outputs[0], w.inputs["W"])
        link(tree, w.outputs["Color"], color)
    return build


def wave_plane(kind, direction, profile, **values):
    def build(tree, color):
        vec, _ = object_coords(tree, scale=0.3)
        w = node(tree, "ShaderNodeTexWave", wave_type=kind, wave_profile=profile)
        if kind == "BANDS":
            w.bands_direction = direction
        else:
            w.rings_direction = direction
        link(tree, vec, w.inputs["Vector"])
        for k, v in {"Scale": 2.0, "Distortion": 0.0, "Phase Offset": 0.4, **values}.items():
            setdef(w, k, v)
        link(tree, w.outputs[0], color)
    return build


def magic_plane(depth, distortion=1.7):
    def build(tree, color):
        vec, _ = object_coords(tree, scale=0.4)
        m = node(tree, "ShaderNodeTexMagic", turbulence_depth=depth)
        link(tree, vec, m.inputs["Vector"])
        setdef(m, "Distortion", distortion)
        link(tree, m.outputs[0], color)
    return build


def brick_plane(offset, offset_frequency, squash, squash_frequency):
    def build(tree, color):
        vec, _ = object_coords(tree)
        b = node(tree, "ShaderNodeTexBrick", offset=offset, offset_frequency=offset_frequency,
                 squash=squash, squash_frequency=squash_frequency)
        link(tree, vec, b.inputs["Vector"])
        for k, v in {"Scale": 2.0, "Mortar Size": 0.05, "Mortar Smooth": 0.3, "Bias": 0.1,
                     "Brick Width": 0.6, "Row Height": 0.25,
                     "Color1": (0.8, 0.2, 0.1, 1), "Color2": (0.3, 0.6, 0.2, 1),
                     "Mortar": (0.1, 0.1, 0.4, 1)}.items():
            setdef(b, k, v)
        link(tree, b.outputs[0], color)
    return build


def blackbody_plane(tree, color):
    sa, _ = uv_scalars(tree, sx=11000.0, ox=600.0)
    bb = node(tree, "ShaderNodeBlackbody")
    link(tree, sa, bb.inputs["Temperature"])
    link(tree, bb.outputs[0], color)


def curves_plane(extrapolate):
    def build(tree, color):
        a, b, _ = two_colors(tree)
        c = node(tree, "ShaderNodeRGBCurve")
        m = c.mapping
        m.extend = 'EXTRAPOLATED' if extrapolate else 'HORIZONTAL'
        m.curves[3].points.new(0.4, 0.6)
        m.curves[0].points.new(0.3, 0.1)
        m.curves[1].points[1].location = (0.8, 0.9)
        m.curves[2].points[0].location = (0.1, 0.3)
        m.update()
        setdef(c, "Fac", 0.85)
        link(tree, b, c.inputs["Color"])
        link(tree, c.outputs[0], color)
    return build


def float_curve_plane(tree, color):
    sa, sb = uv_scalars(tree, sx=1.4, ox=-0.2)
    c = node(tree, "ShaderNodeFloatCurve")
    c.mapping.curves[0].points.new(0.5, 0.8)
    c.mapping.update()
    link(tree, sa, c.inputs["Value"])
    to_color(tree, color, c.outputs[0], sb)


def test_checker_gradient_white_noise_wave_magic_brick_blackbody_curves_match_cycles():
    specs = [("Checker", checker_plane)]
    specs += [(f"Gradient {k}", gradient_plane(k)) for k in (
        "LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "RADIAL", "QUADRATIC_SPHERE",
        "SPHERICAL")]
    specs += [(f"White noise {d}", white_noise_plane(d)) for d in ("1D", "2D", "3D", "4D")]
    specs += [(f"Wave {w} {d} {p}", wave_plane(w, d, p)) for w, d, p in (
        ("BANDS", "X", "SIN"), ("BANDS", "DIAGONAL", "SAW"), ("RINGS", "SPHERICAL", "TRI"),
        ("RINGS", "Z", "SIN"))]
    specs += [("Wave distorted", wave_plane("BANDS", "Y", "SIN", Distortion=3.0, Detail=2.5))]
    specs += [(f"Magic depth {d}", magic_plane(d)) for d in (0, 2, 5)]
    specs += [("Magic depth 10", magic_plane(10, distortion=0.6))]
    specs += [("Brick", brick_plane(0.5, 2, 1.0, 1)), ("Brick squashed", brick_plane(0.3, 3, 0.6, 2)),
              ("Blackbody", blackbody_plane), ("RGB Curves", curves_plane(False)),
              ("RGB Curves extrapolated", curves_plane(True)), ("Float Curve", float_curve_plane)]
    result = ss.compare(specs)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in specs])


# --- node groups, unsupported nodes, cycles ---------------------------------------------------

def ring_group():
    """A node group: (Vector, Scale = 4.0 by default, Shift) -> Noise colour + Shift."""
    group = bpy.data.node_groups.get("Ring")
    if group is not None:
        return group
    group = bpy.data.node_groups.new("Ring", "ShaderNodeTree")
    group.interface.new_socket("Vector", in_out='INPUT', socket_type='NodeSocketVector')
    scale = group.interface.new_socket("Scale", in_out='INPUT', socket_type='NodeSocketFloat')
    scale.default_value = 4.0
    group.interface.new_socket("Shift", in_out='INPUT', socket_type='NodeSocketFloat')
    group.interface.new_socket("Color", in_out='OUTPUT', socket_type='NodeSocketColor')
    gi = group.nodes.new("NodeGroupInput")
    go = group.nodes.new("NodeGroupOutput")
    n = group.nodes.new("ShaderNodeTexNoise")
    group.links.new(gi.outputs["Vector"], n.inputs["Vector"])
    group.links.new(gi.outputs["Scale"], n.inputs["Scale"])
    reroute = group.nodes.new("NodeReroute")
    group.links.new(n.outputs["Color"], reroute.inputs[0])
    add = group.nodes.new("ShaderNodeMix")
    add.data_type = 'RGBA'
    add.blend_type = 'ADD'
    setdef(add, "Factor_Float", 1.0)
    group.links.new(reroute.outputs[0], inp(add, "A_Color"))
    group.links.new(gi.outputs["Shift"], inp(add, "B_Color"))
    group.links.new(next(o for o in add.outputs if o.identifier == "Result_Color"),
                    go.inputs["Color"])
    return group


def outer_group():
    """A group holding a Ring instance (Scale left at its default) times 0.5."""
    group = bpy.data.node_groups.get("Outer")
    if group is not None:
        return group
    group = bpy.data.node_groups.new("Outer", "ShaderNodeTree")
    group.interface.new_socket("Vector", in_out='INPUT', socket_type='NodeSocketVector')
    group.interface.new_socket("Color", in_out='OUTPUT', socket_type='NodeSocketColor')
    gi = group.nodes.new("NodeGroupInput")
    go = group.nodes.new("NodeGroupOutput")
    ring = group.nodes.new("ShaderNodeGroup")
    ring.node_tree = ring_group()
    group.links.new(gi.outputs["Vector"], ring.inputs["Vector"])
    ring.inputs["Shift"].default_value = 0.25
    half = group.nodes.new("ShaderNodeVectorMath")
    half.operation = 'SCALE'
    group.links.new(ring.outputs["Color"], half.inputs[0])
    setdef(half, "Scale", 0.5)
    group.links.new(half.outputs["Vector"], go.inputs["Color"])
    return group


def group_twice(tree, color):
    vec, _ = object_coords(tree)
    outs = []
    for scale, shift in ((2.0, 0.0), (7.0, -0.3)):
        g = node(tree, "ShaderNodeGroup")
        g.node_tree = ring_group()
        link(tree, vec, g.inputs["Vector"])
        g.inputs["Scale"].default_value = scale
        g.inputs["Shift"].default_value = shift
        outs.append(g.outputs["Color"])
    m = node(tree, "ShaderNodeMix", data_type='RGBA', blend_type='MIX')
    setdef(m, "Factor_Float", 0.4)
    link(tree, outs[0], inp(m, "A_Color"))
    link(tree, outs[1], inp(m, "B_Color"))
    link(tree, next(o for o in m.outputs if o.identifier == "Result_Color"), color)


def group_in_group(tree, color):
    vec, _ = object_coords(tree)
    g = node(tree, "ShaderNodeGroup")
    g.node_tree = outer_group()
    link(tree, vec, g.inputs["Vector"])
    link(tree, g.outputs["Color"], color)


def test_node_groups_twice_and_nested_match_cycles():
    specs = [("Group twice", group_twice), ("Group in group", group_in_group)]
    result = ss.compare(specs)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in specs])


def test_unsupported_node_and_cycle_are_reported_once_with_default_values():
    """A Wireframe node (not supported) feeding two sockets: one warning naming the
    material and the node, its output's default value everywhere (folded: no program); a Math loop:
    reported, no exception, finite values."""
    from photon_map.core.shading import program as pg
    from photon_map.photon_engine.export_shader import compile_sockets

    def magic(tree, color):
        m = node(tree, "ShaderNodeWireframe", name="My Magic")
        add = node(tree, "ShaderNodeVectorMath", operation='ADD')
        link(tree, m.outputs[0], add.inputs[0])
        link(tree, m.outputs[0], add.inputs[1])
        link(tree, add.outputs[0], color)

    def loop(tree, color):
        a = node(tree, "ShaderNodeMath", operation='ADD', name="Loop A")
        b = node(tree, "ShaderNodeMath", operation='MULTIPLY', name="Loop B")
        vec, _ = object_coords(tree)
        sep = node(tree, "ShaderNodeSeparateXYZ")
        link(tree, vec, sep.inputs[0])
        link(tree, sep.outputs[0], a.inputs[0])
        link(tree, a.outputs[0], b.inputs[0])
        link(tree, b.outputs[0], a.inputs[1])
        link(tree, b.outputs[0], color)

    scene, planes, g = ss.layout([("Magic mat", magic), ("Loop mat", loop)])
    ours, warnings = ss.photon_map_image(planes, g)
    magic_warnings = [w for w in warnings if "My Magic" in w]
    assert len(magic_warnings) == 1, warnings
    assert "Magic mat" in magic_warnings[0] and "ShaderNodeWireframe" in magic_warnings[0]
    mat = planes[0].data.materials[0]
    default = np.full(3, mat.node_tree.nodes["My Magic"].outputs[0].default_value)
    block = ours[:ss.PIXELS, :ss.PIXELS]
    np.testing.assert_allclose(block, np.broadcast_to(2 * default, block.shape))  # added twice
    assert any("Loop mat" in w and "cycle" in w for w in warnings), warnings
    assert np.isfinite(ours).all()
    em = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeEmission")
    folded = compile_sockets(mat, [(em.inputs["Color"], pg.TARGET_EMISSION, 0, 0)])
    assert folded.program is None
    np.testing.assert_allclose(folded.constant[0], 2 * default, rtol=1e-6)


def test_unlinked_material_has_no_program_and_constant_subgraphs_fold():
    """Emission with a plain colour: no program, the colour as the constant. A Math chain
    on constants (0.3 * 2 + 0.1) mixed with UV: the chain folds into one constant, only the
    UV input, the Separate and the Mix remain, and the value is exact."""
    from photon_map.core.shading import program as pg
    from photon_map.photon_engine.export_shader import compile_sockets

    def plain(tree, color):
        color.default_value = (0.2, 0.4, 0.6, 1.0)

    def partly(tree, color):
        m1 = node(tree, "ShaderNodeMath", operation='MULTIPLY')
        m1.inputs[0].default_value = 0.3
        m1.inputs[1].default_value = 2.0
        m2 = node(tree, "ShaderNodeMath", operation='ADD')
        link(tree, m1.outputs[0], m2.inputs[0])
        m2.inputs[1].default_value = 0.1
        a, _ = uv_scalars(tree, sx=1.0, ox=0.0)
        mix = node(tree, "ShaderNodeMix", data_type='FLOAT', clamp_factor=False)
        link(tree, m2.outputs[0], inp(mix, "Factor_Float"))
        link(tree, a, inp(mix, "A_Float"))
        setdef(mix, "B_Float", 1.0)
        link(tree, next(o for o in mix.outputs if o.identifier == "Result_Float"), color)

    scene, planes, g = ss.layout([("Plain", plain), ("Partly", partly)])
    compiled, warnings = ss.compile_planes(planes)
    assert not warnings
    plain_result = compiled[0][1]
    assert plain_result.program is None
    np.testing.assert_allclose(plain_result.constant[0], (0.2, 0.4, 0.6), rtol=1e-6)
    prog = compiled[1][1].program
    ops = [pg.OP_NAMES[int(op)] for op in prog.instructions[:, 0]]
    assert ops.count("MATH") == 1, ops  # the UV's multiply-add; 0.3 * 2 + 0.1 folded
    assert "MIX_FLOAT" in ops
    img, _ = ss.photon_map_image(planes, g, compiled=compiled)
    u = ss.plane_inputs(planes[1], g).uv[0, :, 0].reshape(ss.PIXELS, ss.PIXELS)
    block = img[:ss.PIXELS, ss.PIXELS:2 * ss.PIXELS, 0]
    np.testing.assert_allclose(block, u * 0.3 + 0.7, rtol=1e-5)
