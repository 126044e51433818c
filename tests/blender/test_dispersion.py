"""The material's Dispersion setting through bpy (photon_engine/properties.py
``PhotonMapMaterialSettings``, export_materials.py, docs/dispersion.md): it exports as the
contract's Abbe number, 0 exports as no setting at all, a value the core refuses is
reported naming the material, and a prism under a spot light renders a finite,
non-negative rainbow whose blue lands nearer the prism than its red."""

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from mathutils import Vector  # noqa: E402

from tests.blender import scenes  # noqa: E402
from tests.blender.export_probe import export  # noqa: E402
from tests.conftest import load_extension_package  # noqa: E402

pytestmark = [pytest.mark.blender, pytest.mark.api]

photon_map = load_extension_package()
from photon_map.core.scene import shapes  # noqa: E402
from photon_map.photon_engine.compat import ensure_node_tree  # noqa: E402

LIGHT = (-3.07, 0.0, 0.407)
FACE = (-0.25, 0.0, 1.433)  # the prism's left face's centre (tests/core/scenes.py)


def glass(name="Prism", ior=1.5168):
    mat = bpy.data.materials.new(name)
    tree = ensure_node_tree(mat)
    tree.nodes.clear()
    out = tree.nodes.new('ShaderNodeOutputMaterial')
    node = tree.nodes.new('ShaderNodeBsdfGlass')
    node.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    node.inputs["Roughness"].default_value = 0.0
    node.inputs["IOR"].default_value = ior
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat


def prism_scene(dispersion, width=48, height=32, spot_size=0.35):
    """tests/core/scenes.py's prism_scene built through bpy: a 60-degree prism 1 m above a
    white floor, a spot light through its left face, the camera on the rainbow."""
    scenes.photon_map()  # registers the extension: Material.photon_map exists
    scene = scenes.reset()
    scenes.set_resolution(width, height)
    floor = scenes.add_plane(size=1.0, location=(3.0, 0.0, 0.0),
                             material=scenes.diffuse_material("Floor", (0.8, 0.8, 0.8)))
    floor.scale = (12.0, 4.0, 1.0)
    part = shapes.prism([0.0, 0.0, 1.0], 1.0, 1.2)
    verts = part.corners.reshape(-1, 3)
    mesh = bpy.data.meshes.new("Prism")
    mesh.from_pydata([tuple(v) for v in verts], [],
                     [(3 * i, 3 * i + 1, 3 * i + 2) for i in range(part.corners.shape[0])])
    mesh.update()
    obj = bpy.data.objects.new("Prism", mesh)
    scene.collection.objects.link(obj)
    mat = glass()
    mat.photon_map.dispersion = dispersion
    mesh.materials.append(mat)
    spot = scenes.add_light('SPOT', location=LIGHT, power=2000.0, spot_size=spot_size,
                            spot_blend=0.0, shadow_soft_size=0.0)
    spot.rotation_euler = (Vector(FACE) - Vector(LIGHT)).to_track_quat('-Z', 'Y').to_euler()
    scenes.add_camera(location=(4.4, -2.2, 2.0), look_at=(4.3, 0.0, 0.0), lens=30.0)
    return scene, mat


def test_dispersion_exports_as_the_abbe_number_and_zero_as_no_setting():
    scene, mat = prism_scene(36.4)
    m = export(scene).scene.materials
    prism = m.names.index("Prism")
    assert m.dispersion is not None and m.dispersion[prism] == np.float32(36.4)
    assert m.dispersion[m.names.index("Floor")] == 0.0
    mat.photon_map.dispersion = 0.0
    assert export(scene).scene.materials.dispersion is None  # bit-identical to main's export


def test_dispersion_below_the_minimum_is_refused_naming_the_material():
    scene, _ = prism_scene(2.0)
    scenes.use_photon_map(scene, caustic_photons=1000, global_photons=1000)
    with pytest.raises(RuntimeError, match="Prism.*Dispersion"):
        scenes.render_passes(scene)


def test_prism_renders_a_rainbow():
    # A narrow spot: the whole caustic (~1 m long on the floor) inside the frame.
    scene, _ = prism_scene(20.0, spot_size=0.1)
    scenes.use_photon_map(scene, caustic_photons=300_000, global_photons=1_000, samples=1,
                          indirect_mode='off', seed=1)
    passes = scenes.render_passes(scene)
    combined = passes["Combined"][..., :3].astype(np.float64)
    assert np.all(np.isfinite(combined)) and np.all(combined >= 0)
    img = passes["Caustics"][..., :3].astype(np.float64)
    # The rainbow caustic: blue, bent more, lands nearer the prism (left in the image)
    # than red, by Snell ~2.8 degrees between 450 and 650 nm at V_d 20, ~0.6 m on the
    # floor, ~10 pixels here; and its pixels have clearly different hues.
    cols = np.broadcast_to(np.arange(img.shape[1], dtype=np.float64), img.shape[:2])
    x_red = np.average(cols, weights=img[..., 0])
    x_blue = np.average(cols, weights=img[..., 2])
    assert x_blue < x_red - 3.0, (x_blue, x_red)
    lit = img.sum(axis=2) > 0.1 * img.sum(axis=2).max()
    red, blue = img[lit, 0], img[lit, 2]
    hue = (red - blue) / (red + blue + 1e-12)
    assert hue.max() - hue.min() > 0.5
