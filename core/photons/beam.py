"""The volume photon map and its beam radiance estimate (Jarosz, Zwicker and Jensen 2008,
"The beam radiance estimate for volumetric photon mapping"); docs/volumes.md.

Volume photons are stored where a photon scatters in a medium, with the flux it scatters
there (W, RGB: the free-flight weight includes sigma_s, media/free_flight.py), its
propagation direction before scattering and a radius r_i (metres) from the distance to its
k-th nearest photon (``photon_radii``). Each photon is a sphere of radius r_i; a camera ray
o + t d, t in [0, t_max], crossing it collects

    L += flux_i * p(cos_i) * exp(-sigma_t t_i) / (pi r_i^2),

t_i = (x_i - o) . d the photon's distance along the ray (in [0, t_max]), cos_i between the
photon's direction and -d (the way to the camera), p the Henyey-Greenstein phase of the
ray's medium, exp(-sigma_t t_i) its homogeneous transmittance: the 3-D volume estimate
integrated along the ray in closed form, with a constant kernel over each photon's disc.
The result is the radiance (W/(m^2 sr)) scattered into the ray by all the stored light
(multiple scattering and volumetric caustics), to be attenuated no further.

The query reuses the photon kd-tree (kdtree.balance_kernel: left-balanced, heap order,
split planes through the photons): each node also keeps the largest radius of its subtree,
so a ray visits a node only if it passes the node's cell grown by that radius.

Memory: 45 B per volume photon (position 12, flux 12, direction 12, radius 4, subtree
radius 4, split axis 1), float32 throughout: volume maps are smaller than surface maps,
and the estimate reads every field of every photon it meets.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..media.phase import hg_eval
from .kdtree import balance_kernel, nearest_kernel, query_order, search_growth, tree_depth

BYTES_PER_PHOTON = 12 + 12 + 12 + 4 + 4 + 1
STACK = 128  # deferred nodes of one ray's traversal (the tree's depth is at most 64)


def photon_radii(positions, k: int) -> np.ndarray:
    """Distance (N,) float32, metres, from each photon to its k-th nearest photon, itself
    counted (k >= 2; fewer photons than k: the farthest one's distance).

    positions: (N, 3) float32, metres.
    """
    positions = np.ascontiguousarray(positions, np.float32)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError(f"volume photon positions must have shape (N, 3), got {positions.shape}")
    if int(k) < 2:
        raise ValueError(f"volume photon radius k must be >= 2, got {k}")
    n = positions.shape[0]
    if n == 0:
        return np.zeros(0, np.float32)
    k = min(int(k), n)
    tree, _, axis = balance_kernel(positions)
    idx = np.empty((n, k), np.int64)
    d2 = np.empty((n, k), np.float32)
    nearest_kernel(tree, axis, tree_depth(n), positions, query_order(positions), k,
                   np.float32(np.inf), search_growth(k), idx, d2)
    return np.sqrt(d2[:, k - 1]).astype(np.float32)


@njit(cache=True, error_model="numpy")
def _subtree_radius(radius, out):
    """out[i] = the largest radius in node i's subtree (children 2i+1, 2i+2)."""
    n = radius.shape[0]
    for i in range(n - 1, -1, -1):
        r = radius[i]
        c = 2 * i + 1
        if c < n:
            r = max(r, out[c])
        if c + 1 < n:
            r = max(r, out[c + 1])
        out[i] = r


class VolumePhotonMap:
    """Volume photons in a kd-tree for the beam radiance estimate (module docstring).

    positions (N, 3) float32 metres, flux (N, 3) float32 W, directions (N, 3) float32
    unit propagation directions, radii (N,) float32 metres (``photon_radii``), all > 0.
    """

    def __init__(self, positions, flux, directions, radii):
        positions = np.ascontiguousarray(positions, np.float32)
        n = positions.shape[0]
        flux = np.ascontiguousarray(flux, np.float32)
        directions = np.ascontiguousarray(directions, np.float32)
        radii = np.ascontiguousarray(radii, np.float32)
        for name, a, shape in (("positions", positions, (n, 3)), ("flux", flux, (n, 3)),
                               ("directions", directions, (n, 3)), ("radii", radii, (n,))):
            if a.shape != shape:
                raise ValueError(f"volume photon {name} must have shape {shape}, got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"volume photon {name} holds a non-finite value")
        if np.any(flux < 0):
            raise ValueError("volume photon flux must be >= 0")
        if np.any(radii <= 0):
            raise ValueError("volume photon radii must be > 0")
        tree, perm, axis = balance_kernel(positions)
        self.tree, self.axis = tree, axis
        self.flux = flux[perm]
        self.directions = directions[perm]
        self.radii = radii[perm]
        self.subtree_radius = np.empty(n, np.float32)
        _subtree_radius(self.radii, self.subtree_radius)
        lo = positions.min(axis=0) if n else np.zeros(3, np.float32)
        hi = positions.max(axis=0) if n else np.zeros(3, np.float32)
        self.bounds = np.concatenate([lo, hi]).astype(np.float64)

    def __len__(self):
        return int(self.tree.shape[0])

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.tree, self.axis, self.flux, self.directions,
                                      self.radii, self.subtree_radius))

    def kernel_arrays(self):
        """(tree, axis, flux, directions, radii, subtree radius, bounds (6,)) for kernels."""
        return (self.tree, self.axis, self.flux, self.directions, self.radii,
                self.subtree_radius, self.bounds)

    def radiance(self, origins, directions, t_max, sigma_t, g: float) -> np.ndarray:
        """The beam radiance estimate (M, 3) float64, W/(m^2 sr), of M rays: origins,
        unit directions (M, 3) metres, t_max (M,) or scalar metres, in one homogeneous
        medium of extinction sigma_t (3,) 1/m and anisotropy g."""
        o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
        d = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
        tm = np.ascontiguousarray(np.broadcast_to(np.asarray(t_max, np.float64), (o.shape[0],)))
        out = np.zeros((o.shape[0], 3))
        if len(self):
            beam_rays(*self.kernel_arrays(), o, d, tm, np.asarray(sigma_t, np.float64),
                      float(g), out)
        return out


@njit(cache=True, error_model="numpy")
def _segment_hits_box(ox, oy, oz, dx, dy, dz, t_max, box, grow):
    """Whether o + t d, t in [0, t_max], meets the box (lo 0..2, hi 3..5) grown by ``grow``."""
    t0 = 0.0
    t1 = t_max
    for a in range(3):
        o = ox if a == 0 else (oy if a == 1 else oz)
        d = dx if a == 0 else (dy if a == 1 else dz)
        lo = box[a] - grow
        hi = box[a + 3] + grow
        if d == 0.0:
            if o < lo or o > hi:
                return False
            continue
        inv = 1.0 / d
        ta = (lo - o) * inv
        tb = (hi - o) * inv
        if ta > tb:
            ta, tb = tb, ta
        t0 = max(t0, ta)
        t1 = min(t1, tb)
        if t0 > t1:
            return False
    return True


@njit(cache=True, error_model="numpy")
def beam_radiance(tree, axis, flux, directions, radii, subtree_radius, bounds, ox, oy, oz,
                  dx, dy, dz, t_max, s0, s1, s2, g, stack_node, stack_box):
    """The beam radiance estimate (L0, L1, L2) of one ray (module docstring); stack_node
    (STACK,) int64 and stack_box (STACK, 6) float64 scratch."""
    n = tree.shape[0]
    L0 = 0.0
    L1 = 0.0
    L2 = 0.0
    box = np.empty(6)
    top = 0
    stack_node[0] = 0
    stack_box[0, :] = bounds
    while top >= 0:
        node = stack_node[top]
        box[:] = stack_box[top]
        top -= 1
        if node >= n or not _segment_hits_box(ox, oy, oz, dx, dy, dz, t_max, box,
                                               subtree_radius[node]):
            continue
        # This node's photon: does the ray cross its disc within the segment?
        vx = tree[node, 0] - ox
        vy = tree[node, 1] - oy
        vz = tree[node, 2] - oz
        t = vx * dx + vy * dy + vz * dz
        r = radii[node]
        if 0.0 <= t <= t_max:
            d2 = vx * vx + vy * vy + vz * vz - t * t
            if d2 <= r * r:
                cos = -(directions[node, 0] * dx + directions[node, 1] * dy
                        + directions[node, 2] * dz)
                k = hg_eval(g, cos) / (math.pi * r * r)
                L0 += flux[node, 0] * k * math.exp(-s0 * t)
                L1 += flux[node, 1] * k * math.exp(-s1 * t)
                L2 += flux[node, 2] * k * math.exp(-s2 * t)
        # Children: the split plane through this photon halves the cell.
        left = 2 * node + 1
        if left < n:
            ax = axis[node]
            split = tree[node, ax]
            top += 1
            stack_node[top] = left
            stack_box[top, :] = box
            stack_box[top, ax + 3] = split
            if left + 1 < n:
                top += 1
                stack_node[top] = left + 1
                stack_box[top, :] = box
                stack_box[top, ax] = split
    return L0, L1, L2


@njit(cache=True, parallel=True, error_model="numpy")
def beam_rays(tree, axis, flux, directions, radii, subtree_radius, bounds, origins, dirs, t_max,
              sigma_t, g, out):
    """beam_radiance for M rays -> out (M, 3)."""
    m = origins.shape[0]
    blocks = (m + 63) // 64
    for b in prange(blocks):
        stack_node = np.empty(STACK, np.int64)
        stack_box = np.empty((STACK, 6))
        for i in range(b * 64, min(m, (b + 1) * 64)):
            out[i, 0], out[i, 1], out[i, 2] = beam_radiance(
                tree, axis, flux, directions, radii, subtree_radius, bounds, origins[i, 0],
                origins[i, 1], origins[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2], t_max[i],
                sigma_t[0], sigma_t[1], sigma_t[2], g, stack_node, stack_box)
