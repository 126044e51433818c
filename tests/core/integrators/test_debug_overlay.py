"""The photon debug pass: projection to the predicted pixel, occlusion, colours, edge cases.

Predicted pixels come from the pinhole / orthographic formulas written out here, not from
``camera.project``; occlusion is checked against the geometry (which faces of a box face
the camera), not against the code's own ray casts.
"""

import numpy as np
import pytest

from core.integrators import debug_overlay as dbg
from core.scene import shapes
from core.scene.accel import Accelerator, BruteForceAccelerator
from core.scene.contract import CAMERA_ORTHOGRAPHIC, Camera

W, H = 64, 48
EYE = np.array([0.0, -5.0, 1.0])


def camera_looking_along_y(kind=0, film=(0.8, 0.6), shift=(0.0, 0.0), eye=EYE, **kw):
    """At ``eye`` looking along +Y: right = +X, up = +Z, back = -Y (matrix written by hand)."""
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = [1, 0, 0], [0, 0, 1], [0, -1, 0], eye
    return Camera(to_world=m, width=W, height=H, film_size=np.array(film, float),
                  film_shift=np.array(shift, float), kind=kind, **kw)


def pinhole_pixel(point, film=(0.8, 0.6), shift=(0.0, 0.0), eye=EYE):
    """(column, row) integer pixel of a world point for camera_looking_along_y."""
    x, depth, y = np.asarray(point, float) - eye  # right, forward, up
    fx, fy = x / depth - shift[0], y / depth - shift[1]
    return int(np.floor((fx / film[0] + 0.5) * W)), int(np.floor((0.5 - fy / film[1]) * H))


def ortho_pixel(point, film=(4.0, 3.0), shift=(0.0, 0.0), eye=EYE):
    x, _, y = np.asarray(point, float) - eye
    return (int(np.floor(((x - shift[0]) / film[0] + 0.5) * W)),
            int(np.floor((0.5 - (y - shift[1]) / film[1]) * H)))


def wall_mesh(extra=()):
    """A 4 x 4 m wall in the plane y = 0 facing the camera (normal -Y), plus ``extra`` parts."""
    wall = shapes.quad([0, 0, 1], [2, 0, 0], [0, 0, 2])  # u x v = -Y
    return shapes.assemble([(wall, 0)] + [(p, 0) for p in extra])


def lit_pixels(image):
    rows, cols = np.nonzero(image[..., 3])
    return sorted(zip(cols.tolist(), rows.tolist()))


PHOTON = np.array([[0.3, 0.0, 1.2]], np.float32)  # on the wall
FLUX = np.array([[2.0, 1.0, 0.5]], np.float32)


@pytest.mark.parametrize("shift", [(0.0, 0.0), (0.05, -0.04)])
def test_single_photon_lands_on_the_predicted_pixel(shift):
    cam = camera_looking_along_y(shift=shift)
    with Accelerator(wall_mesh(), threads=1) as accel:
        image = dbg.photon_overlay(cam, accel, PHOTON, FLUX, dot_radius_px=0)
    assert image.shape == (H, W, 4) and image.dtype == np.float32
    col, row = pinhole_pixel(PHOTON[0], shift=shift)
    assert lit_pixels(image) == [(col, row)]
    # One photon: the display scale is its brightest channel.
    np.testing.assert_allclose(image[row, col], [1.0, 0.5, 0.25, 1.0], rtol=1e-6)


def test_dot_radius_draws_a_disc_around_the_pixel():
    cam = camera_looking_along_y()
    with Accelerator(wall_mesh(), threads=1) as accel:
        image = dbg.photon_overlay(cam, accel, PHOTON, FLUX, dot_radius_px=1)
    col, row = pinhole_pixel(PHOTON[0])
    assert lit_pixels(image) == sorted([(col, row), (col - 1, row), (col + 1, row),
                                        (col, row - 1), (col, row + 1)])


def test_photon_behind_an_occluder_is_hidden():
    occluder = shapes.quad([0.3, -2.0, 1.2], [0.2, 0, 0], [0, 0, 0.2])  # between eye and photon
    cam = camera_looking_along_y()
    with Accelerator(wall_mesh([occluder]), threads=1) as accel:
        image = dbg.photon_overlay(cam, accel, PHOTON, FLUX)
        visible, _ = dbg.visible_photons(cam, accel, PHOTON)
    assert not visible[0]
    assert not image.any()


def test_photon_beside_the_occluder_still_shows():
    occluder = shapes.quad([-1.0, -2.0, 1.2], [0.2, 0, 0], [0, 0, 0.2])
    cam = camera_looking_along_y()
    with Accelerator(wall_mesh([occluder]), threads=1) as accel:
        image = dbg.photon_overlay(cam, accel, PHOTON, FLUX, dot_radius_px=0)
    assert lit_pixels(image) == [pinhole_pixel(PHOTON[0])]


def box_surface_photons(rng, n_per_face, lo, hi, margin=0.05):
    """Points on the six faces of a box (away from the edges) and the outward normal of each."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    pts, normals = [], []
    for axis in range(3):
        for side, value in ((-1, lo[axis]), (1, hi[axis])):
            p = lo + (hi - lo) * rng.uniform(margin, 1 - margin, (n_per_face, 3))
            p[:, axis] = value
            nrm = np.zeros((n_per_face, 3))
            nrm[:, axis] = side
            pts.append(p)
            normals.append(nrm)
    return np.concatenate(pts).astype(np.float32), np.concatenate(normals)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
@pytest.mark.parametrize("kind", [0, CAMERA_ORTHOGRAPHIC])
def test_a_box_shows_exactly_the_photons_on_its_faces_towards_the_camera(rng, scale, kind):
    """Photons on the box's own (slanted) faces show; those on the faces turned away don't.

    The box is rotated so the camera sees three faces at different slopes, some grazing;
    the same at 1e-3 and 1e3 times the size (the tolerance is scale-relative).
    """
    lo, hi = np.array([-0.6, -0.5, 0.3]), np.array([0.6, 0.7, 1.5])
    pts, normals = box_surface_photons(rng, 400, lo, hi)
    rot = _rotation([0.3, 0.2, 1.0], 0.7)
    centre = (lo + hi) / 2
    pts = ((pts - centre) @ rot.T + centre).astype(np.float32)
    normals = normals @ rot.T
    box = shapes.box(lo, hi)
    corners = (box.corners - centre) @ rot.T + centre
    mesh = shapes.assemble([(shapes.Part(corners * scale, box.normals), 0)])
    eye = EYE + np.array([1.5, 0.0, 1.5])
    cam = camera_looking_along_y(kind=kind, eye=eye * scale,
                                 film=(8.0 * scale, 6.0 * scale) if kind else (1.8, 1.35))
    if kind == CAMERA_ORTHOGRAPHIC:
        toward_camera = np.array([0.0, -1.0, 0.0])[None]
    else:
        toward_camera = eye - pts
    facing = np.einsum("ij,ij->i", normals, toward_camera) > 0
    with Accelerator(mesh, threads=1) as accel:
        visible, pixel = dbg.visible_photons(cam, accel, pts * np.float32(scale))
    in_frame = (pixel[:, 0] >= 0) & (pixel[:, 0] < W) & (pixel[:, 1] >= 0) & (pixel[:, 1] < H)
    assert in_frame.all()  # the whole box is in the picture
    assert 0.3 < facing.mean() < 0.7
    np.testing.assert_array_equal(visible, facing)


def _rotation(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_orthographic_camera_lands_on_the_predicted_pixel():
    film, shift = (4.0, 3.0), (0.3, -0.2)
    cam = camera_looking_along_y(kind=CAMERA_ORTHOGRAPHIC, film=film, shift=shift)
    photons = np.array([[0.3, 0.0, 1.2], [-1.1, 0.0, 0.4]], np.float32)
    flux = np.ones((2, 3), np.float32)
    with Accelerator(wall_mesh(), threads=1) as accel:
        image = dbg.photon_overlay(cam, accel, photons, flux, dot_radius_px=0)
    assert lit_pixels(image) == sorted(ortho_pixel(p, film, shift) for p in photons)


def test_brute_force_accelerator_gives_the_same_image(rng):
    occluder = shapes.quad([0.0, -2.0, 1.0], [0.4, 0, 0], [0, 0, 0.3])
    mesh = wall_mesh([occluder])
    pts = np.column_stack([rng.uniform(-1.5, 1.5, 300), np.zeros(300), rng.uniform(-0.8, 2.8, 300)])
    flux = rng.uniform(0, 1, (300, 3)).astype(np.float32)
    cam = camera_looking_along_y()
    with Accelerator(mesh, threads=1) as accel:
        a = dbg.photon_overlay(cam, accel, pts.astype(np.float32), flux)
    b = dbg.photon_overlay(cam, BruteForceAccelerator(mesh), pts.astype(np.float32), flux)
    np.testing.assert_array_equal(a, b)
    # The occluder casts a hole: some photons are hidden, most show.
    visible, _ = dbg.visible_photons(cam, BruteForceAccelerator(mesh), pts.astype(np.float32))
    assert 0.5 < visible.mean() < 1.0


def test_photons_outside_the_view_or_the_clipping_range_are_dropped():
    cam = camera_looking_along_y(clip_start=1.0, clip_end=5.5)
    photons = np.array([
        [0.3, 0.0, 1.2],    # visible
        [0.3, -4.5, 1.0],   # 0.5 m in front of the camera: before clip_start
        [0.3, -6.0, 1.0],   # behind the camera
        [0.3, 1.0, 1.2],    # beyond clip_end (no surface needed to test it)
        [50.0, 0.0, 1.2],   # far outside the picture to the right
    ], np.float32)
    with Accelerator(wall_mesh(), threads=1) as accel:
        visible, _ = dbg.visible_photons(cam, accel, photons)
        image = dbg.photon_overlay(cam, accel, photons, np.ones((5, 3), np.float32), dot_radius_px=0)
    np.testing.assert_array_equal(visible, [True, False, False, False, False])
    assert lit_pixels(image) == [pinhole_pixel(photons[0])]


def test_dots_at_the_image_border_are_clipped_not_wrapped():
    cam = camera_looking_along_y()
    # Film x at the very left edge of the picture, in pixel column 0.
    x_left = (-0.4 + 0.2 / W) * 5.0
    photon = np.array([[x_left, 0.0, 1.2]], np.float32)
    with Accelerator(wall_mesh(), threads=1) as accel:
        image = dbg.photon_overlay(cam, accel, photon, FLUX, dot_radius_px=2)
    cols = {c for c, _ in lit_pixels(image)}
    assert cols == {0, 1, 2}


def test_overlapping_dots_hold_the_mean_colour_and_colours_are_relative():
    cam = camera_looking_along_y()
    photons = np.repeat(PHOTON, 3, axis=0)
    flux = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 4.0]], np.float32)
    with Accelerator(wall_mesh(), threads=1) as accel:
        image = dbg.photon_overlay(cam, accel, photons, flux, dot_radius_px=0, scale=2.0)
        scaled = dbg.photon_overlay(cam, accel, photons, flux * 1000, dot_radius_px=0)
    col, row = pinhole_pixel(PHOTON[0])
    np.testing.assert_allclose(image[row, col], [1 / 6, 1 / 6, 4 / 6, 1.0], rtol=1e-6)
    # Without a scale the colours do not depend on the light's power.
    unscaled = dbg.display_colors(flux).mean(axis=0)
    np.testing.assert_allclose(scaled[row, col, :3], unscaled, rtol=1e-5)


def test_display_scale_is_the_99th_percentile():
    flux = np.zeros((1000, 3), np.float32)
    flux[:, 1] = np.arange(1000)
    assert dbg.display_scale(flux) == pytest.approx(np.percentile(np.arange(1000), 99))
    assert dbg.display_scale(np.zeros((5, 3))) == 1.0
    assert dbg.display_scale(np.zeros((0, 3))) == 1.0


def test_empty_photons_give_an_empty_overlay():
    cam = camera_looking_along_y()
    with Accelerator(wall_mesh(), threads=1) as accel:
        image = dbg.photon_overlay(cam, accel, np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32))
    assert image.shape == (H, W, 4) and not image.any()
    # No triangles at all: nothing occludes, photons still project.
    with Accelerator(np.zeros((0, 3, 3), np.float32), threads=1) as accel:
        image = dbg.photon_overlay(cam, accel, PHOTON, FLUX, dot_radius_px=0)
    assert lit_pixels(image) == [pinhole_pixel(PHOTON[0])]


def test_zero_flux_gives_black_dots_not_nan():
    cam = camera_looking_along_y()
    with Accelerator(wall_mesh(), threads=1) as accel:
        image = dbg.photon_overlay(cam, accel, PHOTON, np.zeros((1, 3), np.float32))
    assert np.isfinite(image).all()
    assert image[..., 3].sum() == 5 and not image[..., :3].any()


def test_bad_input_names_the_argument():
    cam = camera_looking_along_y()
    accel = BruteForceAccelerator(wall_mesh())
    with pytest.raises(ValueError, match="dot_radius_px"):
        dbg.photon_overlay(cam, accel, PHOTON, FLUX, dot_radius_px=-1)
    with pytest.raises(ValueError, match="flux"):
        dbg.photon_overlay(cam, accel, PHOTON, np.ones((2, 3)))
    with pytest.raises(ValueError, match="positions"):
        dbg.photon_overlay(cam, accel, np.array([[np.nan, 0, 0]]), FLUX)
    with pytest.raises(ValueError, match="scale"):
        dbg.photon_overlay(cam, accel, PHOTON, FLUX, scale=0.0)
    with pytest.raises(ValueError, match="overlay_map"):
        dbg.select_photons(None, None, "ALL")


class _Map:
    def __init__(self, positions, flux):
        self.positions, self.flux = positions, flux


def test_select_photons_picks_the_maps():
    g = _Map(np.ones((2, 3), np.float32), np.full((2, 3), 1.0, np.float32))
    c = _Map(np.zeros((3, 3), np.float32), np.full((3, 3), 2.0, np.float32))
    assert dbg.select_photons(g, c, "global")[0].shape == (2, 3)
    assert dbg.select_photons(g, c, "caustic")[1][0, 0] == 2.0
    pos, flux = dbg.select_photons(g, None, "both")
    assert pos.shape == (2, 3) and pos.dtype == np.float32
    assert dbg.select_photons(g, c, "both")[0].shape == (5, 3)
    assert dbg.select_photons(None, None, "both")[0].shape == (0, 3)


def test_composite_over():
    combined = np.full((2, 2, 3), 0.5, np.float32)
    overlay = np.zeros((2, 2, 4), np.float32)
    overlay[0, 1] = [1.0, 0.0, 2.0, 1.0]
    out = dbg.composite_over(combined, overlay)
    np.testing.assert_array_equal(out[0, 1], [1.0, 0.0, 2.0])
    np.testing.assert_array_equal(out[1], combined[1])
    with pytest.raises(ValueError, match="overlay"):
        dbg.composite_over(combined, overlay[..., :3])


def test_photons_on_a_grazing_surface_far_from_the_origin_all_show(rng):
    """A tilted plane 1.6 km from the origin seen at down to 0.75 degrees: every photon on it
    (on the float32 triangles themselves, as the tracer stores them) is drawn.

    This is what the tolerance is for (measured): stopping the ray eps/4 short of the
    photon hides a quarter of them, 1 eps short 2 % (the most grazing), 4 eps none; the
    code uses 16.
    """
    origin = np.array([1234.567, 987.654, 321.123])
    normal = np.array([0.1, -0.05, 1.0]) / np.linalg.norm([0.1, -0.05, 1.0])
    u = np.cross(normal, [1.0, 0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    mesh = shapes.assemble([(shapes.quad(origin + [0, 20, 0], 60 * u, 60 * v), 0)])
    corners = mesh.vertices.astype(np.float64)[mesh.triangles]
    n = 5000
    tri = rng.integers(0, 2, n)
    s, r = np.sqrt(rng.uniform(0, 1, n)), rng.uniform(0, 1, n)
    bary = np.column_stack([1 - s, s * (1 - r), s * r])
    pts = np.einsum("nk,nkj->nj", bary, corners[tri]).astype(np.float32)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = [1, 0, 0], [0, 0, 1], [0, -1, 0], origin + 0.3 * normal
    cam = Camera(to_world=m, width=400, height=200, film_size=np.array([2.0, 1.0]), clip_start=0.5)
    with Accelerator(mesh, threads=1) as accel:
        visible, pixel = dbg.visible_photons(cam, accel, pts, extent=120.0)
    in_frame = (pixel[:, 0] >= 0) & (pixel[:, 0] < 400) & (pixel[:, 1] >= 0) & (pixel[:, 1] < 200)
    ahead = (pts - m[:3, 3]) @ np.array([0.0, 1.0, 0.0]) > 0.5
    seen = in_frame & ahead
    cos = np.abs((pts - m[:3, 3]) @ normal) / np.linalg.norm(pts - m[:3, 3], axis=1)
    assert seen.sum() > 1000 and cos[seen].min() < 0.015
    assert visible[seen].all()


# --- in the render (core/integrators/photon_mapping.py) ---------------------------------------------------

def _wall_scene():
    """wall_mesh() (diffuse, albedo 0.5) lit by a point light in front of it, seen by
    camera_looking_along_y()."""
    from core.scene.contract import LIGHT_POINT, Lights, Materials, Scene

    lights = Lights.from_list([{"kind": LIGHT_POINT, "position": [0.0, -1.0, 1.0], "power": 20.0}])
    return Scene(wall_mesh(), Materials.from_list([{"diffuse": [0.5, 0.5, 0.5]}]), lights,
                 camera_looking_along_y())


def _hand_built_map():
    """Six photons on the wall, far enough apart for their dots (radius 0) not to meet;
    flux rises with the index so each dot's colour names its photon."""
    from core.photons.photon_map import PhotonMap

    x = np.array([-0.61, -0.23, 0.17, 0.41, 0.07, -0.37])
    z = np.array([0.83, 1.07, 1.31, 0.91, 0.71, 1.23])
    positions = np.stack([x, np.zeros(6), z], axis=1).astype(np.float32)
    flux = np.outer(np.arange(1, 7), [1.0, 0.5, 0.25]).astype(np.float32)
    directions = np.tile([0.0, -1.0, 0.0], (6, 1))
    return PhotonMap(positions, flux, directions)


def test_render_adds_the_photons_pass_only_when_asked_and_combined_stays_the_sum():
    import types

    from core.integrators import photon_mapping as integrator
    from core.settings import RenderSettings

    scene = _wall_scene()
    pm = _hand_built_map()
    maps = types.SimpleNamespace(global_map=pm, caustic_map=None, global_emitted=0,
                                 caustic_emitted=0, stats={})
    base = RenderSettings(samples=1, caustics=False, indirect_mode="preview", global_k=4)

    off = integrator.render(scene, base, photon_maps=maps)
    assert "photons" not in off.passes
    assert off.photon_maps.global_map is pm and off.photon_maps.caustic_map is None

    on = integrator.render(scene, base.with_values(photon_debug_pass=True, overlay_dot_radius=0.0),
                           photon_maps=maps)
    dots = on.passes["photons"]
    assert dots.shape == (H, W, 4) and dots.dtype == np.float32
    # One pixel per photon, where the pinhole formula puts it, coloured flux / 99th pct.
    expected = [pinhole_pixel(p) for p in pm.positions]
    assert len(set(expected)) == 6
    assert lit_pixels(dots) == sorted(expected)
    scale = np.percentile(pm.flux.max(axis=1), 99.0)
    for (col, row), flux in zip(expected, pm.flux):
        np.testing.assert_allclose(dots[row, col, :3], flux / scale, rtol=1e-6)
    assert np.all(np.isfinite(dots)) and dots.min() >= 0
    # The debug pass is not a light pass: combined is still exactly their sum, and the
    # image is the one rendered without the pass.
    total = sum(on.passes[k].astype(np.float64) for k in integrator.PASSES).astype(np.float32)
    np.testing.assert_array_equal(on.passes["combined"], total)
    for name in ("combined",) + integrator.PASSES:
        np.testing.assert_array_equal(on.passes[name], off.passes[name], err_msg=name)
    assert on.passes["combined"].max() > 0

    # Composited: the dots replace combined where they are, nothing else changes.
    composite = base.with_values(photon_debug_pass=True, overlay_dot_radius=0.0,
                                 overlay_composite=True)
    comp = integrator.render(scene, composite, photon_maps=maps)
    lit = dots[..., 3] == 1
    np.testing.assert_array_equal(comp.passes["combined"][lit], dots[lit][:, :3])
    np.testing.assert_array_equal(comp.passes["combined"][~lit], total[~lit])
    np.testing.assert_array_equal(comp.passes["photons"], dots)

    # The caustic map was not given: its debug pass is there, and empty.
    caustic = integrator.render(scene, base.with_values(photon_debug_pass=True,
                                                        overlay_map="caustic"), photon_maps=maps)
    assert caustic.passes["photons"].shape == (H, W, 4) and not caustic.passes["photons"].any()


def test_debug_settings_are_validated_by_name():
    from core import settings as core_settings
    from core.settings import RenderSettings, SettingsError

    assert core_settings.OVERLAY_MAPS == dbg.OVERLAY_MAPS
    assert core_settings.MAX_DOT_RADIUS_PX == dbg.MAX_DOT_RADIUS_PX
    s = RenderSettings()
    assert (s.photon_debug_pass, s.overlay_map, s.overlay_dot_radius, s.overlay_composite) == (
        False, "both", 1.0, False)
    for name, bad in (("photon_debug_pass", 1), ("overlay_composite", "yes"),
                      ("overlay_map", "Both"), ("overlay_dot_radius", -0.5),
                      ("overlay_dot_radius", 32.5), ("overlay_dot_radius", float("nan")),
                      ("overlay_dot_radius", True)):
        with pytest.raises(SettingsError, match=name):
            s.with_values(**{name: bad})
    assert s.with_values(overlay_dot_radius=32).overlay_dot_radius == 32
    assert s.with_strings({"photon_debug_pass": "on", "overlay_dot_radius": "2.5"}) == s.with_values(
        photon_debug_pass=True, overlay_dot_radius=2.5)
