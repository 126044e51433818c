"""Depth of field as Cycles defines it: a row of spheres from near to far on a lit floor,
the camera focused on the middle one (focus object) with a wide aperture, round and with
blades; Photon Map's block means against Cycles rendered in this same bpy process, with
the terms both compute (direct light + specular chains, cycles_reference.configure_cycles).
An f-stop of infinity is today's pinhole image, bit for bit. The same for an orthographic
camera, against Cycles' cached image (tests/blender/cycles_dof_reference.py).
"""

import math
import types

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from tests.blender import cycles_dof_reference as dr  # noqa: E402
from tests.blender import cycles_reference as ref  # noqa: E402
from tests.blender import scenes  # noqa: E402
from tests.blender.cycles_dof_reference import SIZE, dof_scene  # noqa: E402

pytestmark = pytest.mark.blender

SAMPLES = 256  # per render; two seeds each
BLOCK = 4  # 4 x 4 pixel blocks: fine enough to see the blur


def photon_map_image(scene, samples, seed):
    return ref.render_photon_map(scene, samples, seed=seed)["Combined"][..., :3].astype(np.float64)


def assert_matches_cycles(pm, cyc, sharp, what):
    """Two seeds each of Photon Map (pm) and Cycles (cyc): channel means within 2 %, every
    4 x 4 block within 5 % + 3 sigma; the image without DOF (sharp) is off by > 10 % in
    some block, so the blur is large enough for the comparison to mean something."""
    sigma = np.hypot(ref.block_sigma(*cyc, block=BLOCK), ref.block_sigma(*pm, block=BLOCK)) / 2
    image, reference = (pm[0] + pm[1]) / 2, (cyc[0] + cyc[1]) / 2
    fig = ref.compare(image, reference, sigma, block=BLOCK)
    blur = ref.compare(sharp, reference, block=BLOCK)
    print(f"\n{what}: channel {np.round(100 * fig['channel'], 3)} %, worst block "
          f"{100 * fig['worst_block']:.2f} %, excess {np.nanmax(fig['excess']):.2f}; the "
          f"image without DOF: worst block {100 * blur['worst_block']:.1f} %")
    assert np.all(np.abs(fig["channel"]) < 0.02), fig["channel"]
    assert np.nanmax(fig["excess"]) <= 1.0  # every block within 5 % + 3 sigma
    assert blur["worst_block"] > 0.1


@pytest.mark.parametrize("blades, rotation, ratio", [(0, 0.0, 1.0), (5, 0.4, 1.6)])
def test_depth_of_field_matches_cycles(blades, rotation, ratio):
    args = dict(blades=blades, rotation=rotation, ratio=ratio)
    cyc = [ref.render_cycles(dof_scene(**args), SAMPLES, seed=s).astype(np.float64) for s in (1, 2)]
    pm = [photon_map_image(dof_scene(**args), SAMPLES, s) for s in (1, 2)]
    pinhole = photon_map_image(dof_scene(use_dof=False, **args), 16, 1)
    assert_matches_cycles(pm, cyc, pinhole, f"DOF blades {blades}")


@pytest.mark.parametrize("ortho, fstop, radius", [(False, 0.1, 50e-3 / (2 * 0.1)),
                                                   (True, 1.0, 1.0 / (2 * 1.0))])
def test_infinite_fstop_is_the_pinhole_bit_for_bit(ortho, fstop, radius):
    """f-stop infinity exports a pinhole (or parallel rays, orthographic): the same camera,
    hence the same rays bit for bit (two renders of one scene still differ by float
    rounding of parallel sums, ~1e-7). A finite f-stop's aperture radius is Cycles': focal
    length / (2 f-stop) or, orthographic, 1 / (2 f-stop), in scene units whatever the
    scene's Unit Scale (Cycles applies none)."""
    from tests.conftest import load_extension_package

    load_extension_package()
    from photon_map.core.scene import camera as core_camera
    from photon_map.photon_engine.export import export_scene

    cams = {}
    for key, args in {"pinhole": dict(use_dof=False), "inf": dict(fstop=math.inf),
                      "wide": dict(fstop=fstop)}.items():
        dof_scene(ortho=ortho, **args)
        bpy.context.scene.unit_settings.scale_length = 0.01 if key == "wide" else 1.0
        cams[key] = export_scene(bpy.context.evaluated_depsgraph_get()).scene.camera
    for field in cams["pinhole"].__dataclass_fields__:
        assert np.array_equal(getattr(cams["inf"], field), getattr(cams["pinhole"], field)), field
    assert cams["inf"].aperture_radius == 0.0
    assert cams["wide"].aperture_radius == pytest.approx(radius)
    pixel = np.arange(SIZE[0] * SIZE[1])
    jitter = np.random.default_rng(1).random((pixel.size, 2))
    lens = np.random.default_rng(2).random((pixel.size, 2))
    a = core_camera.generate_rays(cams["pinhole"], pixel, jitter)
    b = core_camera.generate_rays(cams["inf"], pixel, jitter, lens)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    pinhole = ref.render_photon_map(dof_scene(use_dof=False, ortho=ortho), 4, seed=3)["Combined"]
    infinite = ref.render_photon_map(dof_scene(fstop=math.inf, ortho=ortho), 4, seed=3)["Combined"]
    np.testing.assert_allclose(infinite, pinhole, rtol=1e-5, atol=1e-6)
    wide = ref.render_photon_map(dof_scene(fstop=fstop, ortho=ortho), 4, seed=3)["Combined"]
    assert np.abs(wide - pinhole).max() > 0.05


def test_progressive_renders_depth_of_field():
    """SPPM's camera pass uses the same lens: against the Photon Map integrator (both with
    every light term, caustics off), blurred alike."""
    full = dict(caustics=False, seed=2)
    scene = dof_scene()
    scenes.use_photon_map(scene, integrator='progressive', progressive_passes=64,
                          photons_per_pass=4000, **full)
    sppm = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    scene = dof_scene()
    scenes.use_photon_map(scene, samples=64, **full)
    final = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    scene = dof_scene(use_dof=False)
    scenes.use_photon_map(scene, integrator='progressive', progressive_passes=64,
                          photons_per_pass=4000, **full)
    sharp = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    fig = ref.compare(sppm, final, block=BLOCK)
    blur = ref.compare(sharp, final, block=BLOCK)
    print(f"\nSPPM vs Photon Map with DOF: channel {np.round(100 * fig['channel'], 2)} %, "
          f"worst block {100 * fig['worst_block']:.1f} % (SPPM without DOF: "
          f"{100 * blur['worst_block']:.1f} %)")
    assert np.isfinite(sppm).all() and sppm.min() >= 0
    assert np.all(np.abs(fig["channel"]) < 0.03), fig["channel"]
    assert fig["worst_block"] < 0.5 * blur["worst_block"]


def test_viewport_through_the_camera_has_its_depth_of_field():
    """Rendered shading looking through the scene camera uses its DOF: the viewport's
    image after N passes is the Progressive integrator's F12 image of the same passes."""
    from tests.conftest import load_extension_package

    load_extension_package()
    from photon_map.photon_engine.viewport import ViewportRender, view_camera

    scene = dof_scene()
    scenes.use_photon_map(scene, photons_per_pass=3000, viewport_passes=8, seed=4,
                          caustics=False)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    cam = scene.camera.evaluated_get(depsgraph)
    images = {}
    for perspective in ('CAMERA', 'PERSP'):
        view = types.SimpleNamespace(
            view_matrix=cam.matrix_world.inverted(), view_perspective=perspective,
            window_matrix=cam.calc_matrix_camera(depsgraph, x=SIZE[0], y=SIZE[1]))
        viewport = ViewportRender()
        camera = view_camera(view, *SIZE, scene.camera)
        while True:
            viewport.sync(depsgraph, camera)
            if not viewport.step(seconds=0.0):
                break
        images[perspective] = viewport.image().astype(np.float64)
        viewport.close()
    scene.photon_map.integrator = 'progressive'
    scene.photon_map.progressive_passes = 8
    final = scenes.render_passes(scene)["Combined"][..., :3].astype(np.float64)
    np.testing.assert_allclose(images['CAMERA'].mean(axis=(0, 1)), final.mean(axis=(0, 1)),
                               rtol=1e-3)
    np.testing.assert_allclose(images['CAMERA'], final, rtol=1e-3, atol=1e-3 * final.max())
    # A free view (not through the camera) is a pinhole, like Cycles' viewport.
    assert np.abs(images['PERSP'] - final).max() > 0.05 * final.max()


def test_orthographic_depth_of_field_matches_cycles():
    """Cycles' orthographic thin lens (aperture radius 1 / (2 f-stop) scene units, rays
    of a film point meeting at the focus distance): block means within 5 % + 3 sigma of
    Cycles' cached image, where the sharp orthographic image is far off."""
    cycles = dr.load_reference()
    cyc = [cycles["a"].astype(np.float64), cycles["b"].astype(np.float64)]
    pm = [photon_map_image(dr.ortho_scene(), SAMPLES, s) for s in (1, 2)]
    sharp = photon_map_image(dr.ortho_scene(use_dof=False), 16, 1)
    assert_matches_cycles(pm, cyc, sharp, "orthographic DOF")
