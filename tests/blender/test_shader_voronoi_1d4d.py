"""Voronoi Texture in 1D (W) and 4D (Vector + W) against Cycles, through emission (the
pattern and tolerances of tests/blender/test_shader_nodes.py): every feature (F1, F2,
Smooth F1, Distance to Edge, N-Sphere Radius), every output (Distance, Color, Position,
W, Radius), the four metrics in 4D (1D has one distance, |dw|), the fractal octaves.

Blender 4.x and 5.x place the 4D feature points with different hashes (lookup3 on the
cell's floats, PCG 4D); running on both .venv (5.2) and .venv-4.2 checks both.
"""

import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import shader_scenes as ss  # noqa: E402
from tests.blender.test_shader_nodes import (  # noqa: E402
    check, link, node, object_coords, setdef, uv_scalars)

pytestmark = [pytest.mark.blender, pytest.mark.api]


def voronoi_w_plane(dims="4D", feature="F1", metric="EUCLIDEAN", output="Color", **values):
    """A Voronoi node in 1D or 4D: Vector from the object coordinates (4D; 5.x drops the
    socket in 1D), W = 2.1 u - 0.4 (about 6 cells across the plane at scale 3)."""
    def build(tree, color):
        vec, _ = object_coords(tree)
        v = node(tree, "ShaderNodeTexVoronoi", voronoi_dimensions=dims, feature=feature,
                 distance=metric)
        sock = next((s for s in v.inputs if s.identifier == "Vector"), None)
        if sock is not None:
            link(tree, vec, sock)
        link(tree, uv_scalars(tree, sx=2.1, ox=-0.4)[0], v.inputs["W"])
        for k, val in {"Scale": 3.0, **values}.items():
            setdef(v, k, val)
        link(tree, v.outputs[output], color)
    return build


SPECS_1D = [
    ("Voronoi 1D F1 colour", voronoi_w_plane("1D", "F1")),
    ("Voronoi 1D F1 distance", voronoi_w_plane("1D", "F1", output="Distance")),
    ("Voronoi 1D F1 W", voronoi_w_plane("1D", "F1", output="W")),
    ("Voronoi 1D F2 colour", voronoi_w_plane("1D", "F2")),
    ("Voronoi 1D F2 distance", voronoi_w_plane("1D", "F2", output="Distance")),
    ("Voronoi 1D SMOOTH_F1 colour", voronoi_w_plane("1D", "SMOOTH_F1")),
    ("Voronoi 1D SMOOTH_F1 W", voronoi_w_plane("1D", "SMOOTH_F1", output="W")),
    ("Voronoi 1D distance to edge", voronoi_w_plane("1D", "DISTANCE_TO_EDGE",
                                                    output="Distance")),
    ("Voronoi 1D N-Sphere Radius", voronoi_w_plane("1D", "N_SPHERE_RADIUS",
                                                   output="Radius")),
    ("Voronoi 1D fractal (detail 1.5)", voronoi_w_plane(
        "1D", "F1", output="Distance", Detail=1.5, Roughness=0.6, Lacunarity=2.2)),
    ("Voronoi 1D fractal edge (detail 2)", voronoi_w_plane(
        "1D", "DISTANCE_TO_EDGE", output="Distance", Detail=2.0)),
]

SPECS_4D = [
    ("Voronoi 4D F1 colour", voronoi_w_plane("4D", "F1")),
    ("Voronoi 4D F1 distance", voronoi_w_plane("4D", "F1", output="Distance")),
    ("Voronoi 4D F1 position", voronoi_w_plane("4D", "F1", output="Position")),
    ("Voronoi 4D F1 W", voronoi_w_plane("4D", "F1", output="W")),
    ("Voronoi 4D F2 colour", voronoi_w_plane("4D", "F2")),
    ("Voronoi 4D F2 distance", voronoi_w_plane("4D", "F2", output="Distance")),
    ("Voronoi 4D SMOOTH_F1 colour", voronoi_w_plane("4D", "SMOOTH_F1")),
    ("Voronoi 4D SMOOTH_F1 distance", voronoi_w_plane("4D", "SMOOTH_F1", output="Distance")),
    ("Voronoi 4D distance to edge", voronoi_w_plane("4D", "DISTANCE_TO_EDGE",
                                                    output="Distance")),
    ("Voronoi 4D N-Sphere Radius", voronoi_w_plane("4D", "N_SPHERE_RADIUS",
                                                   output="Radius", Randomness=0.8)),
    ("Voronoi 4D MANHATTAN", voronoi_w_plane("4D", "F1", "MANHATTAN", output="Distance")),
    ("Voronoi 4D CHEBYCHEV", voronoi_w_plane("4D", "F1", "CHEBYCHEV", output="Distance")),
    ("Voronoi 4D MINKOWSKI", voronoi_w_plane("4D", "F2", "MINKOWSKI", output="Distance",
                                             Exponent=1.5)),
    ("Voronoi 4D fractal (detail 1.5)", voronoi_w_plane(
        "4D", "F1", output="Distance", Detail=1.5, Roughness=0.6, Lacunarity=2.2)),
    ("Voronoi 4D random 0.4", voronoi_w_plane("4D", "F1", Randomness=0.4)),
]


def test_voronoi_1d_matches_cycles():
    result = ss.compare(SPECS_1D)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in SPECS_1D])


def test_voronoi_4d_matches_cycles():
    result = ss.compare(SPECS_4D)
    assert not result["warnings"], result["warnings"]
    check(result, [n for n, _ in SPECS_4D])
