"""Blackbody volume emission (Principled Volume Blackbody Intensity, Temperature, Blackbody
Tint; photon_engine/export_volumes.py ``blackbody_emission``) against Cycles in the same
bpy process: an orthographic camera looks through a 1 m cube of a Principled Volume that
only emits (Density 0), so each central pixel's Emission pass is the medium's emission x
1 m in both renderers, exactly (Cycles integrates a homogeneous volume's emission in
closed form, no noise but the pixel filter's at the cube's edges). Three media: blackbody
alone at 1500 K (red) and 6500 K (white), and blackbody at intensity 0.5 (the
mix(1, T^4, B) term) plus Emission Strength. Cycles' blackbody colour is not clamped: at
1500 K its blue is negative and Cycles' Emission pass reads -0.0059 there; a medium's
emission cannot be negative, so Photon Map's is that channel clamped at 0."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_mesh_media_reference as mesh_ref  # noqa: E402
from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes  # noqa: E402

pytestmark = [pytest.mark.blender]

CASES = {
    "red_1500K": {"Density": 0.0, "Blackbody Intensity": 1.0, "Temperature": 1500.0,
                  "Emission Strength": 0.0},
    "white_6500K": {"Density": 0.0, "Blackbody Intensity": 1.0, "Temperature": 6500.0,
                    "Blackbody Tint": (0.5, 0.8, 1.0, 1.0), "Emission Strength": 0.0},
    "half_plus_emission": {"Density": 0.0, "Blackbody Intensity": 0.5, "Temperature": 1200.0,
                           "Emission Strength": 0.05, "Emission Color": (0.2, 0.4, 1.0, 1.0)},
}


def _scene(inputs):
    scene = scenes.reset()
    scenes.set_resolution(16, 16)
    mat = mesh_ref.volume_material("Fire", None, 'ShaderNodeVolumePrincipled', inputs)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.0))
    bpy.context.active_object.data.materials.append(mat)
    scenes.add_camera(location=(0.0, -3.0, 0.0), look_at=(0.0, 0.0, 0.0), ortho_scale=2.0)
    scene.view_layers[0].use_pass_emit = True
    return scene


def _centre(image):
    """The mean of the central 6 x 6 pixels (the cube spans the middle 8 x 8)."""
    return image[5:11, 5:11, :3].reshape(-1, 3).mean(axis=0).astype(np.float64)


@pytest.mark.parametrize("case", sorted(CASES))
def test_blackbody_emission_matches_cycles(case):
    scene = ref.configure_cycles(_scene(CASES[case]), 4, 1)
    cycles_passes = scenes.render_passes(scene)
    # Cycles names the pass "Emit" in Blender 4.2 and "Emission" from 4.3 on.
    cycles = _centre(cycles_passes.get("Emission", cycles_passes.get("Emit")))
    scene = _scene(CASES[case])
    scenes.use_photon_map(scene, samples=4, global_photons=1000, caustic_photons=0,
                          indirect_mode='preview')
    passes = scenes.render_passes(scene)
    ours = _centre(passes["Emission"])
    print(f"\n{case}: Cycles {cycles}, Photon Map {ours}, ratio {ours / cycles}")
    assert cycles[0] > 0 and np.all(np.isfinite(ours)) and np.all(ours >= 0)
    np.testing.assert_allclose(ours, np.maximum(cycles, 0.0), rtol=2e-3, atol=1e-7)
