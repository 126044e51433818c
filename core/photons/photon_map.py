"""The photon map: photons stored compactly, balanced into a kd-tree, gathered by k-NN.

The seed lecture's steps: store (flat arrays, independent of the scene's geometry),
balance and locate (kdtree.py: a left-balanced kd-tree in one heap-ordered array, and
the k nearest photons with a max-heap that shrinks the search radius once full).

Storage, structure of arrays in the map's own (heap) order, 23 bytes per photon with the
tree (``BYTES_PER_PHOTON``):
    position   (N, 3) float32, metres                          12 B
    flux       (N, 3) uint16, float16 codes x one map scale     6 B  (encoding.py)
    direction  (N, 2) uint16, octahedral code                   4 B  (encoding.py)
    split axis (N,)   uint8, 0/1/2 = x/y/z                      1 B
Measured decoding errors: each flux channel within 2^-11 (0.049 %) of itself, direction
within 0.004 degrees (encoding.py).

Neighbours come sorted by (float32 squared distance, index in the map); a photon is
within ``max_radius`` when its float32 squared distance ``dx*dx + dy*dy + dz*dz`` is
<= float32(max_radius**2). The same rule on a brute-force distance matrix gives
identical indices, ties included (the tests rely on it).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from . import encoding
from .kdtree import balance_kernel, nearest_kernel, query_order, search_growth, tree_depth

BYTES_PER_PHOTON = 12 + 6 + 4 + 1
PEAK_BYTES_PER_PHOTON = 12 + 10 + 41 - 12
"""Bytes per photon at the peak of ``PhotonMap.from_parts``: the codes (10) while the
balance holds its 41 (core/photons/kdtree.py), whose work array is the positions (12) themselves."""
ENCODE_CHUNK = 1 << 18
"""Rows encoded together (float64 copies of this many rows only)."""
_INF32 = np.float32(np.inf)


def check_points(a, name):
    """(N, 3) float32 C-contiguous copy or view of ``a``; ValueError naming ``name``."""
    a = np.asarray(a)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {a.shape}")
    if not np.issubdtype(a.dtype, np.floating) and not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"{name} must be a float array, got dtype {a.dtype}")
    a = np.ascontiguousarray(a, dtype=np.float32)
    if not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite (found NaN or Inf)")
    return a


def squared_radius(max_radius) -> np.float32:
    """float32(max_radius**2), the inclusive bound on float32 squared distances."""
    r = float(max_radius)
    if not r >= 0.0:  # also rejects NaN
        raise ValueError(f"max_radius must be >= 0 (or inf), got {max_radius!r}")
    r2 = r * r
    return np.float32(r2) if r2 <= float(np.finfo(np.float32).max) else _INF32


def check_k(k) -> int:
    """k as an int >= 1; ValueError otherwise."""
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    return int(k)


def _release_freed_memory():
    """Hand memory freed by numpy back to the system (glibc's malloc_trim; elsewhere
    nothing). glibc keeps freed blocks of a few MB (the tracer's per-bounce pieces) in its
    heap, so without this the process's peak counts them again (measured: 66-69 B per
    photon at the peak instead of 54-57, benchmarks/bench_photon_memory.py)."""
    global _TRIM
    if _TRIM is None:
        try:
            import ctypes

            _TRIM = ctypes.CDLL(None).malloc_trim
        except (OSError, AttributeError):
            _TRIM = False
    if _TRIM:
        _TRIM(0)


_TRIM = None


@njit(parallel=True, cache=True, nogil=True)
def _gather_codes(flux_codes, direction_codes, source, flux_out, direction_out):
    """Row i of the outputs = row source[i] of the codes (into the tree's order)."""
    for i in prange(source.shape[0]):
        j = source[i]
        flux_out[i, 0] = flux_codes[j, 0]
        flux_out[i, 1] = flux_codes[j, 1]
        flux_out[i, 2] = flux_codes[j, 2]
        direction_out[i, 0] = direction_codes[j, 0]
        direction_out[i, 1] = direction_codes[j, 1]


class PhotonMap:
    """Photons stored compactly and balanced into a left-balanced kd-tree (heap order).

    PhotonMap(positions, flux, directions):
        positions (N, 3) float32, metres;
        flux (N, 3) watts per photon (RGB), finite and >= 0;
        directions (N, 3) unit vectors toward where each photon came from (normalised on
        encoding; zero vectors are rejected).

    Memory: ``BYTES_PER_PHOTON`` = 23 bytes per photon including the tree (12 position,
    6 flux, 4 direction, 1 split axis); ``nbytes`` is the total. Decoding error (see
    encoding.py): each flux channel within 0.049 % of itself, direction within 0.004 deg.

    Attributes (decoded on access, (N, 3) float32, in the map's own heap order):
    ``positions``, ``flux`` (watts), ``directions`` (unit). ``split_axis`` (N,) uint8 and
    ``depth`` describe the tree; ``nearest`` gathers.
    """

    def __init__(self, positions, flux, directions):
        positions = check_points(positions, "positions")
        n = positions.shape[0]
        flux = np.asarray(flux)
        directions = np.asarray(directions)
        if flux.shape != (n, 3):
            raise ValueError(f"flux must have shape ({n}, 3) like positions, got {flux.shape}")
        if directions.shape != (n, 3):
            raise ValueError(
                f"directions must have shape ({n}, 3) like positions, got {directions.shape}")
        # The caller keeps its arrays (the balance reorders a copy of the positions).
        self._build([positions], [flux], [directions])

    @classmethod
    def from_parts(cls, positions, flux, directions) -> "PhotonMap":
        """The map of photons given as lists of pieces (the tracer's per-bounce arrays,
        concatenated in list order), (n_i, 3) each like ``__init__``'s arrays. The lists
        are emptied as the pieces are used, so the construction peaks at about
        ``PEAK_BYTES_PER_PHOTON`` with the pieces counted, instead of copies of them all.
        The map is identical to ``PhotonMap(concatenated arrays)``."""
        if not (len(positions) == len(flux) == len(directions)):
            raise ValueError("positions, flux and directions need the same number of pieces")
        for k, (p, f, d) in enumerate(zip(positions, flux, directions)):
            if np.shape(f) != np.shape(p) or np.shape(d) != np.shape(p):
                raise ValueError(f"piece {k}: flux {np.shape(f)} and directions "
                                 f"{np.shape(d)} must match positions {np.shape(p)}")
            positions[k] = check_points(p, "positions")
        self = cls.__new__(cls)
        self._build(positions, flux, directions)
        return self

    def _build(self, position_parts, flux_parts, direction_parts):
        """Encode the flux and direction pieces in chunks of ENCODE_CHUNK rows, then join
        the positions (in the memory the pieces freed) and balance them in place, then
        gather the codes into the tree's order. Empties the three lists."""
        n = sum(p.shape[0] for p in position_parts)
        if n >= 2**32:  # the search's heap keys hold a photon index in 32 bits
            raise ValueError(f"positions: at most 2^32 - 1 photons per map, got {n}")
        peak = 0.0
        for f in flux_parts:
            f = np.asarray(f)
            if f.size:
                if not np.isfinite(f).all() or (f < 0).any():
                    raise ValueError("flux must be finite and >= 0 (watts)")
                peak = max(peak, float(f.max()))
        self._scale = encoding.flux_scale(np.array([peak]))
        # Encode in the input order (sequential reads), one chunk at a time: float64
        # copies of a chunk only (the codes are the same as for the whole array).
        flux_codes = np.empty((n, 3), np.uint16)
        direction_codes = np.empty((n, 2), np.uint16)
        row = 0
        while flux_parts:
            f, d = np.asarray(flux_parts.pop(0)), np.asarray(direction_parts.pop(0))
            for lo in range(0, f.shape[0], ENCODE_CHUNK):
                hi = min(f.shape[0], lo + ENCODE_CHUNK)
                flux_codes[row + lo:row + hi] = encoding.encode_flux(f[lo:hi], self._scale)
                direction_codes[row + lo:row + hi] = encoding.encode_direction(d[lo:hi])
            row += f.shape[0]
            del f, d
        _release_freed_memory()  # the flux and direction pieces
        positions = (np.concatenate(position_parts) if position_parts
                     else np.zeros((0, 3), np.float32))
        position_parts.clear()
        _release_freed_memory()  # the position pieces, before the balance's arrays
        self._tree, source, self._axis = balance_kernel(positions, in_place=True)
        del positions
        self._flux = np.empty((n, 3), np.uint16)
        self._direction = np.empty((n, 2), np.uint16)
        _gather_codes(flux_codes, direction_codes, source, self._flux, self._direction)
        self._depth = tree_depth(n)

    def __len__(self):
        return self._tree.shape[0]

    @property
    def positions(self) -> np.ndarray:
        """(N, 3) float32 metres, heap order (a read-only view of the stored array)."""
        view = self._tree.view()
        view.flags.writeable = False
        return view

    @property
    def flux(self) -> np.ndarray:
        """(N, 3) float32 watts, heap order (decoded)."""
        return encoding.decode_flux(self._flux, self._scale)

    @property
    def directions(self) -> np.ndarray:
        """(N, 3) float32 unit vectors toward where each photon came from (decoded)."""
        return encoding.decode_direction(self._direction)

    @property
    def split_axis(self) -> np.ndarray:
        """(N,) uint8: the axis (0 x, 1 y, 2 z) of node i's split plane; 0 for leaves."""
        view = self._axis.view()
        view.flags.writeable = False
        return view

    @property
    def depth(self) -> int:
        """Levels of the tree, ceil(log2(N + 1))."""
        return self._depth

    @property
    def nbytes(self) -> int:
        """Bytes held by the map's arrays."""
        return self._tree.nbytes + self._flux.nbytes + self._direction.nbytes + self._axis.nbytes

    def kernel_arrays(self):
        """(tree, axis, depth, flux codes, flux scale, direction codes) for numba kernels."""
        return self._tree, self._axis, self._depth, self._flux, self._scale, self._direction

    def nearest(self, points, k: int, max_radius=np.inf, *, sort_queries: bool = True):
        """The k nearest photons of each point within ``max_radius``.

        points: (M, 3) float32, metres. k >= 1. max_radius >= 0 metres (inf: no limit).
        Returns idx (M, k) int64 into ``positions`` (-1 where fewer than k photons lie
        within the radius) and dist2 (M, k) float32 squared distances, m^2, ascending by
        (distance, index), inf where idx is -1. sort_queries visits the points in Morton
        order (faster for incoherent points; the results do not depend on it).
        """
        points = check_points(points, "points")
        k = check_k(k)
        r2 = squared_radius(max_radius)
        m = points.shape[0]
        idx = np.empty((m, k), np.int64)
        dist2 = np.empty((m, k), np.float32)
        order = query_order(points) if sort_queries else np.arange(m, dtype=np.int64)
        with numba.parallel_chunksize(1):
            nearest_kernel(self._tree, self._axis, self._depth, points, order, k, r2,
                            search_growth(k), idx, dist2)
        return idx, dist2
