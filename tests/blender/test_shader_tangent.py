"""A linked Tangent input: an anisotropic Glossy plane under a sun whose Tangent is a
Tangent node (the UV map's, the UV map turned 90 degrees: T = (0, -1, 0) everywhere) or a
constant vector, against Cycles in this bpy process (direct light only) and against the
unlinked input (Cycles' default, the radial tangent about the object's Z axis, which
turns across the plane: the two pictures differ)."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import scenes  # noqa: E402
from tests.blender import test_shader_normals as sun_lit  # noqa: E402
from tests.blender.export_probe import export  # noqa: E402
from tests.conftest import load_extension_package  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]

photon_map = load_extension_package()


def anisotropic_material(tangent):
    """Glossy (GGX single scatter: no random walk in Cycles' estimate), roughness 0.4,
    Anisotropy 0.8, Rotation 0.1 turn; tangent None (unlinked), "UV_MAP" (a Tangent node
    of the UV map) or a constant (x, y, z) (a Combine XYZ, folded into the closure)."""
    mat = bpy.data.materials.new(f"Anisotropic {tangent}")
    tree = scenes.ensure_node_tree(mat)
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    bsdf = tree.nodes.new("ShaderNodeBsdfGlossy")
    bsdf.distribution = 'GGX'
    bsdf.inputs["Color"].default_value = (0.9, 0.9, 0.9, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.4
    bsdf.inputs["Anisotropy"].default_value = 0.8
    bsdf.inputs["Rotation"].default_value = 0.1
    if tangent == "UV_MAP":
        node = tree.nodes.new("ShaderNodeTangent")
        node.direction_type = 'UV_MAP'
        node.uv_map = "UVMap"
        tree.links.new(node.outputs["Tangent"], bsdf.inputs["Tangent"])
    elif tangent is not None:
        node = tree.nodes.new("ShaderNodeCombineXYZ")
        for name, v in zip("XYZ", tangent):
            node.inputs[name].default_value = v
        tree.links.new(node.outputs[0], bsdf.inputs["Tangent"])
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


@pytest.mark.parametrize("tangent", ["UV_MAP", (1.0, 1.0, 0.0)], ids=["uv_map", "constant"])
def test_a_linked_tangent_turns_the_anisotropic_highlight_as_cycles(tangent):
    scene = sun_lit.sun_plane(lambda: anisotropic_material(tangent))
    exported = export(scene)
    assert not [w for w in exported.warnings if "Tangent" in w], exported.warnings
    ours = sun_lit.render_photon_map(scene)
    cycles = sun_lit.render_cycles(scene)
    radial = sun_lit.render_photon_map(sun_lit.sun_plane(lambda: anisotropic_material(None)))
    a, b, r = (sun_lit.block_means(x) for x in (ours, cycles, radial))
    rel = np.abs(a - b) / b
    moved = np.abs(r - b) / b
    print(f"\ntangent {tangent}: 8 x 8 blocks vs Cycles worst {100 * rel.max():.3f} %, "
          f"means ours {ours.mean():.6f} Cycles {cycles.mean():.6f} (radial default "
          f"{radial.mean():.6f}, {r.min():.6f} to {r.max():.6f})")
    assert moved.max() > 0.1  # the tangent matters here
    assert rel.max() < 0.03
