"""Camera rays: pixel -> direction (row 0 at the top), orthographic, lens shift, clipping."""

import numpy as np
import pytest

from core.scene import camera
from core.integrators import photon_mapping as integrator
from core.scene import shapes
from core.scene.contract import (CAMERA_ORTHOGRAPHIC, Camera, Lights, Materials, Scene)
from core.settings import RenderSettings


def identity_camera(**kw):
    """At the origin, looking down -Z, +Y up; 4 x 2 pixels, 90 degrees horizontally."""
    args = dict(to_world=np.eye(4), width=4, height=2, film_size=np.array([2.0, 1.0]))
    args.update(kw)
    return Camera(**args)


def test_pixel_centres_map_to_the_film_top_row_first():
    cam = identity_camera()
    pix = np.array([0, 3, 4, 7])  # top-left, top-right, bottom-left, bottom-right
    rays = camera.generate_rays(cam, pix, np.full((4, 2), 0.5))
    expected = np.array([[-0.75, 0.25, -1], [0.75, 0.25, -1], [-0.75, -0.25, -1], [0.75, -0.25, -1]])
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    np.testing.assert_allclose(rays.directions, expected, atol=1e-12)


def test_jitter_spans_the_pixel():
    cam = identity_camera()
    rays = camera.generate_rays(cam, np.array([0, 0]), np.array([[0.0, 0.0], [1.0, 1.0]]))
    d = rays.directions / -rays.directions[:, 2:3]
    # Pixel 0 covers x in [-1, -0.5] and y in [0.5, 0] (top row).
    np.testing.assert_allclose(d[:, :2], [[-1.0, 0.5], [-0.5, 0.0]], atol=1e-12)


def test_camera_frame_rotation_and_position():
    eye = np.array([1.0, 2.0, 3.0])
    m = shapes.look_at(eye, [1.0, 12.0, 3.0])  # looking along +Y, Z up
    cam = identity_camera(to_world=m, width=1, height=1, film_size=np.array([1.0, 1.0]))
    rays = camera.generate_rays(cam, np.array([0]), np.array([[0.5, 0.5]]))
    np.testing.assert_allclose(rays.directions[0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(rays.origins[0], eye + cam.clip_start * np.array([0, 1, 0]), atol=1e-12)


def test_blender_focal_length_convention():
    """50 mm lens on a 36 mm sensor: the frame edge is at atan(18 / 50)."""
    cam = identity_camera(width=2, height=2, film_size=np.array([36 / 50, 36 / 50]))
    rays = camera.generate_rays(cam, np.array([1]), np.array([[1.0, 0.5]]))
    assert np.arctan2(rays.directions[0, 0], -rays.directions[0, 2]) == pytest.approx(np.arctan(18 / 50))


def test_lens_shift_moves_the_frame():
    cam = identity_camera(width=1, height=1, film_size=np.array([1.0, 1.0]), film_shift=np.array([0.1, -0.2]))
    d = camera.generate_rays(cam, np.array([0]), np.array([[0.5, 0.5]])).directions[0]
    np.testing.assert_allclose(d / -d[2], [0.1, -0.2, -1.0], atol=1e-12)


def test_orthographic_rays_are_parallel_and_spread_over_the_film():
    cam = identity_camera(kind=CAMERA_ORTHOGRAPHIC, film_size=np.array([4.0, 2.0]), clip_start=0.5)
    rays = camera.generate_rays(cam, np.arange(8), np.full((8, 2), 0.5))
    np.testing.assert_allclose(rays.directions, np.tile([0, 0, -1.0], (8, 1)))
    np.testing.assert_allclose(rays.origins[:4, 0], [-1.5, -0.5, 0.5, 1.5])
    np.testing.assert_allclose(rays.origins[[0, 4], 1], [0.5, -0.5])
    np.testing.assert_allclose(rays.origins[:, 2], -0.5)


def test_orthographic_depth_of_field_meets_at_the_focus_distance():
    """Cycles' orthographic thin lens: every lens sample of a film point (x, y) starts on
    the near clip plane at (x, y) + lens offset moved along the ray, and passes through
    (x, y) at the focus distance; the offsets fill the aperture (radius 0.3 here)."""
    cam = identity_camera(kind=CAMERA_ORTHOGRAPHIC, film_size=np.array([4.0, 2.0]),
                          clip_start=0.5, clip_end=20.0, aperture_radius=0.3,
                          focus_distance=3.0)
    assert camera.has_aperture(cam)
    n = 4000
    pixel = np.full(n, 5)  # column 1, row 1: film point (-0.5, -0.5) at the pixel centre
    lens = np.random.default_rng(3).random((n, 2))
    rays = camera.generate_rays(cam, pixel, np.full((n, 2), 0.5), lens)
    np.testing.assert_allclose(np.linalg.norm(rays.directions, axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(rays.origins[:, 2], -0.5, rtol=1e-12)  # on the near plane
    t = (3.0 - 0.5) / -rays.directions[:, 2]
    focus = rays.origins + t[:, None] * rays.directions
    np.testing.assert_allclose(focus, np.tile([-0.5, -0.5, -3.0], (n, 1)), atol=1e-12)
    back = rays.origins - (0.5 / -rays.directions[:, 2])[:, None] * rays.directions  # depth 0
    offset = back[:, :2] - [-0.5, -0.5]
    r = np.linalg.norm(offset, axis=1)
    assert r.max() <= 0.3 + 1e-12 and r.max() > 0.29
    assert abs(np.mean(r <= 0.15) - 0.25) < 0.03  # uniform over the disk's area
    np.testing.assert_array_equal(rays.tmax, 20.0 - 0.5)  # Cycles: cliplength along D


def test_clipping_planes_are_depths_like_cycles():
    cam = identity_camera(clip_start=0.5, clip_end=10.0)
    rays = camera.generate_rays(cam, np.arange(8), np.random.default_rng(1).random((8, 2)))
    depth_near = -rays.origins[:, 2]
    depth_far = -(rays.origins + rays.tmax[:, None] * rays.directions)[:, 2]
    np.testing.assert_allclose(depth_near, 0.5, rtol=1e-12)
    np.testing.assert_allclose(depth_far, 10.0, rtol=1e-12)


def test_a_marker_renders_at_its_projected_pixel():
    """End to end: a small emitter at a pixel's centre lights that pixel and no other."""
    w, h = 24, 16
    cam = shapes.pinhole([0.3, -4.0, 1.2], [0.0, 0.0, 0.5], w, h, np.radians(50))
    col, row, depth = 14, 5, 4.0
    # Independent of camera.py: local film point of the pixel centre, row 0 at the top.
    local = np.array([((col + 0.5) / w - 0.5) * cam.film_size[0],
                      (0.5 - (row + 0.5) / h) * cam.film_size[1], -1.0]) * depth
    target = (cam.to_world @ np.append(local, 1.0))[:3]
    pixel_size = depth * cam.film_size[0] / w
    right, up = cam.to_world[:3, 0], cam.to_world[:3, 1]
    marker = shapes.quad(target, 0.15 * pixel_size * right, 0.15 * pixel_size * up)
    scene = Scene(shapes.assemble([(marker, 0)]), Materials.from_list([{"emission": [1, 1, 1]}]),
                  Lights.empty(), cam)
    # every pixel all 64 samples: adaptive sampling would stop a pixel whose first samples
    # all missed the marker
    img = integrator.render(scene, RenderSettings(samples=64, adaptive_threshold=0.0)
                            ).passes["emission"][..., 0]
    assert np.unravel_index(np.argmax(img), img.shape) == (row, col)
    assert np.count_nonzero(img) == 1
    # The marker covers 0.3 x 0.3 of the pixel.
    assert img[row, col] == pytest.approx(0.09, abs=0.05)
    np.testing.assert_allclose(camera.project(cam, target[None])[0], [col + 0.5, row + 0.5], atol=1e-9)


def _frustum(l, r, b, t, n, f):
    """OpenGL's glFrustum matrix."""
    return np.array([[2 * n / (r - l), 0, (r + l) / (r - l), 0],
                     [0, 2 * n / (t - b), (t + b) / (t - b), 0],
                     [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)],
                     [0, 0, -1, 0]])


def _ortho(l, r, b, t, n, f):
    """OpenGL's glOrtho matrix."""
    return np.array([[2 / (r - l), 0, 0, -(r + l) / (r - l)],
                     [0, 2 / (t - b), 0, -(t + b) / (t - b)],
                     [0, 0, -2 / (f - n), -(f + n) / (f - n)],
                     [0, 0, 0, 1]])


@pytest.mark.parametrize("projection", [
    _frustum(-0.3, 0.5, -0.2, 0.25, 0.1, 50.0),   # off-centre (a panned / shifted view)
    _frustum(-1.0, 1.0, -0.75, 0.75, 0.01, 1e3),
    _ortho(-2.0, 3.0, -1.0, 2.5, 0.5, 40.0),
    _ortho(-2.0, 3.0, -1.0, 2.5, -30.0, 40.0),   # Blender's ortho viewport: both sides
])
def test_camera_from_projection_sends_each_sample_where_the_matrix_projects_it(projection, rng):
    """A view given as OpenGL matrices (Blender's viewport): the ray of a sample at pixel
    (c + jx, r + jy) is the set of points the matrices put there, from the near plane
    (z_ndc = -1) to the far plane (z_ndc = +1)."""
    angle = 0.7
    to_world = np.eye(4)
    to_world[:3, :3] = [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0],
                        [-np.sin(angle), 0, np.cos(angle)]]
    to_world[:3, 3] = [3.0, -2.0, 1.5]
    w, h = 40, 30
    cam = camera.camera_from_projection(to_world, projection, w, h)
    pixel = rng.integers(0, w * h, 200)
    jitter = rng.random((200, 2))
    rays = camera.generate_rays(cam, pixel, jitter)
    clip = projection @ np.linalg.inv(to_world)
    for t, z_expected in ((0.0, -1.0), (0.37, None), (1.0, 1.0)):
        points = rays.origins + (t * rays.tmax)[:, None] * rays.directions
        h4 = np.c_[points, np.ones(len(points))] @ clip.T
        ndc = h4[:, :3] / h4[:, 3:]
        np.testing.assert_allclose((ndc[:, 0] + 1) / 2 * w, pixel % w + jitter[:, 0], atol=1e-6)
        np.testing.assert_allclose((1 - ndc[:, 1]) / 2 * h, pixel // w + jitter[:, 1], atol=1e-6)
        if z_expected is not None:
            np.testing.assert_allclose(ndc[:, 2], z_expected, atol=1e-6)


def test_camera_from_projection_refuses_other_matrices():
    with pytest.raises(ValueError, match="not a perspective or orthographic"):
        camera.camera_from_projection(np.eye(4), np.eye(4) * 2 + np.eye(4, k=1), 4, 4)
    with pytest.raises(ValueError, match="zero scale"):
        camera.camera_from_projection(np.eye(4), np.zeros((4, 4)), 4, 4)
    with pytest.raises(ValueError, match="finite"):
        camera.camera_from_projection(np.full((4, 4), np.nan), np.eye(4), 4, 4)
    # An orthographic viewport's near plane behind the eye: the origin moves back to it.
    cam = camera.camera_from_projection(np.eye(4), _ortho(-1, 1, -1, 1, -10.0, 10.0), 4, 4)
    assert (cam.clip_start, cam.clip_end) == (0.0, 20.0)
    np.testing.assert_allclose(cam.to_world[:3, 3], [0.0, 0.0, 10.0])


# --- the Render Region (issue 11 part 3) ------------------------------------------------------

def test_region_pixels_are_the_frame_indices_row_major():
    import dataclasses
    from core.scene import camera as cam_mod
    cam = shapes.pinhole([0, -3, 0], [0, 0, 0], 7, 5, 0.8)
    assert cam_mod.region_of(cam) == (0, 0, 7, 5)
    np.testing.assert_array_equal(cam_mod.region_pixels(cam), np.arange(35))
    cut = dataclasses.replace(cam, region=(2, 1, 5, 3))
    np.testing.assert_array_equal(cam_mod.region_pixels(cut), [9, 10, 11, 16, 17, 18])
    frame = np.arange(35).reshape(5, 7, 1)
    np.testing.assert_array_equal(cam_mod.crop_to_region(frame, cut)[..., 0],
                                  [[9, 10, 11], [16, 17, 18]])


@pytest.mark.parametrize("region", [(0, 0, 8, 5), (3, 2, 3, 4), (-1, 0, 2, 2), (0, 0, 2.5, 2)])
def test_a_region_outside_the_frame_is_refused(region):
    import dataclasses
    from core.scene.contract import SceneError
    cam = dataclasses.replace(shapes.pinhole([0, -3, 0], [0, 0, 0], 7, 5, 0.8), region=region)
    scene = Scene(shapes.assemble([]), Materials.from_list([{}]), Lights.empty(), cam)
    with pytest.raises(SceneError, match="render region"):
        scene.validate()
