"""The left-balanced kd-tree of the photon map, in one heap-ordered array, and its search.

Balance (the seed lecture's BALANCE(L)): at each node, the axis where the bounding box of
the node's photons is widest, the median photon along it as the node, the two halves
balanced recursively. The result is left-balanced (complete) and stored without pointers:
the children of node i are 2i+1 and 2i+2, node i's split plane passes through photon i
along ``axis[i]``, and the depth is ceil(log2(N+1)). O(N log N): level by level, every
node of a level in parallel, each a bounding box and a quickselect over its own segment.

Locate: the k nearest photons with a max-heap whose top, once the heap is full, is the
search radius ("ajuster la distance maximale"). Results are ordered by (float32 squared
distance ``dx*dx + dy*dy + dz*dz``, index), inclusive of the radius; pruning is exact in
float32 arithmetic, so a brute-force oracle with the same rule gives identical results.
``nearest_compatible_kernel``: the first of the k nearest whose normal agrees with the
query's (the radiance cache's lookup), without writing the k neighbours out.

Speed: the bottom levels are scanned like buckets; queries are visited in Morton order,
each thread's previous query lending its k-th distance as a first search radius
(``knn_search_coherent``); blocks of queries run in parallel (numba prange). Figures
against scipy's cKDTree: benchmarks/bench_photon_map.py and docs/photon_map.md.

Kernels take arrays (``PhotonMap.kernel_arrays()``), never objects; other core modules
call ``knn_scratch`` / ``knn_search_coherent`` / ``heap_entry`` from their own kernels.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

# Subtrees with this many levels or fewer (up to 7 photons) are scanned like one bucket of
# cKDTree: their levels are contiguous runs of the heap array (1, 2, 4 photons).
_BUCKET_LEVELS = 3
# Queries handled by one parallel task (each task allocates its scratch once, and its
# queries are neighbours along the Morton curve), and the deferred-cell stack of one
# search (one entry per level at most).
QUERY_BLOCK = 64
STACK_SIZE = 64


# --------------------------------------------------------------------------- balance

@njit(cache=True, nogil=True, inline="always")
def _left_subtree_size(n):
    """Photons in the left subtree of a left-balanced tree of n photons."""
    if n <= 1:
        return 0
    h = 0
    while (2 << h) <= n:
        h += 1
    half = 1 << (h - 1)  # what the left subtree's last level can hold
    last = n - ((1 << h) - 1)
    return half - 1 + min(last, half)


@njit(cache=True, nogil=True)
def _select(work, src, lo, hi, m, ax):
    """Reorder rows [lo, hi) so row m holds the median along ``ax``: rows before it are
    <= and rows after it >= along ``ax`` (Hoare/Wirth selection, median-of-three pivot)."""
    hi -= 1
    while hi - lo > 12:
        a = work[lo, ax]
        b = work[m, ax]
        c = work[hi, ax]
        pivot = max(min(a, b), min(max(a, b), c))
        i = lo
        j = hi
        while i <= j:
            while work[i, ax] < pivot:
                i += 1
            while work[j, ax] > pivot:
                j -= 1
            if i <= j:
                for d in range(3):
                    t = work[i, d]
                    work[i, d] = work[j, d]
                    work[j, d] = t
                s = src[i]
                src[i] = src[j]
                src[j] = s
                i += 1
                j -= 1
        if m <= j:
            hi = j
        elif m >= i:
            lo = i
        else:
            return  # m sits among rows equal to the pivot
    # Short ranges: insertion sort.
    for i in range(lo + 1, hi + 1):
        x0 = work[i, 0]
        x1 = work[i, 1]
        x2 = work[i, 2]
        key = work[i, ax]
        s = src[i]
        j = i - 1
        while j >= lo and work[j, ax] > key:
            work[j + 1, 0] = work[j, 0]
            work[j + 1, 1] = work[j, 1]
            work[j + 1, 2] = work[j, 2]
            src[j + 1] = src[j]
            j -= 1
        work[j + 1, 0] = x0
        work[j + 1, 1] = x1
        work[j + 1, 2] = x2
        src[j + 1] = s


@njit(cache=True, nogil=True, inline="always")
def _widest_axis(work, lo, hi):
    """Axis (0, 1, 2) of the widest extent of rows [lo, hi); the lowest axis on a tie."""
    x0 = work[lo, 0]
    y0 = work[lo, 1]
    z0 = work[lo, 2]
    x1 = x0
    y1 = y0
    z1 = z0
    for i in range(lo + 1, hi):
        x = work[i, 0]
        y = work[i, 1]
        z = work[i, 2]
        x0 = min(x0, x)
        x1 = max(x1, x)
        y0 = min(y0, y)
        y1 = max(y1, y)
        z0 = min(z0, z)
        z1 = max(z1, z)
    ex = x1 - x0
    ey = y1 - y0
    ez = z1 - z0
    if ex >= ey and ex >= ez:
        return 0
    if ey >= ez:
        return 1
    return 2


@njit(parallel=True, cache=True, nogil=True)
def _balance_into(work, src, seg_lo, seg_hi, tree, perm, axis):
    """Balance the (N, 3) float32 positions in ``work`` (reordered in place) into
    ``tree`` (heap order), ``perm`` (tree row -> input row, from ``src`` = arange(N)) and
    ``axis``; seg_lo / seg_hi (N,) scratch. Index arrays int32 or int64 alike.

    Level by level, every node of a level in parallel: a node owns a contiguous segment of
    the work array, picks its widest axis, selects its median, and hands the two halves
    to its children. O(N log N): each level costs O(N) (bounding boxes and selections).
    """
    n = work.shape[0]
    seg_lo[0] = 0
    seg_hi[0] = n
    first = 0
    width = 1
    while first < n:
        count = min(width, n - first)
        for t in prange(count):
            node = first + t
            lo = seg_lo[node]
            hi = seg_hi[node]
            m = lo + _left_subtree_size(hi - lo)
            if hi - lo > 1:
                ax = _widest_axis(work, lo, hi)
                _select(work, src, lo, hi, m, ax)
                axis[node] = ax
            tree[node, 0] = work[m, 0]
            tree[node, 1] = work[m, 1]
            tree[node, 2] = work[m, 2]
            perm[node] = src[m]
            left = 2 * node + 1
            if left < n:
                seg_lo[left] = lo
                seg_hi[left] = m
            if left + 1 < n:
                seg_lo[left + 1] = m + 1
                seg_hi[left + 1] = hi
        first += width
        width *= 2


def balance_kernel(positions, in_place=False):
    """Balance (N, 3) float32 positions -> (tree positions, source index, split axis).

    in_place: reorder ``positions`` itself instead of a copy (12 B per photon less; the
    PhotonMap does it on the array it owns). The index arrays (source and three scratch
    ones) are int32 below 2^31 photons, int64 above: 41 B per photon at the peak with
    ``in_place`` (12 work, 12 tree, 1 axis, 4 x 4 indices).
    """
    n = positions.shape[0]
    index = np.int32 if n < 2**31 else np.int64
    work = positions if in_place else positions.copy()
    tree = np.empty((n, 3), np.float32)
    perm = np.empty(n, index)
    axis = np.zeros(n, np.uint8)
    if n:
        src = np.arange(n, dtype=index)
        seg_lo, seg_hi = np.empty(n, index), np.empty(n, index)
        _balance_into(work, src, seg_lo, seg_hi, tree, perm, axis)
    return tree, perm, axis


def tree_depth(n: int) -> int:
    """Levels of a left-balanced tree of n photons: ceil(log2(n + 1)); 0 when empty."""
    return int(n).bit_length()


def balance(positions: np.ndarray):
    """Balance photon positions into a left-balanced kd-tree in heap order.

    positions: (N, 3) float32, metres.
    Returns (tree, source, split_axis): tree (N, 3) float32 = positions[source] in heap
    order, source (N,) int32 (int64 from 2^31 photons) index into the input, split_axis
    (N,) uint8 (0 for leaves).
    """
    positions = np.ascontiguousarray(positions, dtype=np.float32)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError(f"positions must have shape (N, 3), got {positions.shape}")
    return balance_kernel(positions)


# --------------------------------------------------------------------------- locate
#
# The k-heap holds uint64 keys: the float32 bits of the squared distance (for d2 >= 0 the
# bits order like the values) above the photon's index, so the lecture's priority queue
# ordered by (distance, index) compares one integer, and its top is the farthest photon
# kept.

_HI = np.uint64(32)
_LO_MASK = np.uint64(0xFFFFFFFF)


@njit(cache=True, nogil=True)
def knn_scratch(k):
    """Per-thread scratch for ``knn_search``: (heap, fbuf, ubuf, stack_i, stack_f, prev).

    heap (k,) uint64 keys; fbuf (1,) float32 and ubuf, its uint32 view (bit casts);
    stack_i (STACK_SIZE, 2) int64 (node, level) and stack_f (STACK_SIZE, 4) float32
    (plane offsets, squared cell distance) of deferred cells; prev (4,) float64, the
    previous query of this thread (x, y, z, distance to its k-th photon, or -1).
    """
    fbuf = np.empty(1, np.float32)
    prev = np.full(4, -1.0)
    return (np.empty(k, np.uint64), fbuf, fbuf.view(np.uint32),
            np.empty((STACK_SIZE, 2), np.int64), np.empty((STACK_SIZE, 4), np.float32), prev)


@njit(cache=True, nogil=True, inline="always")
def heap_entry(heap, s, fbuf, ubuf):
    """(index int64, squared distance float32) of heap slot s."""
    key = heap[s]
    ubuf[0] = np.uint32(key >> _HI)
    return np.int64(key & _LO_MASK), fbuf[0]


@njit(cache=True, nogil=True, inline="always")
def _top_distance(heap, fbuf, ubuf):
    ubuf[0] = np.uint32(heap[0] >> _HI)
    return fbuf[0]


@njit(cache=True, nogil=True, inline="always")
def _sift_up(heap, c, key):
    """Insert key at slot c of a max-heap."""
    while c > 0:
        p = (c - 1) >> 1
        if heap[p] > key:
            break
        heap[c] = heap[p]
        c = p
    heap[c] = key


@njit(cache=True, nogil=True, inline="always")
def _sift_down(heap, size, key):
    """Replace the top of a max-heap of ``size`` keys with key."""
    c = 0
    while True:
        big = 2 * c + 1
        if big >= size:
            break
        if big + 1 < size and heap[big + 1] > heap[big]:
            big += 1
        if heap[big] < key:
            break
        heap[c] = heap[big]
        c = big
    heap[c] = key


@njit(cache=True, nogil=True, inline="always")
def _offer(heap, fbuf, ubuf, count, k, bound, d2, j):
    """Offer photon j at squared distance d2 (<= bound) -> (count, bound).

    Until the heap is full the bound is the search radius; then it is the heap's top,
    the farthest photon kept ("ajuster la distance maximale").
    """
    fbuf[0] = d2
    key = (np.uint64(ubuf[0]) << _HI) | np.uint64(j)
    if count < k:
        _sift_up(heap, count, key)
        count += 1
        if count == k:
            bound = _top_distance(heap, fbuf, ubuf)
    elif key < heap[0]:
        _sift_down(heap, k, key)
        bound = _top_distance(heap, fbuf, ubuf)
    return count, bound


@njit(cache=True, nogil=True, inline="always")
def knn_search(tree, axis, depth, qx, qy, qz, k, r2, heap, fbuf, ubuf, stack_i, stack_f):
    """The k nearest photons of one query point within squared radius r2.

    tree (N, 3) float32 and axis (N,) uint8 as stored by PhotonMap, depth its levels;
    qx, qy, qz float32; r2 float32 m^2 (inclusive). Scratch from ``knn_scratch``.
    Returns the count c <= k; heap[:c] is a max-heap of keys (``heap_entry`` decodes).

    Depth first, near child first. A deferred far child carries the query's offsets to
    the planes bounding its cell (Arya & Mount's incremental distance): its squared
    distance is a lower bound of its photons', summed in the same float32 order, so
    pruning (cell distance > bound) never loses a photon, ties included.
    """
    n = tree.shape[0]
    count = 0
    bound = r2
    if n == 0:
        return 0
    sp = 0
    node = 0
    level = 1
    ox = np.float32(0.0)
    oy = np.float32(0.0)
    oz = np.float32(0.0)
    while True:
        if depth - level < _BUCKET_LEVELS:
            # A small subtree: scan its levels, contiguous runs of the heap array.
            start = node
            run = 1
            while start < n:
                for j in range(start, min(start + run, n)):
                    dx = qx - tree[j, 0]
                    dy = qy - tree[j, 1]
                    dz = qz - tree[j, 2]
                    d2 = dx * dx + dy * dy + dz * dz
                    if d2 <= bound:
                        count, bound = _offer(heap, fbuf, ubuf, count, k, bound, d2, j)
                start = 2 * start + 1
                run *= 2
        else:
            dx = qx - tree[node, 0]
            dy = qy - tree[node, 1]
            dz = qz - tree[node, 2]
            d2 = dx * dx + dy * dy + dz * dz
            if d2 <= bound:
                count, bound = _offer(heap, fbuf, ubuf, count, k, bound, d2, node)
            a = axis[node]
            delta = dx if a == 0 else (dy if a == 1 else dz)
            if delta < 0:
                near = 2 * node + 1
                far = near + 1
            else:
                far = 2 * node + 1
                near = far + 1
            if far < n:
                fx = delta if a == 0 else ox
                fy = delta if a == 1 else oy
                fz = delta if a == 2 else oz
                rd = fx * fx + fy * fy + fz * fz
                if rd <= bound:
                    stack_i[sp, 0] = far
                    stack_i[sp, 1] = level + 1
                    stack_f[sp, 0] = fx
                    stack_f[sp, 1] = fy
                    stack_f[sp, 2] = fz
                    stack_f[sp, 3] = rd
                    sp += 1
            if near < n:
                node = near
                level += 1
                continue
        # Resume at the most recently deferred cell still within the (shrunken) bound.
        while sp > 0 and stack_f[sp - 1, 3] > bound:
            sp -= 1
        if sp == 0:
            return count
        sp -= 1
        node = stack_i[sp, 0]
        level = stack_i[sp, 1]
        ox = stack_f[sp, 0]
        oy = stack_f[sp, 1]
        oz = stack_f[sp, 2]


@njit(cache=True, nogil=True, inline="always")
def knn_search_coherent(tree, axis, depth, qx, qy, qz, k, r2, growth, heap, fbuf, ubuf,
                        stack_i, stack_f, prev):
    """``knn_search`` with the same result, faster when queries come in spatial order.

    The previous query of this thread (``prev``: x, y, z and the distance to its k-th
    photon, or -1) gives the search a first radius: its k-th distance squared times
    ``growth`` (a guess: 1 + 2/sqrt(k) covers the k-NN radius's spread), else the
    triangle bound (that distance plus the distance between the queries, which holds the
    previous query's k photons), else r2. The k photons found within a smaller radius
    are the k nearest within r2, so only a search that finds fewer than k is repeated
    with the next larger radius. Updates ``prev``.
    """
    start = r2
    safe = r2
    if prev[3] >= 0.0:
        mx = qx - prev[0]
        my = qy - prev[1]
        mz = qz - prev[2]
        g = prev[3] + math.sqrt(mx * mx + my * my + mz * mz)
        g = g * g * 1.00001 + 1e-30  # margin for float32 rounding: avoids needless retries
        if g < r2:
            safe = np.float32(g)
        guess = prev[3] * prev[3] * growth
        start = np.float32(guess) if guess < safe else safe
    radius2 = start
    while True:
        c = knn_search(tree, axis, depth, qx, qy, qz, k, radius2, heap, fbuf, ubuf, stack_i,
                       stack_f)
        if c == k or radius2 >= r2:
            break
        radius2 = safe if radius2 < safe else r2
    prev[0] = qx
    prev[1] = qy
    prev[2] = qz
    prev[3] = math.sqrt(np.float64(_top_distance(heap, fbuf, ubuf))) if c == k else -1.0
    return c


@njit(cache=True, nogil=True)
def search_growth(k: int) -> float:
    """The first-radius factor of ``knn_search_coherent`` (on squared distances)."""
    return 1.0 + 2.0 / math.sqrt(k)


@njit(cache=True, nogil=True)
def sort_heap(heap, count):
    """Sort the first ``count`` keys ascending (by distance, then index), in place."""
    for end in range(count - 1, 0, -1):
        key = heap[end]
        heap[end] = heap[0]
        _sift_down(heap, end, key)


@njit(parallel=True, cache=True, nogil=True)
def nearest_kernel(tree, axis, depth, queries, order, k, r2, growth, out_idx, out_d2):
    # The search is inlined in the parallel body: measured 20 % faster than calling a
    # plain njit function per block.
    m = order.shape[0]
    for b in prange((m + QUERY_BLOCK - 1) // QUERY_BLOCK):
        heap, fbuf, ubuf, stack_i, stack_f, prev = knn_scratch(k)
        for t in range(b * QUERY_BLOCK, min(m, (b + 1) * QUERY_BLOCK)):
            q = order[t]
            c = knn_search_coherent(tree, axis, depth, queries[q, 0], queries[q, 1],
                                    queries[q, 2], k, r2, growth, heap, fbuf, ubuf,
                                    stack_i, stack_f, prev)
            sort_heap(heap, c)
            for s in range(c):
                out_idx[q, s], out_d2[q, s] = heap_entry(heap, s, fbuf, ubuf)
            for s in range(c, k):
                out_idx[q, s] = -1
                out_d2[q, s] = np.inf


@njit(parallel=True, cache=True, nogil=True)
def kth_distance_kernel(tree, axis, depth, queries, order, k, r2, growth, out_d2):
    """out_d2[q] (M,) float32 <- ``nearest_kernel``'s out_d2[q, c - 1]: the squared
    distance to query q's k-th nearest photon within r2 (its farthest found if fewer, inf
    if none), the max-heap's top, without sorting or writing the k neighbours out (the
    volume photons' radii, photons/beam.py)."""
    m = order.shape[0]
    for b in prange((m + QUERY_BLOCK - 1) // QUERY_BLOCK):
        heap, fbuf, ubuf, stack_i, stack_f, prev = knn_scratch(k)
        for t in range(b * QUERY_BLOCK, min(m, (b + 1) * QUERY_BLOCK)):
            q = order[t]
            c = knn_search_coherent(tree, axis, depth, queries[q, 0], queries[q, 1],
                                    queries[q, 2], k, r2, growth, heap, fbuf, ubuf,
                                    stack_i, stack_f, prev)
            out_d2[q] = _top_distance(heap, fbuf, ubuf) if c else np.float32(np.inf)


@njit(cache=True, nogil=True, inline="always")
def _compatible_side(site_normals, j, n0, n1, n2, inv, min_cos):
    """The first side s of point j whose normal agrees with (n0, n1, n2) * inv (cos >=
    min_cos), or -1."""
    for s in range(site_normals.shape[1]):
        cs = (site_normals[j, s, 0] * n0 + site_normals[j, s, 1] * n1
              + site_normals[j, s, 2] * n2) * inv
        if cs >= min_cos:
            return s
    return -1


@njit(parallel=True, cache=True, nogil=True)
def nearest_compatible_kernel(tree, axis, depth, queries, normals, order, k, r2, growth,
                              site_normals, min_cos, out):
    """For each query q: among its k nearest points (``nearest_kernel``'s order: (squared
    distance, index), within r2), the first point j with a side s whose normal
    site_normals[j, s] agrees with normals[q]: cos >= min_cos (cosine with normals[q]
    normalised, site normals taken as unit). out[q] = j * S + s (S sides), or -1.

    queries (M, 3) float32 metres, normals (M, 3) float64 non-zero, order (M,) int64 (any
    permutation: the results do not depend on it), site_normals (N, S, 3) float64 in the
    tree's order; out (M,) int64. No (M, k) arrays: the radiance cache's lookup
    (core/integrators/gather.py), where each site holds both sides of a surface point.

    The nearest point alone is searched first (k = 1), within the squared distance to the
    previous query's nearest point where that is below r2 (a bound that holds a point, so
    no search is repeated; inclusive, so a tie with a smaller index is still found): it is
    the k-search's first in that order (the smallest (squared distance, index) key within
    r2, ties included), so where one of its sides agrees it is the answer, and only the
    other queries (a few per thousand at the cache's points) search all k. On a render's
    lookups (issue 13) this took ~15 % less time than searching k every time, and ~9 %
    less again than starting from ``knn_search_coherent``'s radius guess.
    """
    m = order.shape[0]
    sides = site_normals.shape[1]
    for b in prange((m + QUERY_BLOCK - 1) // QUERY_BLOCK):
        heap, fbuf, ubuf, stack_i, stack_f, prev = knn_scratch(k)
        last = -1  # this block's previous nearest point, -1: none
        for t in range(b * QUERY_BLOCK, min(m, (b + 1) * QUERY_BLOCK)):
            q = order[t]
            qx, qy, qz = queries[q, 0], queries[q, 1], queries[q, 2]
            n0, n1, n2 = normals[q, 0], normals[q, 1], normals[q, 2]
            inv = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            bound = r2
            if last >= 0:
                dx = qx - tree[last, 0]
                dy = qy - tree[last, 1]
                dz = qz - tree[last, 2]
                bound = min(r2, dx * dx + dy * dy + dz * dz)
            pick = -1
            last = -1
            if knn_search(tree, axis, depth, qx, qy, qz, 1, bound, heap, fbuf, ubuf, stack_i,
                          stack_f) == 1:
                j, _ = heap_entry(heap, 0, fbuf, ubuf)
                last = j
                s = _compatible_side(site_normals, j, n0, n1, n2, inv, min_cos)
                if s >= 0:
                    pick = j * sides + s
                elif k > 1:
                    c = knn_search_coherent(tree, axis, depth, qx, qy, qz, k, r2, growth, heap,
                                            fbuf, ubuf, stack_i, stack_f, prev)
                    sort_heap(heap, c)
                    for r in range(1, c):  # the first is the nearest, already refused
                        j, _ = heap_entry(heap, r, fbuf, ubuf)
                        s = _compatible_side(site_normals, j, n0, n1, n2, inv, min_cos)
                        if s >= 0:
                            pick = j * sides + s
                            break
            out[q] = pick


# --------------------------------------------------------------------------- query order

@njit(cache=True, nogil=True, inline="always")
def _spread_bits(x):
    """Spread the low 21 bits of x so two zero bits separate each (Morton interleave)."""
    x &= np.uint64(0x1FFFFF)
    x = (x | (x << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    x = (x | (x << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    x = (x | (x << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    x = (x | (x << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    x = (x | (x << np.uint64(2))) & np.uint64(0x1249249249249249)
    return x


@njit(parallel=True, cache=True, nogil=True)
def _morton_kernel(points, lo, scale):
    m = points.shape[0]
    codes = np.empty(m, np.uint64)
    for i in prange(m):
        cx = np.uint64(min(max((points[i, 0] - lo[0]) * scale, 0.0), 2097151.0))
        cy = np.uint64(min(max((points[i, 1] - lo[1]) * scale, 0.0), 2097151.0))
        cz = np.uint64(min(max((points[i, 2] - lo[2]) * scale, 0.0), 2097151.0))
        codes[i] = (_spread_bits(cx) | (_spread_bits(cy) << np.uint64(1))
                    | (_spread_bits(cz) << np.uint64(2)))
    return codes


@njit(cache=True, nogil=True)
def _bounds_kernel(points):
    """(lo (3,) float64, extent float): the per-axis minimum of (M >= 1, 3) points and
    the largest per-axis max - min, in float64 (numpy's two axis reductions took ~40 %
    of ``query_order`` on a render's batches)."""
    lo = np.empty(3)
    hi = np.empty(3)
    for c in range(3):
        lo[c] = points[0, c]
        hi[c] = points[0, c]
    for i in range(1, points.shape[0]):
        for c in range(3):
            v = points[i, c]
            if v < lo[c]:
                lo[c] = v
            elif v > hi[c]:
                hi[c] = v
    extent = 0.0
    for c in range(3):
        extent = max(extent, hi[c] - lo[c])
    return lo, extent


@njit(cache=True, nogil=True)
def radix_argsort(codes, bits=64):
    """(M,) int64 permutation sorting (M,) uint64 ``codes`` ascending, stable (equal codes
    keep their order): ``np.argsort(codes, kind="stable")`` when every code is below
    2**bits, by passes of 11 bits (six for 64 bits, three for ``query_order``'s 30). The
    codes travel with the permutation, so every pass reads them in order (about twice
    as fast as numpy's argsort on a render's batches of ~40k Morton codes)."""
    m = codes.shape[0]
    idx = np.arange(m, dtype=np.int64)
    tmp = np.empty(m, np.int64)
    key = codes.copy()
    key_tmp = np.empty(m, np.uint64)
    count = np.empty(2049, np.int64)
    mask = np.uint64(2047)
    for shift in range(0, bits, 11):
        sh = np.uint64(shift)
        count[:] = 0
        for i in range(m):
            count[((key[i] >> sh) & mask) + 1] += 1
        for c in range(2048):
            count[c + 1] += count[c]
        for i in range(m):
            digit = (key[i] >> sh) & mask
            tmp[count[digit]] = idx[i]
            key_tmp[count[digit]] = key[i]
            count[digit] += 1
        idx, tmp = tmp, idx
        key, key_tmp = key_tmp, key
    return idx


QUERY_ORDER_BITS = 10
"""Cells per axis of ``query_order``'s Morton curve: 2**10 (a 30-bit code, three radix
passes): consecutive queries are neighbours at this scale already, and the results of
the kernels that take the order do not depend on it."""


def query_order(points: np.ndarray) -> np.ndarray:
    """(M,) int64 permutation visiting (M, 3) points along a Z-order (Morton) curve.

    Neighbouring queries then walk the same branches of the tree, which stay in cache.
    """
    m = points.shape[0]
    if m < 2 * QUERY_BLOCK:
        return np.arange(m, dtype=np.int64)
    lo, extent = _bounds_kernel(points)
    cells = float((1 << QUERY_ORDER_BITS) - 1)
    scale = cells / extent if extent > 0 else 0.0
    return radix_argsort(_morton_kernel(points, lo, scale), 3 * QUERY_ORDER_BITS)
