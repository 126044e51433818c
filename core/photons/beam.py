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

Boundaries. Photons lie only where the medium scatters, so near a plane where it ends (the
face of a fog box, a floor in the fog) part of each disc around the ray falls where there
are none, and the estimate reads low: half the density on the plane, over a layer as thick
as the radii (the top of a fog box seen at a grazing angle read 10-30 % dark against
Cycles). Where a stretch starts or ends at such a plane (``regions.Stretches.bound0`` /
``bound1``: |cos| c between ray and plane), a photon met at t counts 1 / (the share of the
disc of radius r_i around the ray's point at t, perpendicular to the ray, that lies inside
the medium): the plane cuts that disc at l = (distance to the plane along the ray) x c /
sqrt(1 - c^2) from its centre, and the share is 1 - (acos(l / r) - (l / r) sqrt(1 -
(l / r)^2)) / pi (``disc_inside``). For a uniform density up to the plane the estimate is
then exact at every depth (docs/volumes.md, "Boundaries of the beam estimate").

The query reuses the photon kd-tree's order (kdtree.balance_kernel: left-balanced, heap
order, split planes through the photons), with a bounding box per inner node: the box of its
subtree's photon spheres (position -+ radius, rounded outward to float32). A ray descends
into a child only if it meets the child's box (a leaf: its photon's own test, no box). On
fog_spot's Draft a camera ray collects 588 photons visiting 2,253 nodes, where the
split-plane cells grown by the subtree's largest radius (the query until issue 16's
profile) made it visit 3,337, each visit also copying a cell: 3x less time
(docs/volumes.md, "Where the fog's time goes"). The visiting order is the
same depth-first order as before, so the sum is the same bit for bit.

Memory: 52 B per volume photon (position 12, flux 12, direction 12, radius 4, and the
inner nodes' boxes, 24 B for every other photon), float32 throughout: volume maps are
smaller than surface maps, and the estimate reads every field of every photon it meets.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)
from ..media.phase import hg_eval
from .kdtree import balance_kernel, kth_distance_kernel, query_order, search_growth, tree_depth

BYTES_PER_PHOTON = 12 + 12 + 12 + 4 + 12
"""Bytes per volume photon (module docstring); the boxes are stored for the n // 2
inner nodes, so a map of n photons holds 24 (n // 2) bytes of them."""
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
    d2 = np.empty(n, np.float32)
    kth_distance_kernel(tree, axis, tree_depth(n), positions, query_order(positions), k,
                        np.float32(np.inf), search_growth(k), d2)
    return np.sqrt(d2)


@njit(cache=True, error_model="numpy")
def _sphere_bound(tree, radii, i, a, out):
    """out (2,) float32 <- photon i's sphere along axis a, rounded outward to float32
    (the query's float64 tests must not cut a sphere the float32 box rounded in)."""
    c = np.float64(tree[i, a])
    r = np.float64(radii[i])
    out[0] = np.nextafter(np.float32(c - r), np.float32(-np.inf))
    out[1] = np.nextafter(np.float32(c + r), np.float32(np.inf))


@njit(cache=True, error_model="numpy")
def _subtree_boxes(tree, radii, out):
    """out (n // 2, 6) float32: inner node i's box (lo 0..2, hi 3..5) of the spheres of its
    subtree (children 2i+1, 2i+2; a child past n // 2 is a leaf, its own sphere)."""
    n = tree.shape[0]
    inner = out.shape[0]
    b = np.empty(2, np.float32)
    for i in range(inner - 1, -1, -1):
        for a in range(3):
            _sphere_bound(tree, radii, i, a, b)
            lo = b[0]
            hi = b[1]
            for c in range(2 * i + 1, min(2 * i + 3, n)):
                if c < inner:
                    lo = min(lo, out[c, a])
                    hi = max(hi, out[c, a + 3])
                else:
                    _sphere_bound(tree, radii, c, a, b)
                    lo = min(lo, b[0])
                    hi = max(hi, b[1])
            out[i, a] = lo
            out[i, a + 3] = hi


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
        self.tree = tree
        self.flux = flux[perm]
        self.directions = directions[perm]
        self.radii = radii[perm]
        self.boxes = np.empty((n // 2, 6), np.float32)
        _subtree_boxes(tree, self.radii, self.boxes)

    def __len__(self):
        return int(self.tree.shape[0])

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.tree, self.flux, self.directions, self.radii,
                                      self.boxes))

    def kernel_arrays(self):
        """(tree, flux, directions, radii, inner nodes' boxes (n // 2, 6)) for kernels."""
        return self.tree, self.flux, self.directions, self.radii, self.boxes

    def radiance(self, origins, directions, t_max, sigma_t, g: float,
                 bounds=None) -> np.ndarray:
        """The beam radiance estimate (M, 3) float64, W/(m^2 sr), of M rays: origins,
        unit directions (M, 3) metres, t_max (M,) or scalar metres, in one homogeneous
        medium of extinction sigma_t (3,) 1/m and anisotropy g. bounds (M, 4) float64:
        per ray (c0, a0, c1, a1), the |cos| of the plane where the scattering ends a
        distance a0 before the ray's start and a1 past its end (the module doc; c NaN:
        no plane there), or None: no planes."""
        o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
        d = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
        tm = np.ascontiguousarray(np.broadcast_to(np.asarray(t_max, np.float64), (o.shape[0],)))
        bd = np.full((o.shape[0], 4), np.nan) if bounds is None else \
            np.asarray(bounds, np.float64).reshape(-1, 4)
        out = np.zeros((o.shape[0], 3))
        if len(self):
            # Rays of similar directions one after another (a Morton order of d): they walk
            # the same nodes, which stay in cache (final gathering's rays, in random
            # directions: a quarter less time on fog_spot; each ray's sum is unchanged)
            order = query_order(d.astype(np.float32))
            part = np.empty_like(out)
            beam_rays(*self.kernel_arrays(), np.ascontiguousarray(o[order]),
                      np.ascontiguousarray(d[order]), np.ascontiguousarray(tm[order]),
                      np.ascontiguousarray(bd[order]), np.asarray(sigma_t, np.float64),
                      float(g), part)
            out[order] = part
        return out


@njit(cache=True, error_model="numpy", inline="always")
def _segment_hits_box(ox, oy, oz, ix, iy, iz, t_max, boxes, node):
    """Whether o + t d, t in [0, t_max], meets boxes[node] (lo 0..2, hi 3..5); i = 1 / d
    per axis, inf for a zero component (the ray parallel to that axis's slab)."""
    t0 = 0.0
    t1 = t_max
    for a in range(3):
        o = ox if a == 0 else (oy if a == 1 else oz)
        inv = ix if a == 0 else (iy if a == 1 else iz)
        lo = boxes[node, a]
        hi = boxes[node, a + 3]
        if math.isinf(inv):
            if o < lo or o > hi:
                return False
            continue
        ta = (lo - o) * inv
        tb = (hi - o) * inv
        if ta > tb:
            ta, tb = tb, ta
        t0 = max(t0, ta)
        t1 = min(t1, tb)
        if t0 > t1:
            return False
    return True


@njit(cache=True, error_model="numpy", inline="always")
def _plane_slope(c):
    """c / sqrt(1 - c^2) of a plane at |cos| c to the ray (the distance from the ray's
    point to the plane's line in the disc per unit distance along the ray), inf for a
    plane across the ray, NaN for none."""
    if c != c:
        return c
    s2 = 1.0 - c * c
    return c / math.sqrt(s2) if s2 > 0.0 else math.inf


@njit(cache=True, error_model="numpy", inline="always")
def disc_inside(l, r):
    """The share of a disc of radius r on one side of a line at distance l >= 0 from its
    centre, the centre's side: 1 - (acos(x) - x sqrt(1 - x^2)) / pi, x = l / r (1 for x
    >= 1, 1/2 at x = 0)."""
    x = l / r
    if not x < 1.0:
        return 1.0
    return 1.0 - (math.acos(x) - x * math.sqrt(1.0 - x * x)) / math.pi


@njit(cache=True, error_model="numpy")
def beam_radiance(tree, flux, directions, radii, boxes, ox, oy, oz, dx, dy, dz, t_max, b0c, b0a,
                  b1c, b1a, s0, s1, s2, g, stack):
    """The beam radiance estimate (L0, L1, L2) of one ray (module docstring); b0c, b0a,
    b1c, b1a its planes (``VolumePhotonMap.radiance``'s bounds); stack (STACK,) int64
    scratch. Depth first, a node's photon before its subtrees, the right subtree before
    the left (the order fixes the float sum)."""
    n = tree.shape[0]
    inner = boxes.shape[0]
    L0 = 0.0
    L1 = 0.0
    L2 = 0.0
    ix = 1.0 / dx if dx != 0.0 else math.inf
    iy = 1.0 / dy if dy != 0.0 else math.inf
    iz = 1.0 / dz if dz != 0.0 else math.inf
    grey = s0 == s1 and s1 == s2  # one exp for the three channels (the same value)
    k0 = _plane_slope(b0c)  # NaN: no plane (every comparison with it is False)
    k1 = _plane_slope(b1c)
    top = -1
    if n and (inner == 0 or _segment_hits_box(ox, oy, oz, ix, iy, iz, t_max, boxes, 0)):
        top = 0
        stack[0] = 0
    while top >= 0:
        node = stack[top]
        top -= 1
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
                share = 1.0
                if k0 == k0:
                    share *= disc_inside((t + b0a) * k0, r)
                if k1 == k1:
                    share *= disc_inside((t_max - t + b1a) * k1, r)
                k = hg_eval(g, cos) / (math.pi * r * r * share)
                e0 = math.exp(-s0 * t)
                e1 = e0 if grey else math.exp(-s1 * t)
                e2 = e0 if grey else math.exp(-s2 * t)
                L0 += flux[node, 0] * k * e0
                L1 += flux[node, 1] * k * e1
                L2 += flux[node, 2] * k * e2
        # Children whose box the ray meets (a leaf has no box: its photon's test decides)
        for c in range(2 * node + 1, min(2 * node + 3, n)):
            if c >= inner or _segment_hits_box(ox, oy, oz, ix, iy, iz, t_max, boxes, c):
                top += 1
                stack[top] = c
    return L0, L1, L2


@njit(cache=True, parallel=True, error_model="numpy")
def beam_rays(tree, flux, directions, radii, boxes, origins, dirs, t_max, bounds, sigma_t, g,
              out):
    """beam_radiance for M rays -> out (M, 3); bounds (M, 4) their planes."""
    m = origins.shape[0]
    blocks = (m + 63) // 64
    for b in prange(blocks):
        stack = np.empty(STACK, np.int64)
        for i in range(b * 64, min(m, (b + 1) * 64)):
            out[i, 0], out[i, 1], out[i, 2] = beam_radiance(
                tree, flux, directions, radii, boxes, origins[i, 0], origins[i, 1],
                origins[i, 2], dirs[i, 0], dirs[i, 1], dirs[i, 2], t_max[i], bounds[i, 0],
                bounds[i, 1], bounds[i, 2], bounds[i, 3], sigma_t[0], sigma_t[1], sigma_t[2],
                g, stack)
