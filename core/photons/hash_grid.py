"""A hash grid over points (photons, visible points): cells of a fixed width hashed into a
table, filled by one counting sort, for "which points lie within r of here" walks.

Cells are integer triples floor((x - lo) / h); a cell's bucket is ``cell_hash`` of the
triple masked to the table size (a power of two, >= 2 N). Several cells can share a
bucket: a walk compares each candidate's own cell (``cells``) with the cell it scans, so
every point is found once, in its own cell. ``within`` is the one walk: a numba generator
of the points within a radius of a query, in a fixed order (cells by offset, then bucket
order), used by the kernels of SPPM's photon gathering and of the importance pre-pass's
nearness test over the arrays of a ``HashGrid``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)


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
