"""The measured agreement of every shader node test plane with Cycles (docs/shading.md's
table): renders the scenes of tests/blender/test_shader_nodes.py, test_shader_nodes_view.py,
test_shader_voronoi_1d4d.py, test_shader_images.py and test_shader_attributes.py and
prints, per plane,
the 99th-percentile per-pixel error (relative to max(1, |Cycles|)) on the non-edge
pixels, the worst error beyond our value's variation within 0.2 pixel (Cycles' occasional
off-centre sample) and at the centre, and the fraction of edge pixels.

    .venv/bin/python tools/shader_agreement.py > /tmp/agreement.md
    .venv/bin/python tools/shader_agreement.py "Fresnel" "HSL"   # only the scenes named so
    .venv/bin/python tools/shader_agreement.py "Image" "Attributes"
"""

from __future__ import annotations

import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from tests.blender import shader_scenes as ss  # noqa: E402
from tests.blender import test_shader_nodes as t  # noqa: E402
from tests.blender import test_shader_nodes_view as tv  # noqa: E402
from tests.blender import test_shader_voronoi_1d4d as tvw  # noqa: E402


def scenes():
    yield "Inputs", [(f"{k}", t.input_plane(k)) for k in t.INPUTS]
    yield "Math", [("Math " + op, t.math_plane([op])) for op in t.MATH_OPS]
    yield "Vector Math", [(f"Vector Math {op}", t.vector_plane(op)) for op in
                         t.available("ShaderNodeVectorMath", "operation", t.VECTOR_OPS)]
    specs = [(f"Mix colour {b}", t.mix_color_plane(b)) for b in t.BLENDS]
    specs += [("Mix float", t.mix_plane('FLOAT')), ("Mix vector", t.mix_plane('VECTOR')),
              ("Mix vector non-uniform", t.mix_plane('VECTOR', nonuniform=True))]
    for kind in ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP"):
        specs += [(f"Map Range {kind}", t.map_range_plane(kind)),
                  (f"Map Range vector {kind}", t.map_range_plane(kind, vector=True))]
    specs += [("Clamp MINMAX", t.clamp_plane("MINMAX")), ("Clamp RANGE", t.clamp_plane("RANGE")),
              ("Separate/Combine Color RGB", t.separate_combine_plane("RGB")),
              ("Separate/Combine Color HSV", t.separate_combine_plane("HSV"))]
    specs += [(f"ColorRamp {i}", t.ramp_plane(i)) for i in ("LINEAR", "CONSTANT", "EASE",
                                                            "CARDINAL", "B_SPLINE")]
    specs += [(f"Mapping {k}", t.mapping_plane(k)) for k in ("POINT", "TEXTURE", "VECTOR",
                                                           "NORMAL")]
    specs += [("Invert", t.color_node_plane("ShaderNodeInvert", {"Fac": 0.7})),
              ("Gamma", t.color_node_plane("ShaderNodeGamma", {"Gamma": 2.2})),
              ("Hue/Saturation/Value", t.color_node_plane(
                  "ShaderNodeHueSaturation", {"Hue": 0.3, "Saturation": 1.4, "Value": 0.8,
                                              "Fac": 0.9})),
              ("Brightness/Contrast", t.color_node_plane(
                  "ShaderNodeBrightContrast", {"Bright": 0.1, "Contrast": 0.4})),
              ("RGB to BW", t.color_node_plane("ShaderNodeRGBToBW", {}))]
    yield "Converters and colour", specs
    specs = [(f"Noise {d}", t.noise_plane(d)) for d in ("1D", "2D", "3D", "4D")]
    specs += [(f"Noise {d} distortion 0.7", t.noise_plane(d, Distortion=0.7))
              for d in ("2D", "3D")]
    for kind in ("MULTIFRACTAL", "HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL",
                 "HETERO_TERRAIN"):
        specs += [(f"Noise {kind}", t.noise_plane("3D", kind, output="Factor", Offset=0.8,
                                                  Gain=1.3, Roughness=0.5))]
    yield "Noise", specs
    specs = []
    for dims in ("2D", "3D"):
        for feature in ("F1", "F2", "SMOOTH_F1"):
            specs += [(f"Voronoi {dims} {feature} colour", t.voronoi_plane(dims, feature)),
                      (f"Voronoi {dims} {feature} distance",
                       t.voronoi_plane(dims, feature, output="Distance"))]
        specs += [(f"Voronoi {dims} distance to edge",
                   t.voronoi_plane(dims, "DISTANCE_TO_EDGE", output="Distance"))]
    for metric in ("MANHATTAN", "CHEBYCHEV", "MINKOWSKI"):
        specs += [(f"Voronoi {metric}", t.voronoi_plane("3D", "F1", metric,
                                                        output="Distance", Exponent=1.5))]
    specs += [("Voronoi position", t.voronoi_plane("3D", "F1", output="Position")),
              ("Voronoi fractal (detail 1.5)", t.voronoi_plane(
                  "3D", "F1", output="Distance", Detail=1.5, Roughness=0.6, Lacunarity=2.2))]
    yield "Voronoi", specs
    yield "Voronoi 1D", tvw.SPECS_1D
    yield "Voronoi 4D", tvw.SPECS_4D
    specs = [("Checker", t.checker_plane)]
    specs += [(f"Gradient {k}", t.gradient_plane(k)) for k in (
        "LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "RADIAL", "QUADRATIC_SPHERE",
        "SPHERICAL")]
    specs += [(f"White Noise {d}", t.white_noise_plane(d)) for d in ("1D", "2D", "3D", "4D")]
    specs += [(f"Wave {w} {d} {p}", t.wave_plane(w, d, p)) for w, d, p in (
        ("BANDS", "X", "SIN"), ("BANDS", "DIAGONAL", "SAW"), ("RINGS", "SPHERICAL", "TRI"))]
    specs += [("Wave distorted", t.wave_plane("BANDS", "Y", "SIN", Distortion=3.0,
                                              Detail=2.5))]
    specs += [(f"Magic depth {d}", t.magic_plane(d)) for d in (0, 2, 5)]
    specs += [("Magic depth 10 (distortion 0.6)", t.magic_plane(10, distortion=0.6))]
    specs += [("Brick", t.brick_plane(0.5, 2, 1.0, 1)),
              ("Brick squashed", t.brick_plane(0.3, 3, 0.6, 2)),
              ("Blackbody", t.blackbody_plane), ("RGB Curves", t.curves_plane(False)),
              ("RGB Curves extrapolated", t.curves_plane(True)),
              ("Float Curve", t.float_curve_plane)]
    specs += [("Group used twice", t.group_twice), ("Group in a group", t.group_in_group)]
    yield "Textures, groups", specs
    yield "Fresnel, Layer Weight, Texture Coordinate", tv.VIEW_SPECS
    yield "HSL, Vector Curves, Wavelength", tv.COLOR_SPECS
    yield from image_and_attribute_scenes()


def image_and_attribute_scenes():
    """tests/blender/test_shader_images.py's interpolation / extension / file-format planes
    (the images written to a temporary folder as the test does) and
    tests/blender/test_shader_attributes.py's attribute planes; (title, specs, setup)."""
    import tempfile

    from tests.blender import test_shader_attributes as ta
    from tests.blender import test_shader_images as ti

    d = pathlib.Path(tempfile.mkdtemp(prefix="shader_agreement_"))
    png = ti.write_png(str(d / "byte.png"), ti.texels(np.uint8))
    png16 = ti.write_png(str(d / "short.png"), ti.texels(np.uint16, 4))
    exr = ti.write_exr(str(d / "float.exr"), ti.texels(np.float32, 5))
    specs = [(f"Image {i} {e}", ti.image_plane(png, i, e))
             for i in ("Linear", "Closest") for e in ("REPEAT", "EXTEND", "CLIP", "MIRROR")]
    specs += [("Image Linear Non-Color", ti.image_plane(png, colorspace="Non-Color")),
              ("Image Cubic", ti.image_plane(png, "Cubic")),
              ("Image 16-bit PNG", ti.image_plane(png16)),
              ("Image float EXR", ti.image_plane(exr, colorspace="Non-Color"))]
    yield "Image Texture", specs, None
    specs = [("Color Attribute corner", ta.color_attribute("ColCorner")),
             ("Color Attribute point", ta.color_attribute("ColPoint")),
             ("Color Attribute byte corner", ta.color_attribute("ByteCorner")),
             ("Color Attribute byte point", ta.color_attribute("BytePoint")),
             ("Color Attribute alpha", ta.color_attribute("ColCorner", "Alpha")),
             ("Attribute vector", ta.attribute("VecCorner", "Vector")),
             ("Attribute float", ta.attribute("FloatPoint", "Fac")),
             ("Attribute face", ta.attribute("FloatFace", "Fac"))]
    yield "Attributes", specs, ta.add_layers


def main():
    print("| node (plane) | 99th percentile | max beyond 0.2 px | max at the centre | edge pixels |")
    print("|---|---:|---:|---:|---:|")
    only = sys.argv[1:]
    for title, specs, *setup in scenes():
        if only and not any(o in title for o in only):
            continue
        result = ss.compare(specs, setup=setup[0] if setup else None)
        figures = ss.per_plane(result, lambda e, edge, loose: (
            float(e[~edge].max()) if (~edge).any() else 0.0,
            float(np.percentile(e[~edge], 99)) if (~edge).any() else 0.0,
            float(edge.mean()),
            float(loose[~edge].max()) if (~edge).any() else 0.0))
        for (name, _), (worst, p99, edge, loose) in zip(specs, figures):
            print(f"| {name} | {p99:.1e} | {loose:.1e} | {worst:.1e} | {100 * edge:.1f} % |")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
