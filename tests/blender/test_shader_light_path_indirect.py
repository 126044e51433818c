"""The Light Path node where only indirect light reaches (final-gather and photon hits)
against Cycles with diffuse bounces, in the same bpy process.

A white floor under a 45-degree sun and, standing on it, a wall whose shader is a Mix
Shader of a red and a blue Diffuse BSDF with Factor = Is Camera Ray: a camera ray would
see it blue, every other ray red. The orthographic camera looks straight down, so it sees
the floor (the wall edge-on); the floor beside the wall is tinted by the wall's indirect
light, red in Cycles (its diffuse bounces answer Is Camera Ray 0). Photon Map's final
gathering and photons must do the same (docs/shading.md, Light Path contexts): were their
hits answered as camera rays, the tint would be blue.
"""

import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_gi_reference as gi  # noqa: E402
from tests.blender import scenes  # noqa: E402
from tests.blender.test_shader_nodes import link, node  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]

RES = 32
RED, BLUE = (0.8, 0.05, 0.05, 1.0), (0.05, 0.05, 0.8, 1.0)


def camera_switched_wall():
    """The scene above: floor 4 m (albedo 0.8), wall 2 m x 2 m at x = -1 facing +x, sun
    from +x at 45 degrees, orthographic camera above (4 m wide, RES x RES)."""
    scene = scenes.reset()
    scenes.set_resolution(RES, RES)
    scenes.add_plane(size=4.0, material=scenes.diffuse_material("Floor", (0.8, 0.8, 0.8)),
                     name="Floor")
    mat = bpy.data.materials.new("CameraSwitched")
    tree = scenes.ensure_node_tree(mat)
    tree.nodes.clear()
    out = node(tree, "ShaderNodeOutputMaterial")
    red, blue = node(tree, "ShaderNodeBsdfDiffuse"), node(tree, "ShaderNodeBsdfDiffuse")
    red.inputs["Color"].default_value = RED
    blue.inputs["Color"].default_value = BLUE
    mix = node(tree, "ShaderNodeMixShader")
    link(tree, node(tree, "ShaderNodeLightPath").outputs["Is Camera Ray"], mix.inputs[0])
    link(tree, red.outputs[0], mix.inputs[1])
    link(tree, blue.outputs[0], mix.inputs[2])
    link(tree, mix.outputs[0], out.inputs["Surface"])
    scenes.add_plane(size=2.0, location=(-1.0, 0.0, 1.0), material=mat, name="Wall",
                     rotation=(0.0, math.radians(90.0), 0.0))
    sun = scenes.add_light('SUN', power=3.0, rotation=(0.0, math.radians(45.0), 0.0))
    sun.data.angle = 0.0
    scenes.add_camera(location=(0.0, 0.0, 5.0), look_at=(0.0, 0.0, 0.0), ortho_scale=4.0)
    return scene


def test_is_camera_ray_at_gather_and_photon_hits_matches_cycles():
    scene = camera_switched_wall()
    cycles = gi.render_cycles_gi(scene, 256).astype(np.float64)
    scenes.use_photon_map(scene, samples=16, seed=1, final_gather_rays=64,
                          global_photons=20000, photon_max_bounces=gi.BOUNCES,
                          indirect_mode='final_gather')
    ours = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    c = (np.arange(RES) + 0.5) / RES * 4.0 - 2.0
    X, Y = np.meshgrid(c, -c)
    px = 4.0 / RES
    beside = (X > -1.0 + px) & (X < 0.0) & (np.abs(Y) < 0.75)  # lit floor by the wall
    tint = {name: img[beside].mean(0) for name, img in (("ours", ours), ("cycles", cycles))}
    bleed = {k: float(v[0] - v[2]) for k, v in tint.items()}  # red minus blue: the wall's
    print(f"\nfloor beside the wall: ours {np.round(tint['ours'], 4)}, Cycles "
          f"{np.round(tint['cycles'], 4)}; red - blue ours {bleed['ours']:.4f}, Cycles "
          f"{bleed['cycles']:.4f} ({100 * (bleed['ours'] / bleed['cycles'] - 1):+.1f} %); "
          f"image means ours {np.round(ours.mean((0, 1)), 4)}, Cycles "
          f"{np.round(cycles.mean((0, 1)), 4)}")
    # the wall lights the floor red in Cycles (not blue: no camera ray there) ...
    assert bleed["cycles"] > 0.02 * tint["cycles"].mean()
    # ... and in ours by as much
    assert abs(bleed["ours"] / bleed["cycles"] - 1) < 0.15
    np.testing.assert_allclose(ours.mean((0, 1)), cycles.mean((0, 1)), rtol=0.03)
