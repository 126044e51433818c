"""Scene-level features the renderer does not support yet (photon_engine/export_warnings.py):
each is one warning naming the object or setting, through a real render depsgraph; camera
values that cannot make a camera are errors naming the UI's setting."""

import math

import bpy
import bmesh  # noqa: E402  (after bpy, which provides it)
import pytest

from tests.blender import scenes
from tests.blender.test_export import basic_scene, export

pytestmark = [pytest.mark.blender, pytest.mark.api]


def lit():
    scene = basic_scene(8, 6)
    scenes.add_plane(size=4.0, material=scenes.diffuse_material())
    scenes.add_light('POINT', location=(0.0, 0.0, 2.0))
    return scene


def test_a_plain_scene_has_no_warning():
    lit()
    assert export().warnings == []


def test_the_worlds_volume_is_exported_without_a_warning():
    lit()
    scenes.world_volume("Foggy World", 'ShaderNodeVolumePrincipled')
    result = export()
    assert result.warnings == []  # a medium now (tests/blender/test_media.py)
    assert result.scene.media.names == ("Foggy World",)


def test_hair_particles_are_named():
    lit()
    plane = bpy.data.objects["Plane"]
    plane.modifiers.new("Fur", 'PARTICLE_SYSTEM')
    psys = plane.particle_systems[0]
    psys.name = "Fur"
    psys.settings.type = 'HAIR'
    psys.settings.count = 10
    assert export().warnings == [
        "Object 'Plane': hair particle system 'Fur' is not supported yet; not rendered"]


def test_a_curves_hair_object_is_named():
    scene = lit()
    curves = bpy.data.hair_curves.new("Strands")
    obj = bpy.data.objects.new("Strands", curves)
    scene.collection.objects.link(obj)
    assert export().warnings == [
        "Object 'Strands': Curves hair objects are not supported yet; not rendered"]


def test_motion_blur_is_named():
    scene = lit()
    scene.render.use_motion_blur = True
    assert export().warnings == [
        "Motion Blur (Render Properties > Motion Blur) is not supported yet; ignored (the "
        "frame is rendered at one instant)"]


def glass(name):
    mat = bpy.data.materials.new(name)
    tree = scenes.ensure_node_tree(mat)
    bsdf = tree.nodes.new('ShaderNodeBsdfGlass')
    output = next(n for n in tree.nodes if n.type == 'OUTPUT_MATERIAL')
    tree.links.new(bsdf.outputs[0], output.inputs["Surface"])
    return mat


@pytest.mark.parametrize("flip", [False, True])
def test_inside_out_glass_is_named(flip):
    lit()
    sphere = scenes.add_sphere(radius=0.5, location=(0, 0, 0.6), material=glass("Glass"),
                               name="Ball")
    if flip:
        bm = bmesh.new()
        bm.from_mesh(sphere.data)
        bmesh.ops.reverse_faces(bm, faces=bm.faces)
        bm.to_mesh(sphere.data)
        bm.free()
    warnings = export().warnings
    expected = ["Object 'Ball': closed glass with its normals pointing inward (negative "
                "volume), so it refracts inside out; use Mesh > Normals > Recalculate Outside"]
    assert warnings == (expected if flip else [])


@pytest.mark.parametrize("setting, attribute, value", [
    ("Focal Length", "lens", math.nan), ("Sensor Size", "sensor_width", math.nan),
    ("Clip Start", "clip_start", math.nan), ("Clip End", "clip_end", math.nan),
    ("Shift X", "shift_x", math.nan)])
def test_a_camera_value_that_cannot_make_a_camera_names_the_setting(setting, attribute, value):
    lit()
    # Blender clamps what the UI types; a driver or a script still stores NaN.
    setattr(bpy.data.objects["Camera"].data, attribute, value)
    with pytest.raises(Exception) as refused:
        export()
    message = str(refused.value)
    need = "a finite number" if setting.startswith("Shift") else "a finite number > 0"
    assert message == f"camera 'Camera': {setting} must be {need}, got {value:g}"
    assert "film_size" not in message and "camera." not in message
