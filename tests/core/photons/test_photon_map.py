"""The photon map against oracles: a brute-force distance matrix for k-NN, the kd rule
checked at every node, and the codecs against their stated error bounds."""

import math

import numpy as np
import pytest

from core.photons import kdtree
from core.photons import encoding
from core.photons.kdtree import balance
from core.photons.photon_map import BYTES_PER_PHOTON, PhotonMap

N = 300


def point_set(name, rng, n=N):
    """(n, 3) float32 photon positions of one of the shapes the map must handle."""
    if name == "uniform":
        return rng.random((n, 3), dtype=np.float32)
    if name == "clustered":  # a caustic: tight blobs on a plane, a few stray photons
        centres = rng.random((3, 2))
        blob = centres[rng.integers(0, 3, n)] + rng.normal(0.0, 0.01, (n, 2))
        blob[: n // 10] = rng.random((n // 10, 2))
        return np.c_[blob, np.zeros(n)].astype(np.float32)
    if name == "coincident":  # a few distinct positions, each repeated many times
        sites = rng.random((4, 3), dtype=np.float32)
        return sites[rng.integers(0, 4, n)]
    if name == "planar":
        p = rng.random((n, 3), dtype=np.float32)
        p[:, 1] = 0.25
        return p
    if name == "collinear":
        t = rng.random(n, dtype=np.float32)
        return np.c_[t, 2 * t, 0.5 - t].astype(np.float32)
    raise ValueError(name)


def make_map(positions, rng):
    n = positions.shape[0]
    return PhotonMap(positions, rng.random((n, 3)), rng.normal(size=(n, 3)))


def brute_force(photons, queries):
    """The definition, for every k and radius at once: float32 squared distances
    ``dx*dx + dy*dy + dz*dz``, each row sorted by (distance, index)."""
    d = queries[:, None, :] - photons[None, :, :]
    d2 = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]
    order = np.argsort(d2, axis=1, kind="stable")
    return order, np.take_along_axis(d2, order, axis=1)


def expected(oracle, k, max_radius):
    """The first k of each row within float32(max_radius**2), padded with -1 / inf."""
    order, d2 = oracle[0][:, :k], oracle[1][:, :k]
    inside = d2 <= np.float32(float(max_radius) ** 2)
    idx = np.full((order.shape[0], k), -1, np.int64)
    dist2 = np.full((order.shape[0], k), np.inf, np.float32)
    idx[:, : order.shape[1]] = np.where(inside, order, -1)
    dist2[:, : order.shape[1]] = np.where(inside, d2, np.inf)
    return idx, dist2


def queries_for(photons, rng):
    """Random points around the set, points exactly on photons (ties at distance 0) and
    points far outside the map."""
    lo, hi = photons.min(axis=0), photons.max(axis=0)
    around = lo + (hi - lo + 0.2) * rng.random((60, 3), dtype=np.float32) - 0.1
    on = photons[rng.integers(0, photons.shape[0], 20)]
    far = np.array([[50.0, -40.0, 30.0], [-1e4, 0.0, 0.0]], np.float32)
    return np.vstack([around, on, far]).astype(np.float32)


@pytest.mark.parametrize("shape", ["uniform", "clustered", "coincident", "planar", "collinear"])
def test_nearest_equals_brute_force(shape, rng):
    photons = point_set(shape, rng)
    pm = make_map(photons, rng)
    queries = queries_for(pm.positions, rng)
    oracle = brute_force(pm.positions, queries)
    for k in (1, 8, 50, N, N + 5):
        for radius in (0.0, 0.01, 0.1, 0.5, np.inf):
            idx, dist2 = pm.nearest(queries, k, radius)
            want_idx, want_d2 = expected(oracle, k, radius)
            assert idx.dtype == np.int64 and dist2.dtype == np.float32
            assert idx.shape == dist2.shape == (queries.shape[0], k)
            np.testing.assert_array_equal(idx, want_idx, err_msg=f"k={k} radius={radius}")
            np.testing.assert_array_equal(dist2, want_d2, err_msg=f"k={k} radius={radius}")


@pytest.mark.parametrize("shape", ["uniform", "clustered"])
def test_many_coherent_queries_equal_brute_force(shape, rng):
    # Enough queries to be visited in Morton order, where each search starts from the
    # previous query's radius (a guess, retried when it holds fewer than k photons).
    pm = make_map(point_set(shape, rng, 2000), rng)
    queries = np.vstack([point_set(shape, rng, 1500), rng.random((500, 3), dtype=np.float32)])
    oracle = brute_force(pm.positions, queries)
    for k, radius in ((1, np.inf), (20, np.inf), (20, 0.05), (64, 0.2)):
        want = expected(oracle, k, radius)
        for sort_queries in (True, False):
            got = pm.nearest(queries, k, radius, sort_queries=sort_queries)
            np.testing.assert_array_equal(got[0], want[0], err_msg=f"k={k} r={radius}")
            np.testing.assert_array_equal(got[1], want[1], err_msg=f"k={k} r={radius}")


def subtree_boxes(pos):
    """Bounding box (min, max) of every node's subtree, bottom-up over the heap."""
    lo, hi = pos.copy(), pos.copy()
    for node in range(pos.shape[0] - 1, 0, -1):
        parent = (node - 1) // 2
        lo[parent] = np.minimum(lo[parent], lo[node])
        hi[parent] = np.maximum(hi[parent], hi[node])
    return lo, hi


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 8, 100, 257])
@pytest.mark.parametrize("shape", ["uniform", "clustered", "coincident", "planar", "collinear"])
def test_balance_is_a_left_balanced_kd_tree(shape, n, rng):
    photons = point_set(shape, rng, n) if n else np.zeros((0, 3), np.float32)
    tree, source, axis = balance(photons)
    pm = make_map(photons, rng)
    np.testing.assert_array_equal(pm.positions, tree)
    assert pm.depth == math.ceil(math.log2(n + 1))
    # The array is a permutation of the input photons.
    np.testing.assert_array_equal(np.sort(source), np.arange(n))
    np.testing.assert_array_equal(tree, photons[source])
    # kd property: every photon lies on its ancestors' sides of their split planes.
    nodes = np.arange(n)
    child = nodes.copy()
    while (child > 0).any():
        has = child > 0
        anc = (child[has] - 1) // 2
        left = child[has] == 2 * anc + 1
        ax = axis[anc]
        value = tree[nodes[has], ax]
        split = tree[anc, ax]
        assert (value[left] <= split[left]).all()
        assert (value[~left] >= split[~left]).all()
        child[has] = anc
    # The lecture's split rule: the axis where the subtree's bounding box is widest.
    lo, hi = subtree_boxes(tree)
    internal = 2 * nodes + 1 < n
    np.testing.assert_array_equal(axis[internal], np.argmax(hi - lo, axis=1)[internal])


def test_empty_and_single_photon_maps(rng):
    empty = PhotonMap(np.zeros((0, 3), np.float32), np.zeros((0, 3)), np.zeros((0, 3)))
    idx, dist2 = empty.nearest(rng.random((5, 3)), 3, np.inf)
    assert (idx == -1).all() and np.isinf(dist2).all()
    assert len(empty) == 0 and empty.depth == 0 and empty.flux.shape == (0, 3)
    one = PhotonMap(np.array([[1.0, 2.0, 3.0]], np.float32), [[1.0, 1.0, 1.0]], [[0, 0, 1.0]])
    idx, dist2 = one.nearest(np.array([[1.0, 2.0, 4.0]], np.float32), 2, np.inf)
    np.testing.assert_array_equal(idx, [[0, -1]])
    np.testing.assert_array_equal(dist2, np.array([[1.0, np.inf]], np.float32))
    assert one.nearest(np.array([[1.0, 2.0, 4.0]]), 1, 0.5)[0][0, 0] == -1


def test_bytes_per_photon(rng):
    pm = make_map(point_set("uniform", rng, 1000), rng)
    assert BYTES_PER_PHOTON <= 24
    assert pm.nbytes == 1000 * BYTES_PER_PHOTON


def test_flux_round_trip_within_stated_error(rng):
    # Eight decades of power and saturated colours: every channel within 2^-11 of itself
    # (the stated bound holds down to 2^-29 = 1.9e-9 of the map's largest channel).
    n = 20000
    flux = np.exp(rng.uniform(np.log(1e-8), 0.0, (n, 3))) * 7.5
    flux[:10] = [[7.5, 7.5 * 2.0**-29, 0.0]] * 10  # the largest value, the smallest, a zero
    scale = encoding.flux_scale(flux)
    decoded = encoding.decode_flux(encoding.encode_flux(flux, scale), scale).astype(np.float64)
    assert (decoded >= 0).all()
    np.testing.assert_array_equal(decoded[flux == 0], 0.0)
    rel = np.abs(decoded - flux)[flux > 0] / flux[flux > 0]
    assert rel.max() <= 2.0**-11 + 1e-7  # + float32 rounding of the decoded value
    # Through the map: photon i of the map is input photon source[i].
    positions = rng.random((n, 3), dtype=np.float32)
    pm = PhotonMap(positions, flux, rng.normal(size=(n, 3)))
    _, source, _ = balance(positions)
    np.testing.assert_array_equal(pm.flux, decoded[source].astype(np.float32))


def test_zero_and_all_zero_flux_stay_zero(rng):
    positions = rng.random((50, 3), dtype=np.float32)
    pm = PhotonMap(positions, np.zeros((50, 3)), rng.normal(size=(50, 3)))
    np.testing.assert_array_equal(pm.flux, 0.0)


def angle_deg(a, b):
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    cross = np.linalg.norm(np.cross(a, b), axis=1)
    return np.degrees(np.arctan2(cross, (a * b).sum(axis=1)))


def test_direction_round_trip_within_stated_error(rng):
    d = rng.normal(size=(200000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    edges = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0],
                      [1, 1, 0], [-1, 1, 0], [1, -1, -1e-9], [-1, -1, -1]], np.float64)
    edges /= np.linalg.norm(edges, axis=1, keepdims=True)
    d = np.vstack([d, edges])
    decoded = encoding.decode_direction(encoding.encode_direction(d))
    np.testing.assert_allclose(np.linalg.norm(decoded, axis=1), 1.0, atol=1e-6)
    assert angle_deg(decoded, d).max() < 0.004  # measured 0.0037 over 4 million
    # Lengths are ignored; the numba decoder used by kernels agrees with numpy's.
    np.testing.assert_array_equal(encoding.encode_direction(d * 3.0), encoding.encode_direction(d))
    pm = PhotonMap(rng.random((d.shape[0], 3), dtype=np.float32), np.ones_like(d), d)
    assert pm.directions.shape == d.shape


@pytest.mark.parametrize("bad, field", [
    (dict(positions=np.zeros((4, 2))), "positions"),
    (dict(positions=np.full((4, 3), np.nan)), "positions"),
    (dict(flux=-np.ones((4, 3))), "flux"),
    (dict(flux=np.ones((3, 3))), "flux"),
    (dict(directions=np.zeros((4, 3))), "directions"),
    (dict(directions=np.full((4, 3), np.inf)), "directions"),
])
def test_bad_photons_raise_naming_the_field(bad, field):
    args = dict(positions=np.zeros((4, 3)), flux=np.ones((4, 3)), directions=np.ones((4, 3)))
    args.update(bad)
    with pytest.raises(ValueError, match=field):
        PhotonMap(**args)


@pytest.mark.parametrize("k, radius, field", [
    (0, 1.0, "k"), (2.5, 1.0, "k"), (True, 1.0, "k"), (3, -1.0, "max_radius"),
    (3, float("nan"), "max_radius"),
])
def test_bad_queries_raise_naming_the_argument(k, radius, field, rng):
    pm = make_map(point_set("uniform", rng, 10), rng)
    with pytest.raises(ValueError, match=field):
        pm.nearest(np.zeros((1, 3)), k, radius)


def test_from_parts_is_the_map_of_the_joined_pieces(rng):
    """The tracer's path (pieces encoded one by one, the lists emptied, positions balanced
    in place with int32 indices) gives the very arrays of the whole-array constructor and
    of the int64 balance."""
    sizes = [0, 1, 1000, 70_000, 3]
    pos = [rng.random((m, 3), dtype=np.float32) for m in sizes]
    flux = [(rng.random((m, 3)) * 10.0 ** rng.uniform(-6, 2)).astype(np.float32) for m in sizes]
    dirs = [rng.normal(size=(m, 3)).astype(np.float32) for m in sizes]
    whole = PhotonMap(np.concatenate(pos), np.concatenate(flux), np.concatenate(dirs))
    joined = np.concatenate(pos)
    lists = (list(pos), list(flux), list(dirs))
    parts = PhotonMap.from_parts(*lists)
    assert lists == ([], [], [])
    for a, b in zip(whole.kernel_arrays(), parts.kernel_arrays()):
        np.testing.assert_array_equal(a, b)
    # The int32 balance equals the int64 one; the input of PhotonMap is left as it was.
    n = joined.shape[0]
    tree, perm, axis = np.empty((n, 3), np.float32), np.empty(n, np.int64), np.zeros(n, np.uint8)
    kdtree._balance_into(joined.copy(), np.arange(n), np.empty(n, np.int64), np.empty(n, np.int64),
                  tree, perm, axis)
    np.testing.assert_array_equal(tree, parts.positions)
    np.testing.assert_array_equal(axis, parts.split_axis)
    np.testing.assert_array_equal(whole.positions, joined[perm])
    with pytest.raises(ValueError, match="piece 1"):
        PhotonMap.from_parts([pos[1], pos[2]], [flux[1], flux[1]], [dirs[1], dirs[2]])
