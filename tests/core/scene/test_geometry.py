"""core/scene/geometry.py: the scale-invariant offset rule, surface points from
barycentrics (position, geometric and interpolated normals, facing the ray) and offset ray
origins that neither re-hit their own triangle nor shadow a point just above it, with
Embree (core/scene/accel.py) at coordinates from 1e-3 to 1e5."""

import numpy as np
import pytest

from core.scene import geometry
from core.scene.accel import Accelerator

# A tilted triangle (no axis-aligned plane: Embree's plane test rounds in every axis).
BASE = np.array([[0.0, 0.0, 0.0], [1.0, 0.2, 0.1], [0.3, 1.0, 0.45]])
CORNER_NORMALS = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, -0.28, 0.96]])


def triangle(centre, size, normals=None):
    """(1, 3, 3) float32 corners at centre * (1, 0.7, -0.4) + size * BASE, and normals."""
    c = np.asarray(centre * np.array([1.0, 0.7, -0.4]))
    tv = (c + size * BASE)[None].astype(np.float32)
    if normals is None:
        g = np.cross(tv[0, 1].astype(np.float64) - tv[0, 0], tv[0, 2].astype(np.float64) - tv[0, 0])
        normals = np.repeat((g / np.linalg.norm(g))[None], 3, axis=0)
    return tv, np.asarray(normals, np.float32)[None]


def barycentrics(rng, n):
    b = rng.random((n, 2))
    return np.where(b.sum(axis=1, keepdims=True) > 1, 1 - b, b)


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


# --- the offset rule --------------------------------------------------------------------

@pytest.mark.parametrize("scale", [1e-3, 1e3, 1e-6, 1e6])
def test_offset_eps_scales_with_the_scene(scale, rng):
    pts = rng.normal(size=(200, 3)) * rng.uniform(0.01, 100.0, (200, 1))
    extent = 7.5
    eps = np.array([geometry.offset_eps(x, y, z, extent) for x, y, z in pts])
    scaled = np.array([geometry.offset_eps(x, y, z, extent * scale) for x, y, z in pts * scale])
    np.testing.assert_allclose(scaled, eps * scale, rtol=1e-14)
    np.testing.assert_allclose(geometry.point_eps(pts * scale, extent * scale), scaled,
                               rtol=1e-15)


def test_offset_eps_is_8_to_16_float32_steps_of_the_coordinate_and_the_extent(rng):
    # eps = 2^-20 (max |p_i| + extent): 8-16 float32 ulps of the largest coordinate when
    # the scene is small next to it, the same of the extent at the world origin.
    m = np.exp(rng.uniform(np.log(1e-4), np.log(1e6), 500))
    pts = np.c_[m * rng.choice([-1, 1], 500), m * rng.uniform(-1, 1, 500), m * 0.5]
    eps = geometry.point_eps(pts, 0.0)
    ulp = np.spacing(np.float32(m)).astype(np.float64)
    assert np.all((eps / ulp >= 8) & (eps / ulp < 16))
    np.testing.assert_allclose(geometry.point_eps(np.zeros((1, 3)), 3.0), 3.0 * 2.0 ** -20)
    # The largest coordinate, whatever its axis or sign; the extent adds.
    assert geometry.offset_eps(0.0, -5.0, 2.0, 1.0) == 6.0 * 2.0 ** -20
    assert geometry.offset_eps(0.5, 0.0, -8.0, 0.0) == 8.0 * 2.0 ** -20
    assert geometry.scene_extent(np.array([0, -1, 2.0]), np.array([3, 4, 2.5])) == 5.0


# --- surface points ---------------------------------------------------------------------

def expected_point(tv, tn, b1, b2):
    v = tv[0].astype(np.float64)
    n = tn[0].astype(np.float64)
    b0 = 1 - b1 - b2
    pos = b0[:, None] * v[0] + b1[:, None] * v[1] + b2[:, None] * v[2]
    ng = unit(np.cross(v[1] - v[0], v[2] - v[0]))
    ns = unit(b0[:, None] * n[0] + b1[:, None] * n[1] + b2[:, None] * n[2])
    return pos, np.broadcast_to(ng, pos.shape), ns


@pytest.mark.parametrize("centre, size", [(0.0, 1.0), (1e3, 2.0), (1e-3, 1e-3)])
def test_surface_points_at_known_barycentrics(centre, size, rng):
    tv, tn = triangle(centre, size, CORNER_NORMALS)
    b = np.vstack([[[0, 0], [1, 0], [0, 1], [1 / 3, 1 / 3], [0.5, 0.5]], barycentrics(rng, 50)])
    u, v = b[:, 0].astype(np.float32), b[:, 1].astype(np.float32)
    n = b.shape[0]
    d = unit(rng.normal(size=(n, 3)))
    sp = geometry.surface_points(tv, tn, np.array([4], np.int32), np.zeros(n, np.int32), u, v,
                                 d, 2.5 * size)
    pos, ng, ns = expected_point(tv, tn, u.astype(np.float64), v.astype(np.float64))
    np.testing.assert_allclose(sp.position, pos, rtol=1e-14, atol=1e-15 * size)
    np.testing.assert_allclose(sp.geometric_normal, ng, atol=1e-12)
    np.testing.assert_allclose(sp.shading_normal, ns, atol=1e-7)  # float32 corner normals
    # At the corners the shading normal is that corner's.
    np.testing.assert_allclose(sp.shading_normal[:3], unit(CORNER_NORMALS), atol=1e-7)
    assert np.all(sp.material == 4)
    np.testing.assert_allclose(sp.eps, geometry.point_eps(pos, 2.5 * size), rtol=1e-14)


def test_surface_points_fall_back_to_the_geometric_normal(rng):
    tv, _ = triangle(0.0, 1.0)
    g = unit(np.cross(BASE[1] - BASE[0], BASE[2] - BASE[0]))
    away = np.array([-g, -g, -g])  # shading normals on the far side: a bad export
    zero = np.zeros((3, 3))
    d = np.array([[0.0, 0.0, -1.0]])
    for normals in (away, zero):
        sp = geometry.surface_points(tv, normals.astype(np.float32)[None], np.zeros(1, np.int32),
                                     np.zeros(1, np.int32), np.float32([0.2]), np.float32([0.3]),
                                     d, 1.0)
        np.testing.assert_allclose(sp.shading_normal[0], g, atol=1e-7)
    # A zero-area triangle: both normals are -d, never NaN.
    flat = np.array([[[0, 0, 0], [1, 1, 1], [2, 2, 2]]], np.float32)
    dd = unit([[0.3, -0.5, 0.2]])
    sp = geometry.surface_points(flat, np.zeros((1, 3, 3), np.float32), np.zeros(1, np.int32),
                                 np.zeros(1, np.int32), np.float32([0.5]), np.float32([0.25]),
                                 dd, 1.0)
    np.testing.assert_allclose(sp.geometric_normal, -dd)
    np.testing.assert_allclose(sp.shading_normal, -dd)
    np.testing.assert_allclose(sp.position, [[1.0, 1.0, 1.0]])


def test_facing_surface_points_flip_to_face_the_ray(rng):
    tv, tn = triangle(0.0, 1.0, CORNER_NORMALS)
    n = 400
    b = barycentrics(rng, n)
    u, v = b[:, 0].astype(np.float32), b[:, 1].astype(np.float32)
    d = unit(rng.normal(size=(n, 3)))
    mat = np.array([7], np.int32)
    prim = np.zeros(n, np.int32)
    sp = geometry.surface_points(tv, tn, mat, prim, u, v, d, 2.0)
    pos, ngf, nsf, m, eps, front = geometry.facing_surface_points(tv, tn, mat, prim, u, v, d, 2.0)
    want_front = np.einsum("ij,ij->i", d, sp.geometric_normal) < 0
    np.testing.assert_array_equal(front, want_front)
    assert 0.3 < front.mean() < 0.7
    sign = np.where(want_front, 1.0, -1.0)[:, None]
    np.testing.assert_array_equal(pos, sp.position)
    np.testing.assert_allclose(ngf, sign * sp.geometric_normal, atol=1e-15)
    np.testing.assert_allclose(nsf, sign * sp.shading_normal, atol=1e-15)
    # Both face the ray now.
    assert np.all(np.einsum("ij,ij->i", d, ngf) <= 0)
    assert np.all(m == 7)
    np.testing.assert_array_equal(eps, sp.eps)


def test_surface_points_of_embree_hits_lie_on_the_rays(rng):
    # The barycentric convention matches Embree's: the reconstructed point is o + t d.
    tv, tn = triangle(1.0, 1.0)
    n = 2000
    target = geometry.surface_points(tv, tn, np.zeros(1, np.int32), np.zeros(n, np.int32),
                                     *barycentrics(rng, n).T.astype(np.float32),
                                     np.zeros((n, 3)), 1.0).position
    # From 2 m away on either side, at least 17 degrees off the plane (along grazing rays
    # float32 rounding of the hit moves it far along the ray).
    g = unit(np.cross(BASE[1] - BASE[0], BASE[2] - BASE[0]))
    away = unit(rng.normal(size=(n, 3)))
    lifted = unit(away + 0.6 * np.sign(away @ g)[:, None] * g)
    away = np.where(np.abs(away @ g)[:, None] < 0.3, lifted, away)
    o = target + 2.0 * away
    d = unit(target - o)
    with Accelerator(tv, threads=1) as acc:
        hits = acc.intersect(o, d)
    ok = hits.prim == 0
    assert ok.mean() > 0.99
    sp = geometry.surface_points(tv, tn, np.zeros(1, np.int32), hits.prim[ok], hits.u[ok],
                                 hits.v[ok], d[ok], 1.0)
    on_ray = o[ok].astype(np.float32).astype(np.float64) + hits.t[ok, None] * d[ok]
    np.testing.assert_allclose(sp.position, on_ray, atol=1e-5)
    np.testing.assert_allclose(sp.position, target[ok], atol=1e-5)


# --- offset origins ---------------------------------------------------------------------

CASES = [(1e-3, 1e-3), (1.0, 1.0), (1e3, 1e3), (1e5, 1e5),
         (1e3, 1.0), (1e5, 1.0)]  # a 1 m triangle far from the origin


@pytest.mark.parametrize("centre, size", CASES)
def test_offset_rays_do_not_rehit_their_own_triangle(centre, size, rng):
    tv, tn = triangle(centre, size)
    extent = float(np.ptp(tv[0], axis=0).max())
    n = 100_000
    b = barycentrics(rng, n).astype(np.float32)
    d = unit(rng.normal(size=(n, 3)))  # both sides, grazing ones included
    sp = geometry.surface_points(tv, tn, np.zeros(1, np.int32), np.zeros(n, np.int32),
                                 b[:, 0].copy(), b[:, 1].copy(), -d, extent)
    o = geometry.offset_points(sp.position, sp.geometric_normal, sp.eps, d)
    # The origin moved eps to the side the ray leaves towards.
    side = np.sign(np.einsum("ij,ij->i", d, sp.geometric_normal))
    moved = np.einsum("ij,ij->i", o - sp.position, sp.geometric_normal)
    np.testing.assert_allclose(moved, side * sp.eps, rtol=1e-6)
    with Accelerator(tv, threads=1) as acc:
        hits = acc.intersect(o, d)
    # Measured: eps / 16 still never re-hits; eps / 64 re-hits 0.4-15 %; 0 re-hits 50 %.
    assert np.all(hits.prim == -1), (hits.prim >= 0).mean()


@pytest.mark.parametrize("centre, size", CASES)
def test_shadow_rays_to_points_just_above_are_clear(centre, size, rng):
    # From a surface point to a point k eps above another point of the same triangle:
    # a ray nearly parallel to the surface that must not see the surface.
    tv, tn = triangle(centre, size)
    extent = float(np.ptp(tv[0], axis=0).max())
    n = 50_000
    mat, prim = np.zeros(1, np.int32), np.zeros(n, np.int32)
    zero = np.zeros((n, 3))
    p = geometry.surface_points(tv, tn, mat, prim, *barycentrics(rng, n).T.astype(np.float32),
                                zero, extent)
    q = geometry.surface_points(tv, tn, mat, prim, *barycentrics(rng, n).T.astype(np.float32),
                                zero, extent)
    with Accelerator(tv, threads=1) as acc:
        for k in (1.0, 2.0, 16.0):
            light = q.position + (k * q.eps)[:, None] * q.geometric_normal
            to_light = unit(light - p.position)
            o = geometry.offset_points(p.position, p.geometric_normal, p.eps, to_light)
            v = light - o
            dist = np.linalg.norm(v, axis=1)
            blocked = acc.occluded(o, v / dist[:, None], dist)
            assert not blocked.any(), (k, blocked.mean())
        # The same light from below the surface is occluded (the test sees the surface).
        light = p.position + 0.5 * (q.position - p.position) - 0.01 * size * p.geometric_normal
        lift = p.position + 0.01 * size * p.geometric_normal
        v = light - lift
        dist = np.linalg.norm(v, axis=1)
        assert acc.occluded(lift, v / dist[:, None], dist).mean() > 0.99
