"""A hash grid over points (photons, visible points): cells of a fixed width hashed into a
table, filled by one counting sort, for "which points lie within r of here" walks.

Cells are integer triples floor((x - lo) / h); a cell's bucket is ``cell_hash`` of the
triple masked to the table size (a power of two, >= 2 N). Several cells can share a
bucket: a walk compares each candidate's own cell (``cells``) with the cell it scans, so
every point is found once, in its own cell. ``within`` is the one walk: a numba generator
of the points within a radius of a query, in a fixed order (cells by offset, then bucket
order), used by the kernels of SPPM's photon gathering and of the importance pre-pass's
nearness test over the arrays of a ``HashGrid``. ``nearest_compatible_kernel`` is the
radiance cache's lookup (core/integrators/gather.py): the k nearest points from the 27
cells around the query when that settles them, else the points' kd-tree.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from . import kdtree

SETTLED = 0.99
"""The grid search settles a query when its k-th squared distance is below SETTLED h^2:
every point outside the 27 cells is at least h away (less float32 rounding)."""


@njit(cache=True, error_model="numpy")
def cell_hash(ix, iy, iz, mask):
    """The bucket of cell (ix, iy, iz) in a table of mask + 1 buckets."""
    h = (ix * 73856093) ^ (iy * 19349663) ^ (iz * 83492791)
    return h & mask


@njit(cache=True, error_model="numpy")
def cell_of(x, lo, inv_h):
    """The cell index along one axis of coordinate x (grid origin lo, 1 / cell width)."""
    return np.int64(np.floor((x - lo) * inv_h))


@njit(cache=True, error_model="numpy")
def sort_into_cells(pos, lo, inv_h, mask, cells, start, order):
    """Counting sort of the points by hashed cell: bucket b holds order[start[b]:start[b+1]];
    cells[i] is point i's cell."""
    n = pos.shape[0]
    buckets = np.empty(n, np.int64)
    for c in range(start.shape[0]):
        start[c] = 0
    for i in range(n):
        ix = cell_of(pos[i, 0], lo[0], inv_h)
        iy = cell_of(pos[i, 1], lo[1], inv_h)
        iz = cell_of(pos[i, 2], lo[2], inv_h)
        cells[i, 0], cells[i, 1], cells[i, 2] = ix, iy, iz
        b = cell_hash(ix, iy, iz, mask)
        buckets[i] = b
        start[b + 1] += 1
    for c in range(1, start.shape[0]):
        start[c] += start[c - 1]
    fill = start[:-1].copy()
    for i in range(n):
        b = buckets[i]
        order[fill[b]] = i
        fill[b] += 1


@njit(cache=True, error_model="numpy")
def within(px, py, pz, r2, ring, points, lo, inv_h, mask, cells, start, order):
    """Yield the index of every point k with |points[k] - p|^2 <= r2 among the cells within
    ``ring`` cells of p's (the caller chooses ring >= r * inv_h), each once, in walk order."""
    cx = cell_of(px, lo[0], inv_h)
    cy = cell_of(py, lo[1], inv_h)
    cz = cell_of(pz, lo[2], inv_h)
    for ox in range(-ring, ring + 1):
        for oy in range(-ring, ring + 1):
            for oz in range(-ring, ring + 1):
                qx, qy, qz = cx + ox, cy + oy, cz + oz
                b = cell_hash(qx, qy, qz, mask)
                for j in range(start[b], start[b + 1]):
                    k = order[j]
                    # Another cell hashed into the same bucket: skip (found in its own).
                    if cells[k, 0] != qx or cells[k, 1] != qy or cells[k, 2] != qz:
                        continue
                    ex = points[k, 0] - px
                    ey = points[k, 1] - py
                    ez = points[k, 2] - pz
                    if ex * ex + ey * ey + ez * ez <= r2:
                        yield k


class HashGrid:
    """The grid of N points (N, 3) (float32 or float64, metres) with cells ``cell`` metres
    wide: lo (3,) float64 origin (one cell below the points' minimum), inv_h = 1 / cell,
    mask (table size - 1), cells (N, 3) int64, start (size + 1,) int64, order (N,) int64."""

    def __init__(self, points: np.ndarray, cell: float):
        n = points.shape[0]
        self.inv_h = 1.0 / cell
        self.lo = points.min(axis=0).astype(np.float64) - cell
        size = 1 << max(4, int(2 * n - 1).bit_length())
        self.mask = np.int64(size - 1)
        self.cells = np.empty((n, 3), np.int64)
        self.start = np.empty(size + 1, np.int64)
        self.order = np.empty(n, np.int64)
        sort_into_cells(points, self.lo, self.inv_h, self.mask, self.cells, self.start,
                        self.order)


@njit(cache=True, nogil=True, inline="always")
def _insert(keys, count, k, key):
    """Insert key into the ascending keys[:count], keeping the k smallest; returns the new
    count. (Each point lies in one cell, visited once: no key comes twice.)"""
    c = count
    if c == k:
        if key >= keys[k - 1]:
            return count
        c = k - 1
    while c > 0 and keys[c - 1] > key:
        keys[c] = keys[c - 1]
        c -= 1
    keys[c] = key
    return min(count + 1, k)


@njit(parallel=True, cache=True, nogil=True)
def nearest_compatible_kernel(points, lo, inv_h, mask, cells, start, order_in_grid, tree_axis,
                              depth, queries, normals, order, k, r2, site_normals, min_cos,
                              out):
    """``kdtree.nearest_compatible_kernel``'s result (the same picks, bit for bit) through
    a HashGrid over the kd-tree's points: the k nearest points within r2 (by squared
    float32 distance, then index, as the tree orders them) among the 27 cells around
    the query; when the k-th is not within SETTLED h^2 (or fewer than k are found while
    r2 reaches beyond the cells) the tree answers (``kdtree.knn_search``).

    points (N, 3) float32: the tree's points (heap order) and tree_axis, depth its
    kd-tree; lo, inv_h, mask, cells, start, order_in_grid: ``HashGrid(points, h)``'s
    arrays; queries (M, 3) float32, normals (M, 3) float64 non-zero, order (M,) int64 any
    permutation (spatial order keeps the cells in cache), r2 float32 m^2, site_normals
    (N, S, 3) float64 unit; out (M,) int64: j * S + s or -1.
    """
    m = order.shape[0]
    sides = site_normals.shape[1]
    h = 1.0 / inv_h
    settled = SETTLED * h * h
    for b in prange((m + kdtree.QUERY_BLOCK - 1) // kdtree.QUERY_BLOCK):
        heap, fbuf, ubuf, stack_i, stack_f, prev = kdtree.knn_scratch(k)
        keys = np.empty(k, np.uint64)
        for t in range(b * kdtree.QUERY_BLOCK, min(m, (b + 1) * kdtree.QUERY_BLOCK)):
            q = order[t]
            qx, qy, qz = queries[q, 0], queries[q, 1], queries[q, 2]
            fx = (qx - lo[0]) * inv_h
            fy = (qy - lo[1]) * inv_h
            fz = (qz - lo[2]) * inv_h
            cx, cy, cz = np.int64(math.floor(fx)), np.int64(math.floor(fy)), np.int64(math.floor(fz))
            # Gaps (m) from the query to its cell's lower and upper faces per axis.
            gx0, gy0, gz0 = (fx - cx) * h, (fy - cy) * h, (fz - cz) * h
            count = 0
            bound = np.float64(r2)
            for w in range(27):
                # The query's own cell first (w = 13 -> offset 0): its points shrink the bound.
                v = (w + 13) % 27
                ox, oy, oz = v % 3 - 1, (v // 3) % 3 - 1, v // 9 - 1
                gx = 0.0 if ox == 0 else (gx0 if ox < 0 else h - gx0)
                gy = 0.0 if oy == 0 else (gy0 if oy < 0 else h - gy0)
                gz = 0.0 if oz == 0 else (gz0 if oz < 0 else h - gz0)
                if (gx * gx + gy * gy + gz * gz) * 0.999 > bound:
                    continue  # every point of the cell is beyond the bound
                ix, iy, iz = cx + ox, cy + oy, cz + oz
                bk = cell_hash(ix, iy, iz, mask)
                for e in range(start[bk], start[bk + 1]):
                    j = order_in_grid[e]
                    if cells[j, 0] != ix or cells[j, 1] != iy or cells[j, 2] != iz:
                        continue
                    # The tree's float32 distance, summed in the same order.
                    dx = qx - points[j, 0]
                    dy = qy - points[j, 1]
                    dz = qz - points[j, 2]
                    d2 = dx * dx + dy * dy + dz * dz
                    if d2 <= bound:
                        fbuf[0] = d2
                        count = _insert(keys, count, k, (np.uint64(ubuf[0]) << np.uint64(32))
                                        | np.uint64(j))
                        if count == k:
                            ubuf[0] = np.uint32(keys[k - 1] >> np.uint64(32))
                            bound = np.float64(fbuf[0])
            c = count
            if not ((count == k and bound < settled) or np.float64(r2) < settled):
                c = kdtree.knn_search(points, tree_axis, depth, qx, qy, qz, k, r2, heap, fbuf,
                                      ubuf, stack_i, stack_f)
                kdtree.sort_heap(heap, c)
                for s in range(c):
                    keys[s] = heap[s]
            n0, n1, n2 = normals[q, 0], normals[q, 1], normals[q, 2]
            inv = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            pick = -1
            for r in range(c):
                j = np.int64(keys[r] & np.uint64(0xFFFFFFFF))
                for s in range(sides):
                    cs = (site_normals[j, s, 0] * n0 + site_normals[j, s, 1] * n1
                          + site_normals[j, s, 2] * n2) * inv
                    if cs >= min_cos:
                        pick = j * sides + s
                        break
                if pick >= 0:
                    break
            out[q] = pick
