"""Embree against the brute-force oracle: hits, distances, barycentrics, occlusion."""

import numpy as np
import pytest

from core.scene.accel import Accelerator, BruteForceAccelerator
from core.scene import shapes


def random_rays(rng, n, spread=2.0):
    o = rng.uniform(-spread, spread, (n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o, d


@pytest.fixture
def soup(rng):
    """Random triangles: overlapping, all orientations, some slivers."""
    return rng.uniform(-1, 1, (300, 3, 3)).astype(np.float32)


def test_intersect_matches_brute_force(rng, soup):
    o, d = random_rays(rng, 5000)
    with Accelerator(soup, threads=2) as emb:
        a = emb.intersect(o, d)
    b = BruteForceAccelerator(soup).intersect(o, d)
    assert a.prim.dtype == np.int32 and a.t.dtype == np.float32
    hit = b.prim >= 0
    assert 0.1 < hit.mean() < 0.9  # the test exercises both hits and misses
    # Near-ties between two triangles at the same distance may pick either: compare t.
    same = a.prim == b.prim
    assert same.mean() > 0.999
    np.testing.assert_allclose(a.t[hit], b.t[hit], rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(a.u[hit & same], b.u[hit & same], atol=1e-4)
    np.testing.assert_allclose(a.v[hit & same], b.v[hit & same], atol=1e-4)
    assert np.all(np.isinf(a.t[~hit])) and np.all(a.prim[~hit] == -1)


def test_barycentrics_reconstruct_the_hit_point(rng, soup):
    o, d = random_rays(rng, 2000)
    with Accelerator(soup) as emb:
        h = emb.intersect(o, d)
    k = h.prim >= 0
    tri = soup[h.prim[k]].astype(np.float64)
    u, v = h.u[k, None].astype(np.float64), h.v[k, None].astype(np.float64)
    p_bary = (1 - u - v) * tri[:, 0] + u * tri[:, 1] + v * tri[:, 2]
    p_ray = o[k] + h.t[k, None] * d[k]
    np.testing.assert_allclose(p_bary, p_ray, atol=1e-4)


def test_tfar_bounds_the_hits(rng, soup):
    o, d = random_rays(rng, 3000)
    tfar = rng.uniform(0.1, 3.0, 3000)
    with Accelerator(soup, threads=2) as emb:
        a = emb.intersect(o, d, tfar)
        occ = emb.occluded(o, d, tfar)
    b = BruteForceAccelerator(soup).intersect(o, d, tfar)
    assert np.mean((a.prim >= 0) == (b.prim >= 0)) > 0.999
    assert np.all(a.t[a.prim >= 0] <= tfar[a.prim >= 0] * (1 + 1e-6))
    # occluded() is "is there any hit within tfar": the same as intersect finding one.
    assert np.mean(occ == (b.prim >= 0)) > 0.999
    assert 0.1 < occ.mean() < 0.9


def test_occluded_matches_brute_force(rng, soup):
    o, d = random_rays(rng, 4000)
    with Accelerator(soup, threads=2) as emb:
        occ = emb.occluded(o, d, 0.7)
    ref = BruteForceAccelerator(soup).occluded(o, d, 0.7)
    assert occ.dtype == bool
    assert np.mean(occ == ref) > 0.999


def test_threaded_batches_equal_single_thread(rng, soup):
    o, d = random_rays(rng, 20000)
    with Accelerator(soup, threads=1) as one, Accelerator(soup, threads=2) as two:
        a, b = one.intersect(o, d), two.intersect(o, d)
        np.testing.assert_array_equal(a.prim, b.prim)
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(one.occluded(o, d, 1.0), two.occluded(o, d, 1.0))


def test_box_seen_from_inside_always_hit(rng):
    part = shapes.box([-1, -1, -1], [1, 1, 1], inward=True)
    with Accelerator(part.corners.astype(np.float32)) as emb:
        o = rng.uniform(-0.9, 0.9, (1000, 3))
        _, d = random_rays(rng, 1000)
        h = emb.intersect(o, d)
    assert np.all(h.prim >= 0)


@pytest.mark.parametrize("cls", [Accelerator, BruteForceAccelerator])
def test_empty_scene_and_empty_batches(cls, rng):
    empty = cls(np.zeros((0, 3, 3), np.float32))
    o, d = random_rays(rng, 5)
    h = empty.intersect(o, d)
    assert np.all(h.prim == -1) and np.all(np.isinf(h.t))
    assert not np.any(empty.occluded(o, d, 10.0))
    full = cls(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32))
    h0 = full.intersect(np.zeros((0, 3)), np.zeros((0, 3)))
    assert h0.prim.shape == (0,) and full.occluded(np.zeros((0, 3)), np.zeros((0, 3)), 1.0).shape == (0,)
    empty.close()
    full.close()


def test_accepts_mesh_and_non_contiguous_float64(rng):
    mesh = shapes.assemble([(shapes.quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), 0)])
    with Accelerator(mesh) as emb:
        o = np.asfortranarray(np.array([[0.2, 0.3, 1.0], [5.0, 5.0, 1.0]]))
        d = np.array([[0, 0, -1.0], [0, 0, -1.0]])[:, :]
        h = emb.intersect(o, d)
    assert h.prim[0] >= 0 and h.prim[1] == -1
    assert h.t[0] == pytest.approx(1.0, rel=1e-6)


def test_mismatched_shapes_raise():
    with Accelerator(np.zeros((1, 3, 3), np.float32)) as emb:
        with pytest.raises(ValueError, match="same shape"):
            emb.intersect(np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"\(T, 3, 3\)"):
        Accelerator(np.zeros((4, 3), np.float32))
