"""The scene contract: validation messages, defaults, backward compatibility."""

import numpy as np
import pytest

from core.scene import shapes
from core.scene.contract import (LIGHT_AREA, LIGHT_POINT, LIGHT_SUN, Camera, Lights, Materials, Mesh,
                        Scene, SceneError, World)


def small_scene(**lights):
    plane = shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0])
    mesh = shapes.assemble([(plane, 0)], names=("Floor",))
    return Scene(mesh, Materials.from_list([{"diffuse": [0.5, 0.5, 0.5], "name": "Grey"}]),
                 Lights.from_list([{"kind": LIGHT_POINT, "position": [0, 0, 1], "power": 10.0, **lights}]),
                 shapes.pinhole([0, -2, 1], [0, 0, 0], 4, 4, 1.0))


def test_a_good_scene_validates():
    assert small_scene().validate() is not None


def test_new_light_fields_default_to_blenders_defaults():
    li = Lights.from_list([{"kind": LIGHT_POINT}])
    assert li.soft_falloff.tolist() == [True]
    assert li.visible_to_diffuse.tolist() == [True] and li.visible_to_glossy.tolist() == [True]
    assert li.visible_to_transmission.tolist() == [True]
    assert li.visible_to_camera.tolist() == [False]


def test_lights_built_without_the_optional_fields_still_work():
    full = Lights.from_list([{"kind": LIGHT_POINT, "radius": 0.1}])
    old_style = Lights(kind=full.kind, to_world=full.to_world, color=full.color, power=full.power,
                       radius=full.radius, angle=full.angle, spot_size=full.spot_size,
                       spot_blend=full.spot_blend, shape=full.shape, size=full.size,
                       visible_to_camera=full.visible_to_camera, cast_shadow=full.cast_shadow)
    assert old_style.soft_falloff is None
    assert old_style.soft_falloff_mask().tolist() == [True]
    assert old_style.flag_mask("visible_to_glossy").tolist() == [True]
    scene = small_scene()
    Scene(scene.mesh, scene.materials, old_style, scene.camera).validate()


def test_nan_in_a_light_transform_names_the_light():
    scene = small_scene(name="Key")
    bad = scene.lights.to_world.copy()
    bad[0, 1, 3] = np.nan
    lights = Lights(**{**scene.lights.__dict__, "to_world": bad})
    with pytest.raises(SceneError, match=r"lights.to_world of 'Key' holds a non-finite value"):
        Scene(scene.mesh, scene.materials, lights, scene.camera).validate()


def test_nan_in_normals_names_the_object():
    scene = small_scene()
    normals = scene.mesh.normals.copy()
    normals[1, 2, 0] = np.inf
    mesh = Mesh(**{**scene.mesh.__dict__, "normals": normals})
    with pytest.raises(SceneError, match=r"mesh.normals of 'Floor'"):
        Scene(mesh, scene.materials, scene.lights, scene.camera).validate()


def test_bad_optional_flag_shape_is_reported():
    scene = small_scene()
    lights = Lights(**{**scene.lights.__dict__, "soft_falloff": np.ones(3, bool)})
    with pytest.raises(SceneError, match="lights.soft_falloff must have shape"):
        Scene(scene.mesh, scene.materials, lights, scene.camera).validate()


def test_material_index_out_of_range_and_negative_ior():
    scene = small_scene()
    mesh = Mesh(**{**scene.mesh.__dict__, "material_index": np.array([0, 1], np.int32)})
    with pytest.raises(SceneError, match="material_index out of range"):
        Scene(mesh, scene.materials, scene.lights, scene.camera).validate()
    mats = Materials.from_list([{"ior": -1.0, "name": "Odd"}])
    with pytest.raises(SceneError, match="materials.ior of 'Odd' must be > 0"):
        Scene(scene.mesh, mats, scene.lights, scene.camera).validate()


def test_camera_checks():
    scene = small_scene()
    cam = Camera(to_world=np.eye(4), width=0, height=4, film_size=np.array([1.0, 1.0]))
    with pytest.raises(SceneError, match="resolution"):
        Scene(scene.mesh, scene.materials, scene.lights, cam).validate()
    cam = Camera(to_world=np.eye(4), width=4, height=4, film_size=np.array([1.0, 1.0]), clip_start=2.0, clip_end=1.0)
    with pytest.raises(SceneError, match="clip_start < clip_end"):
        Scene(scene.mesh, scene.materials, scene.lights, cam).validate()


def test_bounds_cover_geometry_and_local_lights_only():
    scene = small_scene()
    sun = Lights.from_list([{"kind": LIGHT_SUN, "position": [100, 100, 100]},
                            {"kind": LIGHT_AREA, "position": [0, 0, 5]}])
    lo, hi = Scene(scene.mesh, scene.materials, sun, scene.camera).bounds()
    np.testing.assert_allclose(lo, [-1, -2, 0])
    np.testing.assert_allclose(hi, [1, 1, 5])
    empty = Scene(Mesh.empty(), Materials.from_list([]), Lights.empty(), scene.camera, World())
    lo, hi = empty.validate().bounds()
    np.testing.assert_allclose(lo, hi)
