"""Scenes far from Blender's world origin (architecture, GIS: 1e4 to 1e6 m) render like the
same scene at the origin: the exporter works relative to a render origin (the camera) in
float64, so float32 only holds the scene's own extent.

Blender itself stores object matrices in float32: at 1e6 m a location snaps to 1/16 m.
The reference is therefore *the same Blender scene* at the origin: the demo is built at
the offset, and its objects' stored (snapped) locations minus the offset are given to a
second copy at the origin. The two are then the same scene up to a translation, and any
difference in the images is the renderer's doing.
"""

import types

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes  # noqa: E402

pytestmark = pytest.mark.blender

OFFSETS = (1e4, 1e5, 1e6)
SIZE = (48, 36)
SETTINGS = dict(samples=4, global_photons=20000, caustic_photons=20000, final_gather_rays=16,
                seed=7)


def demo(offset: float):
    """The demo at (offset, offset, offset) m; for a negative ``offset``, the matching scene
    at the origin: the demo's objects at the snapped locations of the demo built at
    ``-offset``, minus that offset."""
    far = abs(offset)
    scene = ref.demo_scene(offset=(far, far, far), resolution=SIZE)
    if offset < 0:
        snapped = {o.name: np.array(o.location, np.float64) for o in scene.objects}  # float32 as stored
        scene = ref.demo_scene(resolution=SIZE)
        for obj in scene.objects:
            obj.location = tuple(snapped[obj.name] - far)
    scenes.use_photon_map(scene, **SETTINGS)
    return scene


_RENDERS: dict = {}


def render(offset: float) -> dict:
    if offset not in _RENDERS:
        _RENDERS[offset] = scenes.render_passes(demo(offset))
    return _RENDERS[offset]


@pytest.mark.parametrize("offset", OFFSETS)
def test_far_demo_renders_like_the_demo_at_the_origin(offset):
    far, near = render(offset), render(-offset)
    for name in ("Combined", "Caustics", "Indirect", "Direct"):
        a, b = far[name][..., :3].astype(np.float64), near[name][..., :3].astype(np.float64)
        assert np.isfinite(a).all() and a.min() >= 0, name
        if name == "Combined":
            assert a.max() > 0
        if b.max() == 0:  # at 1e6 m Blender's snapping moves the light to the ceiling
            assert a.max() == 0, name  # (1.98 -> 2.0 m): no caustic in either scene
            continue
        ratio = a.mean(axis=(0, 1)) / b.mean(axis=(0, 1)) - 1
        print(f"offset {offset:g} m, {name}: means {np.round(100 * ratio, 4)} %")
        assert np.all(np.abs(ratio) < 1e-3), (name, ratio)
    figures = ref.compare(far["Combined"][..., :3], near["Combined"][..., :3])
    assert figures["worst_block"] < 0.01, figures["worst_block"]


def test_export_is_camera_relative_in_float64():
    from tests.conftest import load_extension_package

    load_extension_package()
    from photon_map.photon_engine.export import export_scene

    scene = demo(1e6)
    exported = export_scene(bpy.context.evaluated_depsgraph_get())
    np.testing.assert_array_equal(exported.origin, np.array(scene.camera.location))
    np.testing.assert_array_equal(exported.scene.camera.to_world[:3, 3], 0.0)
    lo, hi = exported.scene.mesh.vertices.min(axis=0), exported.scene.mesh.vertices.max(axis=0)
    # The box (2 m wide, 2 m high, its front 2 m from the camera) around the camera, with
    # float32 holding millimetres and better, not 6 cm steps.
    np.testing.assert_allclose(lo, [-1.0, 2.0, -1.0], atol=0.07)  # snapped by Blender itself
    # The spheres' tessellation survives: vertices a few mm apart stay distinct (in the
    # world frame float32 would have merged everything closer than 6 cm).
    xs = np.unique(exported.scene.mesh.vertices[:, 0])
    assert np.diff(xs).min() < 0.01
    world = export_scene(bpy.context.evaluated_depsgraph_get(), origin=np.zeros(3))
    assert np.diff(np.unique(world.scene.mesh.vertices[:, 0])).min() >= 0.0625


def test_photon_overlay_lands_on_the_far_scene(monkeypatch):
    """The viewport photon display gets world positions back: the render origin added."""
    from tests.conftest import load_extension_package

    load_extension_package()
    from photon_map.core.integrators import photon_mapping as integrator
    from photon_map.photon_engine import overlay, render
    from photon_map.photon_engine.export import export_scene
    from photon_map.photon_engine.properties import to_core_settings

    shown = {}
    for offset in (1e6, -1e6):
        scene = demo(offset)
        exported = export_scene(bpy.context.evaluated_depsgraph_get())
        output = integrator.render(exported.scene, to_core_settings(scene.photon_map))
        monkeypatch.setitem(__import__("sys").modules, "bpy", types.SimpleNamespace(
            app=types.SimpleNamespace(background=False)))
        render.show_in_viewport(output.photon_maps, "both", exported.origin)
        monkeypatch.undo()
        shown[offset] = overlay.photons()[0].astype(np.float64)
    far, near = shown[1e6], shown[-1e6]
    assert far.shape == near.shape and far.shape[0] > 100
    # The same photons, 1e6 m apart (float32 display positions: 1/16 m steps there).
    np.testing.assert_allclose(far - 1e6, near, atol=0.07)


@pytest.mark.parametrize("offset", OFFSETS)
def test_viewport_at_a_far_offset(offset):
    from tests.conftest import load_extension_package

    load_extension_package()
    from photon_map.photon_engine.viewport import ViewportRender, view_camera

    images = []
    for sign in (1, -1):
        scene = demo(sign * offset)
        scene.photon_map.photons_per_pass = 5000
        scene.photon_map.viewport_passes = 4
        depsgraph = bpy.context.evaluated_depsgraph_get()
        cam = scene.camera.evaluated_get(depsgraph)
        view = types.SimpleNamespace(view_matrix=cam.matrix_world.inverted(),
                                     window_matrix=cam.calc_matrix_camera(depsgraph, x=SIZE[0],
                                                                          y=SIZE[1]))
        viewport = ViewportRender()
        camera = view_camera(view, *SIZE)
        while True:
            viewport.sync(depsgraph, camera)
            if not viewport.step(seconds=0.0):
                break
        assert viewport.error is None, viewport.error
        images.append(viewport.image().astype(np.float64))
        viewport.close()
    ratio = images[0].mean(axis=(0, 1)) / images[1].mean(axis=(0, 1)) - 1
    print(f"viewport at {offset:g} m: means {np.round(100 * ratio, 4)} %")
    assert np.isfinite(images[0]).all() and images[0].max() > 0
    assert np.all(np.abs(ratio) < 1e-3), ratio
