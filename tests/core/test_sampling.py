"""Random numbers and warps: reproducible, stratified, with the densities they claim."""

import numpy as np
import pytest

from core import sampling


def test_uniform_depends_only_on_the_counters():
    pixel = np.arange(1000, dtype=np.int64)
    sample = np.full(1000, 3, np.int64)
    a = sampling.uniform(7, pixel, sample, 11)
    b = sampling.uniform(7, pixel[::-1].copy(), sample, 11)[::-1]  # another order / batch
    np.testing.assert_array_equal(a, b)
    assert np.all((a >= 0) & (a < 1))
    assert not np.array_equal(a, sampling.uniform(8, pixel, sample, 11))
    assert not np.array_equal(a, sampling.uniform(7, pixel, sample, 12))


def test_uniform_is_uniform_and_uncorrelated():
    n = 200_000
    idx = np.arange(n, dtype=np.int64)
    u = sampling.uniform(1, idx, idx % 7, 0)
    v = sampling.uniform(1, idx, idx % 7, 1)
    hist, _ = np.histogram(u, bins=20, range=(0, 1))
    assert np.all(np.abs(hist - n / 20) < 5 * np.sqrt(n / 20))
    assert abs(np.corrcoef(u, v)[0, 1]) < 0.01


@pytest.mark.parametrize("n", [16, 64])
def test_stratified_sets_fill_every_elementary_interval(n):
    """Each pixel's n = 2^m points: one per cell of every 2^a x 2^(m-a) grid."""
    m = int(np.log2(n))
    for pixel in (0, 17, 123456):
        x, y = sampling.stratified2(5, np.full(n, pixel), np.arange(n), n, 9)
        for a in range(m + 1):
            cx = np.floor(x * 2 ** a).astype(int)
            cy = np.floor(y * 2 ** (m - a)).astype(int)
            assert len(set(zip(cx, cy))) == n, (pixel, a)


def test_stratified_dimensions_are_independent():
    n, pixels = 16, 4000
    pix = np.repeat(np.arange(pixels), n)
    idx = np.tile(np.arange(n), pixels)
    x1, y1 = sampling.stratified2(3, pix, idx, n, 1)
    x2, y2 = sampling.stratified2(3, pix, idx, n, 2)
    for a, b in ((x1, x2), (x1, y2), (y1, y2), (x1, y1)):
        assert abs(np.corrcoef(a, b)[0, 1]) < 0.02
    with pytest.raises(ValueError, match=r"\[0, 16\)"):
        sampling.stratified2(3, pix[:2], np.array([0, 16]), 16, 1)


def test_stream_ids_are_distinct():
    ids = {sampling.stream(p, b, l, k) for p in (1, 2) for b in range(3) for l in range(4) for k in range(3)}
    assert len(ids) == 2 * 3 * 4 * 3
    with pytest.raises(ValueError):
        sampling.stream(1, 5000)


def _u(n, dim=0):
    idx = np.arange(n, dtype=np.int64)
    return sampling.uniform(2, idx, idx, dim), sampling.uniform(2, idx, idx, dim + 1)


def test_cosine_hemisphere_density():
    d = sampling.sample_cosine_hemisphere(*_u(200_000))
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1, rtol=1e-12)
    assert np.all(d[:, 2] >= 0)
    # pdf = cos / pi: E[cos] = 2/3, E[cos^2] = 1/2.
    assert d[:, 2].mean() == pytest.approx(2 / 3, rel=0.005)
    assert (d[:, 2] ** 2).mean() == pytest.approx(0.5, rel=0.005)


def test_uniform_sphere_and_cone():
    s = sampling.sample_uniform_sphere(*_u(100_000))
    np.testing.assert_allclose(s.mean(axis=0), 0, atol=0.01)
    np.testing.assert_allclose(np.linalg.norm(s, axis=1), 1, rtol=1e-12)
    omc = 1 - np.cos(0.2)
    c = sampling.sample_uniform_cone(*_u(100_000), omc)
    assert c[:, 2].min() >= np.cos(0.2) - 1e-12
    # Uniform in solid angle: cos uniform on [cos_max, 1].
    assert c[:, 2].mean() == pytest.approx(1 - omc / 2, rel=1e-4)
    tiny = sampling.sample_uniform_cone(*_u(1000), 1e-12)
    assert np.all(tiny[:, 2] > 1 - 2e-12) and np.all(np.isfinite(tiny))


def test_disk_is_uniform():
    p = sampling.sample_uniform_disk(*_u(100_000))
    r2 = np.sum(p * p, axis=1)
    assert r2.max() <= 1.0
    assert r2.mean() == pytest.approx(0.5, rel=0.01)


def test_orthonormal_basis(rng):
    n = rng.normal(size=(1000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n[:4] = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, -1, 0]]
    t, b = sampling.orthonormal_basis(n)
    for a, c in ((t, b), (t, n), (b, n)):
        np.testing.assert_allclose(np.sum(a * c, axis=1), 0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1, rtol=1e-12)
    np.testing.assert_allclose(np.cross(t, b), n, atol=1e-12)  # right-handed


def test_pick_follows_the_cdf_ties_and_the_end():
    # zero-probability rows (ties in the cdf) are never picked; u at a step picks the next
    # row; rounding past the last entry picks the last row, never K
    cdf = np.array([0.25, 0.25, 0.75, 1.0])
    u = np.array([0.0, 0.2499, 0.25, 0.5, 0.75, 0.999, 1.0, 1.5])
    want = [0, 0, 2, 2, 3, 3, 3, 3]
    np.testing.assert_array_equal(sampling.pick_many(cdf, u), want)
    assert [sampling.pick(cdf, x) for x in u] == want
    n = 200_000
    j = sampling.pick_many(cdf, sampling.uniform(3, np.arange(n), np.zeros(n, np.int64), 0))
    np.testing.assert_allclose(np.bincount(j, minlength=4) / n, [0.25, 0, 0.5, 0.25],
                               atol=5 * np.sqrt(0.25 / n))
