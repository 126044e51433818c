"""core/photons/kdtree.py on its own, without PhotonMap: the balancing pieces (subtree
sizes, median selection, widest axis, the balanced heap checked subtree by subtree) and
the search kernels (``knn_search``, ``knn_search_coherent``, ``sort_heap``,
``heap_entry``, ``nearest_kernel`` with any query order, ``nearest_compatible_kernel``,
``query_order``) against brute force. tests/core/photons/test_photon_map.py checks the
same rules through ``PhotonMap.nearest``; here each function is called directly."""

import numpy as np
import pytest
from numba import njit

from core.photons import kdtree
from core.photons.kdtree import (balance, heap_entry, knn_scratch, knn_search, query_order,
                                 search_growth, sort_heap, tree_depth)


def point_set(name, rng, n):
    if name == "random":
        return rng.random((n, 3), dtype=np.float32)
    if name == "clustered":  # a few tight blobs in a big empty box, some stray points
        centres = rng.random((4, 3)) * 10.0
        p = centres[rng.integers(0, 4, n)] + rng.normal(0.0, 0.02, (n, 3))
        p[: n // 20] = rng.random((n // 20, 3)) * 10.0
        return p.astype(np.float32)
    if name == "duplicates":  # every point repeated many times: ties everywhere
        sites = np.round(rng.random((6, 3)) * 4.0).astype(np.float32)  # some shared coordinates
        return sites[rng.integers(0, 6, n)]
    if name == "grid":  # integer lattice: many exactly equal distances
        g = np.arange(7, dtype=np.float32)
        p = np.stack(np.meshgrid(g, g, g), axis=-1).reshape(-1, 3)
        return p[rng.permutation(p.shape[0])[:n]]
    raise ValueError(name)


# --- balance ----------------------------------------------------------------------------

def heap_subtree_size(node, n):
    """Nodes of the heap-ordered complete tree of n nodes under ``node``, counted."""
    size, first, width = 0, node, 1
    while first < n:
        size += min(width, n - first)
        first, width = 2 * first + 1, 2 * width
    return size


def test_left_subtree_size_is_that_of_the_complete_tree():
    for n in range(0, 600):
        want = heap_subtree_size(1, n) if n > 1 else 0
        assert kdtree._left_subtree_size(n) == want, n
    for n in (0, 1, 2, 3, 4, 7, 8, 1000, 2**20 - 1, 2**20):
        assert tree_depth(n) == (int(np.ceil(np.log2(n + 1))) if n else 0)


@pytest.mark.parametrize("shape", ["random", "duplicates", "grid"])
@pytest.mark.parametrize("n", [1, 2, 5, 13, 14, 200])
def test_select_puts_the_median_at_m(shape, n, rng):
    for trial in range(6):
        pts = point_set(shape, rng, n).copy()
        lo = int(rng.integers(0, n))
        hi = int(rng.integers(lo + 1, n + 1))
        m = int(rng.integers(lo, hi))
        ax = int(rng.integers(0, 3))
        work, src = pts.copy(), np.arange(n)
        kdtree._select(work, src, lo, hi, m, ax)
        # Rows outside [lo, hi) untouched; the rows are permuted along with src.
        np.testing.assert_array_equal(work[:lo], pts[:lo])
        np.testing.assert_array_equal(work[hi:], pts[hi:])
        np.testing.assert_array_equal(work, pts[src])
        np.testing.assert_array_equal(np.sort(src[lo:hi]), np.arange(lo, hi))
        # Row m holds the (m - lo)-th smallest value; the rows before are <=, after >=.
        col = work[lo:hi, ax]
        assert col[m - lo] == np.sort(pts[lo:hi, ax])[m - lo]
        assert np.all(col[: m - lo] <= col[m - lo]) and np.all(col[m - lo + 1:] >= col[m - lo])


def test_widest_axis_and_its_ties():
    w = np.array([[0, 0, 0], [1, 3, 2]], np.float32)
    assert kdtree._widest_axis(w, 0, 2) == 1
    assert kdtree._widest_axis(np.array([[0, 0, 0], [2, 2, 2]], np.float32), 0, 2) == 0
    assert kdtree._widest_axis(np.array([[0, 0, 0], [1, 2, 2]], np.float32), 0, 2) == 1
    assert kdtree._widest_axis(np.array([[5, 5, 5]], np.float32), 0, 1) == 0
    # Only rows [lo, hi) count.
    w = np.array([[0, 0, 0], [9, 0, 0], [9, 1, 0], [9, 0, 5], [100, 0, 0]], np.float32)
    assert kdtree._widest_axis(w, 1, 4) == 2


def check_subtree(tree, axis, node, n):
    """Every point of the two subtrees under ``node`` on its side of ``node``'s plane,
    and the plane's axis the widest of the node's subtree."""
    sub = tree[_subtree(node, n)]
    left, right = 2 * node + 1, 2 * node + 2
    ax = axis[node]
    if left < n:
        lpts = _subtree(left, n)
        rpts = _subtree(right, n) if right < n else []
        assert np.all(tree[lpts, ax] <= tree[node, ax]), node
        assert np.all(tree[rpts, ax] >= tree[node, ax]), node
        # The split axis is the widest of the node's points' box (lowest on a tie).
        ext = sub.max(axis=0) - sub.min(axis=0)
        assert ax == int(np.argmax(ext)), node
    else:
        assert ax == 0  # leaves report axis 0


def _subtree(node, n):
    out, frontier = [node], [node]
    while frontier:
        frontier = [c for p in frontier for c in (2 * p + 1, 2 * p + 2) if c < n]
        out += frontier
    return out


@pytest.mark.parametrize("shape", ["random", "clustered", "duplicates", "grid"])
@pytest.mark.parametrize("n", [1, 2, 3, 6, 31, 32, 333])
def test_balance_is_a_kd_tree_at_every_node(shape, n, rng):
    pts = point_set(shape, rng, n)
    tree, source, axis = balance(pts)
    assert tree.dtype == np.float32 and source.dtype == np.int32 and axis.dtype == np.uint8
    np.testing.assert_array_equal(np.sort(source), np.arange(n))
    np.testing.assert_array_equal(tree, pts[source])
    for node in range(n):
        check_subtree(tree, axis, node, n)


def test_balance_accepts_float64_and_rejects_bad_shapes(rng):
    pts = rng.random((50, 3))
    tree, source, _ = balance(pts)
    np.testing.assert_array_equal(tree, pts.astype(np.float32)[source])
    with pytest.raises(ValueError):
        balance(np.zeros((4, 2)))
    t, s, a = balance(np.zeros((0, 3), np.float32))
    assert t.shape == (0, 3) and s.shape == (0,) and a.shape == (0,)


# --- search -----------------------------------------------------------------------------

@njit
def _search_plain(tree, axis, depth, queries, k, r2):
    """``knn_search`` for each query in turn with one scratch: (idx, d2) sorted by
    (distance, index) (``sort_heap``, ``heap_entry``), and whether every raw result was a
    max-heap of keys as documented."""
    m = queries.shape[0]
    out_i = np.full((m, k), -1, np.int64)
    out_d = np.full((m, k), np.inf, np.float32)
    heap_ok = True
    heap, fbuf, ubuf, stack_i, stack_f, prev = knn_scratch(k)
    for q in range(m):
        c = knn_search(tree, axis, depth, queries[q, 0], queries[q, 1], queries[q, 2], k,
                       r2, heap, fbuf, ubuf, stack_i, stack_f)
        for s in range(1, c):
            if heap[(s - 1) // 2] < heap[s]:
                heap_ok = False
        sort_heap(heap, c)
        for s in range(c):
            out_i[q, s], out_d[q, s] = heap_entry(heap, s, fbuf, ubuf)
    return out_i, out_d, heap_ok


def search_coherent(tree, axis, queries, k, r2, growth, order=None):
    """``knn_search_coherent`` through ``nearest_kernel`` (the kernel PhotonMap.nearest
    runs): blocks of QUERY_BLOCK queries in ``order``, each query starting from the
    previous one's radius."""
    m = queries.shape[0]
    order = np.arange(m, dtype=np.int64) if order is None else order
    idx = np.empty((m, k), np.int64)
    d2 = np.empty((m, k), np.float32)
    kdtree.nearest_kernel(tree, axis, tree_depth(tree.shape[0]), queries, order, k,
                           np.float32(r2), growth, idx, d2)
    return idx, d2


def brute(tree, queries, k, r2):
    """float32 squared distances dx*dx + dy*dy + dz*dz, sorted by (distance, index),
    the first k within r2 (inclusive), padded with -1 / inf."""
    d = queries[:, None, :] - tree[None, :, :]
    d2 = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]
    order = np.argsort(d2, axis=1, kind="stable")[:, :k]
    dist = np.take_along_axis(d2, order, axis=1)
    inside = dist <= r2
    idx = np.full((queries.shape[0], k), -1, np.int64)
    out = np.full((queries.shape[0], k), np.inf, np.float32)
    idx[:, : order.shape[1]] = np.where(inside, order, -1)
    out[:, : order.shape[1]] = np.where(inside, dist, np.inf)
    return idx, out


def queries_for(pts, rng):
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    around = lo + (hi - lo + 0.5) * rng.random((80, 3), dtype=np.float32) - 0.25
    on = pts[rng.integers(0, pts.shape[0], 30)]  # distance-0 ties on duplicates
    half = (pts[rng.integers(0, pts.shape[0], 20)] + pts[rng.integers(0, pts.shape[0], 20)]) / 2
    far = np.array([[1e3, -1e3, 5.0]], np.float32)
    return np.vstack([around, on, half, far]).astype(np.float32)


@pytest.mark.parametrize("shape", ["random", "clustered", "duplicates", "grid"])
def test_knn_search_equals_brute_force(shape, rng):
    pts = point_set(shape, rng, 343)
    tree, _, axis = balance(pts)
    depth = tree_depth(tree.shape[0])
    queries = queries_for(tree, rng)
    scale = float((tree.max(axis=0) - tree.min(axis=0)).max())
    for k in (1, 2, 7, 16, 100, 343, 400):
        for radius in (0.0, 0.02 * scale, 0.1 * scale, 0.5 * scale, np.inf):
            r2 = np.float32(min(radius * radius, 3.0e38))
            want = brute(tree, queries, k, r2)
            msg = f"k={k} radius={radius}"
            idx, d2, heap_ok = _search_plain(tree, axis, depth, queries, k, r2)
            assert heap_ok, msg
            np.testing.assert_array_equal(idx, want[0], err_msg=msg)
            np.testing.assert_array_equal(d2, want[1], err_msg=msg)
            idx, d2 = search_coherent(tree, axis, queries, k, r2, search_growth(k))
            np.testing.assert_array_equal(idx, want[0], err_msg=msg + " coherent")
            np.testing.assert_array_equal(d2, want[1], err_msg=msg + " coherent")


def test_ties_go_to_the_lower_index(rng):
    # 50 copies of one point and 50 of another at the same distance from the query:
    # the k nearest are the k lowest tree indices among the 100.
    a = np.array([1.0, 0.0, 0.0], np.float32)
    pts = np.vstack([np.tile(a, (50, 1)), np.tile(-a, (50, 1)),
                     rng.random((100, 3), dtype=np.float32) + 3.0])
    tree, _, axis = balance(pts[rng.permutation(200)])
    q = np.zeros((1, 3), np.float32)
    tied = np.flatnonzero(np.abs(tree[:, 0]) == 1.0)
    for k in (1, 10, 49, 100):
        idx, d2, _ = _search_plain(tree, axis, tree_depth(200), q, k, np.float32(np.inf))
        np.testing.assert_array_equal(idx[0], np.sort(tied)[:k])
        assert np.all(d2 == 1.0)


def test_coherent_search_survives_a_bad_first_radius(rng):
    # The previous query's radius is a guess; from far away (too big) or from a dense
    # spot next to an empty one (too small) the answer must not change.
    pts = point_set("clustered", rng, 2000)
    tree, _, axis = balance(pts)
    queries = np.vstack([pts[:50], rng.random((50, 3), dtype=np.float32) * 10.0,
                         pts[50:100] + 0.5]).astype(np.float32)
    for k, radius in ((5, np.inf), (32, 1.0), (32, 0.05)):
        r2 = np.float32(min(radius * radius, 3.0e38))
        want = brute(tree, queries, k, r2)
        for growth in (1.0, search_growth(k), 100.0):
            idx, d2 = search_coherent(tree, axis, queries, k, r2, growth)
            np.testing.assert_array_equal(idx, want[0])
            np.testing.assert_array_equal(d2, want[1])


@pytest.mark.parametrize("shape", ["random", "clustered", "duplicates"])
def testnearest_kernel_does_not_depend_on_the_query_order(shape, rng):
    pts = point_set(shape, rng, 3000)
    tree, _, axis = balance(pts)
    queries = np.vstack([point_set(shape, rng, 700), rng.random((300, 3), np.float32)])
    queries = queries.astype(np.float32)
    k, r2 = 12, np.float32(0.3 ** 2)
    want = brute(tree, queries, k, r2)
    orders = [query_order(queries), np.arange(1000, dtype=np.int64),
              rng.permutation(1000).astype(np.int64)]
    for order in orders:
        idx, d2 = search_coherent(tree, axis, queries, k, r2, search_growth(k), order)
        np.testing.assert_array_equal(idx, want[0])
        np.testing.assert_array_equal(d2, want[1])


@pytest.mark.parametrize("shape", ["random", "clustered", "duplicates"])
def test_kth_distance_kernel_is_the_last_of_the_k_nearest(shape, rng):
    """The k-th squared distance (the volume photons' radii), bit for bit the last column
    of brute force's k nearest within r2: its farthest found when fewer, inf when none."""
    pts = point_set(shape, rng, 3000)
    tree, _, axis = balance(pts)
    queries = np.vstack([point_set(shape, rng, 700), rng.random((300, 3), np.float32),
                         [[1e3, -1e3, 5.0]]]).astype(np.float32)
    for k, r2 in ((12, np.float32(0.3 ** 2)), (5, np.float32(0.02 ** 2)), (40, np.float32(np.inf))):
        _, want = brute(tree, queries, k, r2)
        found = np.isfinite(want)
        last = np.where(found.any(axis=1),
                        want[np.arange(len(want)), np.maximum(found.sum(axis=1) - 1, 0)], np.inf)
        got = np.empty(len(queries), np.float32)
        kdtree.kth_distance_kernel(tree, axis, tree_depth(tree.shape[0]), queries,
                                   query_order(queries), k, r2, search_growth(k), got)
        np.testing.assert_array_equal(got, last)


def compatible_brute(tree, queries, normals, k, r2, site_normals, min_cos):
    """``nearest_compatible_kernel`` by brute force: the first of ``brute``'s k nearest
    with a side whose cosine (query normal normalised) is >= min_cos, as j * S + s."""
    idx, _ = brute(tree, queries, k, r2)
    unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    want = np.full(queries.shape[0], -1, np.int64)
    for q in range(queries.shape[0]):
        for j in idx[q]:
            if j < 0:
                break
            ok = np.flatnonzero(site_normals[j] @ unit[q] >= min_cos)
            if ok.size:
                want[q] = j * site_normals.shape[1] + ok[0]
                break
    return want


def surface_sites(rng, n):
    """n points on three planes of a unit cube with each side's unit normal (front, back),
    and queries near the planes with normals of either side, tilted, or on another plane."""
    axis = rng.integers(0, 3, n)
    pts = rng.random((n, 3), dtype=np.float32)
    pts[np.arange(n), axis] = 0.0
    front = np.eye(3)[axis]
    sites = np.stack([front, -front], axis=1)
    m = 600
    qa = rng.integers(0, 3, m)
    queries = rng.random((m, 3), dtype=np.float32)
    queries[np.arange(m), qa] = rng.normal(0.0, 0.01, m).astype(np.float32)
    normals = np.eye(3)[rng.integers(0, 3, m)] * rng.choice([-2.0, 1.0], (m, 1))
    normals += rng.normal(0.0, 0.4, (m, 3))
    return pts, sites, queries, normals


@pytest.mark.parametrize("k", [1, 2, 5])
def test_nearest_compatible_kernel_equals_brute_force(k, rng):
    pts, sites, queries, normals = surface_sites(rng, 3000)
    tree, source, axis = balance(pts)
    sites = np.ascontiguousarray(sites[source])
    for radius in (0.01, 0.05, np.inf):
        r2 = np.float32(min(radius * radius, 3.0e38))
        want = compatible_brute(tree, queries, normals, k, r2, sites, 0.5)
        for order in (query_order(queries), rng.permutation(queries.shape[0])):
            out = np.empty(queries.shape[0], np.int64)
            kdtree.nearest_compatible_kernel(tree, axis, tree_depth(tree.shape[0]), queries,
                                             normals, order.astype(np.int64), k, r2,
                                             search_growth(k), sites, 0.5, out)
            np.testing.assert_array_equal(out, want, err_msg=f"k={k} radius={radius}")
        assert 0 < (want >= 0).sum() < want.size  # some hits, some misses


@pytest.mark.parametrize("shape", ["duplicates", "grid"])
def test_nearest_compatible_kernel_with_distance_ties(shape, rng):
    """Many points at exactly the query's nearest distance, each with one random side's
    normal: the kernel's first search of the nearest point alone (k = 1) must pick the
    tie's lowest index as the k-search does, and where that point's side disagrees the
    next one in (distance, index) order."""
    pts = point_set(shape, rng, 343)
    tree, _, axis = balance(pts)
    axes = np.eye(3)[rng.integers(0, 3, tree.shape[0])] * rng.choice([-1.0, 1.0],
                                                                     (tree.shape[0], 1))
    sites = np.ascontiguousarray(axes[:, None, :])  # one side per point
    queries = queries_for(pts, rng)
    normals = np.eye(3)[rng.integers(0, 3, queries.shape[0])] * rng.choice(
        [-1.0, 1.0], (queries.shape[0], 1))
    for k in (1, 2, 6):
        r2 = np.float32(4.0)
        want = compatible_brute(tree, queries, normals, k, r2, sites, 0.5)
        out = np.empty(queries.shape[0], np.int64)
        kdtree.nearest_compatible_kernel(tree, axis, tree_depth(tree.shape[0]), queries,
                                         normals, query_order(queries), k, r2,
                                         search_growth(k), sites, 0.5, out)
        np.testing.assert_array_equal(out, want, err_msg=f"k={k}")
        assert (want >= 0).sum() > 0 and (want < 0).sum() > 0


def test_two_sided_sites_equal_two_entries_per_point(rng):
    """The radiance cache keeps one site per surface point with both sides' normals; it
    used to be a map of 2 N entries (each position twice, one normal each) searched for
    the 2 k nearest. Without distance ties between distinct points (random float32
    points) both give the same side of the same point."""
    pts, sites, queries, normals = surface_sites(rng, 2000)
    n = pts.shape[0]
    tree, source, axis = balance(pts)
    sites_t = np.ascontiguousarray(sites[source])
    flat = np.vstack([pts, pts])
    entries = np.concatenate([sites[:, 0], sites[:, 1]])[:, None, :]  # one side per entry
    for k in (1, 2):
        r2 = np.float32(0.04 ** 2)
        out = np.empty(queries.shape[0], np.int64)
        kdtree.nearest_compatible_kernel(tree, axis, tree_depth(n), queries, normals,
                                         query_order(queries), k, r2, search_growth(k),
                                         sites_t, 0.5, out)
        old = compatible_brute(flat, queries, normals, 2 * k, r2, entries, 0.5)
        # Entry e is point e % n, side e // n; the site j * 2 + s is point source[j], side s.
        got_point = np.where(out >= 0, source[out // 2], -1)
        got_side = np.where(out >= 0, out % 2, -1)
        np.testing.assert_array_equal(got_point, np.where(old >= 0, old % n, -1))
        np.testing.assert_array_equal(got_side, np.where(old >= 0, old // n, -1))


def test_query_order_is_a_morton_permutation(rng):
    pts = rng.random((5000, 3), dtype=np.float32)
    order = query_order(pts)
    np.testing.assert_array_equal(np.sort(order), np.arange(5000))
    # Along the curve the cell codes (QUERY_ORDER_BITS per axis) never decrease.
    lo = pts.min(axis=0).astype(np.float64)
    scale = float((1 << kdtree.QUERY_ORDER_BITS) - 1) / float((pts.max(axis=0) - lo).max())
    codes = kdtree._morton_kernel(pts, lo, scale)
    sorted_codes = codes[order]
    assert np.all(sorted_codes[1:] >= sorted_codes[:-1])
    # The radix sort is numpy's stable argsort, ties (repeated codes) included.
    np.testing.assert_array_equal(order, np.argsort(codes, kind="stable"))
    shifts = rng.integers(0, 64, 3000).astype(np.uint64)
    many = rng.integers(0, 2**63, 3000, dtype=np.uint64) >> shifts
    many = np.concatenate([many, many[:500], np.zeros(7, np.uint64)])
    np.testing.assert_array_equal(kdtree.radix_argsort(many), np.argsort(many, kind="stable"))
    low = many & np.uint64((1 << 30) - 1)
    np.testing.assert_array_equal(kdtree.radix_argsort(low, 30), np.argsort(low, kind="stable"))
    # Consecutive queries are neighbours: the mean step is far below a random order's
    # (measured 0.077 against 0.66).
    step = np.linalg.norm(np.diff(pts[order], axis=0), axis=1).mean()
    assert step < 0.2 * np.linalg.norm(np.diff(pts, axis=0), axis=1).mean()
    # Small batches keep their order; a single point's code.
    np.testing.assert_array_equal(query_order(pts[:10]), np.arange(10))
    one = kdtree._morton_kernel(np.array([[1.0, 0.0, 0.0]], np.float32), np.zeros(3), 1.0)
    assert one[0] == 1  # x is the lowest bit of each triple
