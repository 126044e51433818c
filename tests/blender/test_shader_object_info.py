"""Object Info against Cycles through emission (tests/blender/shader_scenes.py): Random
on several objects (Cycles' random_number of each instance's random_id), Color
(``Object.color``) and Object Index (``pass_index``), per pixel to 1e-3 relative to
max(1, |Cycles|)."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import shader_scenes as ss  # noqa: E402
from tests.blender.test_shader_nodes import check, link, node, to_color  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]


def info_plane(output):
    def build(tree, color):
        oi = node(tree, "ShaderNodeObjectInfo")
        if output == "Color":
            link(tree, oi.outputs["Color"], color)
        else:
            to_color(tree, color, oi.outputs[output], oi.outputs[output], oi.outputs[output])
    return build


def test_object_info_random_color_and_index_match_cycles():
    specs = [(f"Random {k}", info_plane("Random")) for k in range(6)]
    specs += [("Color", info_plane("Color")), ("Index", info_plane("Object Index")),
              ("Color 2", info_plane("Color"))]

    def setup(planes):
        rng = np.random.default_rng(11)
        for k, plane in enumerate(planes):
            plane.color = (*rng.uniform(0.0, 1.0, 3), 1.0)
            plane.pass_index = 3 + k

    result = ss.compare(specs, setup=setup)
    assert not result["warnings"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})
    g = result["grid"]
    randoms = [result["ours"][r * ss.PIXELS + 5, c * ss.PIXELS + 5, 0]
               for r, c in [divmod(k, g) for k in range(6)]]
    print("Random per object:", np.round(randoms, 6))
    assert len(set(np.round(randoms, 6))) == 6 and 0.0 <= min(randoms) < max(randoms) <= 1.0
    index = result["ours"][2 * ss.PIXELS + 5, ss.PIXELS + 5]  # plane 7: row 2, column 1
    np.testing.assert_array_equal(index, [10.0, 10.0, 10.0])


def test_object_info_alpha_and_material_index_match_cycles():
    """Object Info Alpha (the object colour's alpha) and Material Index (the material's
    pass index, not the object's) through emission, exactly as Cycles."""
    specs = [("Alpha", info_plane("Alpha")), ("Material Index", info_plane("Material Index")),
             ("Alpha 2", info_plane("Alpha")), ("Material Index 2",
                                                info_plane("Material Index"))]

    def setup(planes):
        for k, plane in enumerate(planes):
            plane.color = (0.2, 0.4, 0.6, 0.15 + 0.2 * k)
            plane.pass_index = 40 + k  # the object's: not what Material Index reads
            plane.data.materials[0].pass_index = 7 + 3 * k

    result = ss.compare(specs, setup=setup)
    assert not result["warnings"]
    figures = check(result, [n for n, _ in specs])
    print({k: tuple(round(x, 6) for x in v) for k, v in figures.items()})
    g = result["grid"]
    at = [result["ours"][r * ss.PIXELS + 5, c * ss.PIXELS + 5]
          for r, c in [divmod(k, g) for k in range(4)]]
    np.testing.assert_allclose([a[0] for a in at], [0.15, 10.0, 0.55, 16.0], rtol=1e-6)
    np.testing.assert_allclose(result["cycles"][5, 5], at[0], rtol=1e-6)
