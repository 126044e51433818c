"""Heterogeneous density: rho(x) of the media whose density a shader program gives, and the
majorant each is tracked with (docs/volumes.md "Heterogeneous density").

This module owns the bound and the clipping; the program itself is run by
core/shading/interpreter.py, bound to each medium by core/prepared.py (rank 3: media and
shading are both rank 2) as ``evaluate(points (K, 3) float64 render-frame metres) -> (K,)``
(it builds the program's Position, Object and Generated inputs as at a surface hit).

**The majorant.** Null-collision tracking needs sigma_bar >= sigma_t(x) on every segment it
walks; an underestimate biases the result. A program is not bounded analytically (a Noise
texture's range depends on its detail, roughness and distortion), so the bound is measured,
**per cell of a GRID^3 grid** over the medium's world box (``MajorantGrid``): the program at
every cell's 8 corners and centre, the cell's maximum dilated by one cell (the maximum of
its 27 neighbours: a feature between lattice points of a neighbouring cell is covered),
times SAFETY. A segment is tracked with the largest value of the cells it crosses
(``segment_majorant``, a 3-D DDA): in a sparse medium the rays through its empty cells
make no null collisions. Between lattice points a smooth texture can exceed the sampled
maximum, which SAFETY and the dilation cover for features larger than a cell; where a
tracked point still exceeds its cell's value, the density is clipped to it (a bias, bounded
by what was clipped) and counted per medium (``take_clipping``, ``warnings``), which the
render reports as a warning naming the medium (in the log and in Blender's report). A negative program value is taken as 0 (Cycles clamps the
density at 0 too: ``fmaxf(density, 0.0f)`` in svm_node_principled_volume).

**A varying colour** (issue 16): a medium whose program also gives Color and Absorption
Color has six factors per point instead of rho (``DensityFields`` doc); the grid bounds the
largest, and ``along`` / ``scattering`` hand the trackers and Volume Direct per-channel
values (docs/volumes.md "Varying colour").
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _numba_cache  # noqa: F401  (per-package numba cache, before any @njit)

GRID = 24
"""Cells per axis of the majorant grid (25^3 corners + 24^3 centres = 29,449 evaluations)."""

SAFETY = 1.5
"""The measured maximum is multiplied by this to give the majorant."""


class DensityFields:
    """The densities of a scene's heterogeneous media.

    evaluators: {medium row: evaluate(points (K, 3) float64 metres) -> (K,) float} the
    program's value, or for the rows in ``colour`` (a varying colour) -> (K, 7): the
    density, Color (3), Absorption Color (3) (core/scene/media.py); boxes: {medium row:
    (lo, hi) (3,) metres} the region the majorant covers (the medium's boundary box; the
    World's: the box its varying part fills, core/media/regions.py); names: the media's
    names.

    A colour medium's "density" is six factors per point (``principled_volume_coefficients``:
    the absorption's per channel, then the scattering's, each rho x a colour term), which
    the row's sigma_a, sigma_s (weights) multiply; the majorant grid is measured on their
    largest, so it bounds every factor.
    """

    def __init__(self, evaluators: dict, boxes: dict, names, colour=()):
        self.evaluators = dict(evaluators)
        self.names = tuple(names)
        self.colour = frozenset(int(m) for m in colour)
        self.boxes = {m: (np.asarray(boxes[m][0], np.float64), np.asarray(boxes[m][1], np.float64))
                      for m in self.evaluators}
        # The clipping since the last ``take_clipping`` (its block), and the blocks taken
        # before it: together every tracked point's since the fields were made
        self._clipping = {}
        self._taken = {}
        self.grids = {m: MajorantGrid.measure(self._largest(m), *boxes[m])
                      for m in self.evaluators}
        # The medium's bound over its whole box (the decisions' figure)
        self.majorant = {m: float(g.cells.max()) for m, g in self.grids.items()}

    def _raw(self, m: int):
        """rho of medium m at world points (K, 3) -> (K,) float64, not clipped; a colour
        medium: its factors (K, 6) (class doc)."""
        ev = self.evaluators[m]
        if m in self.colour:
            def factors(points):
                v = np.asarray(ev(np.asarray(points, np.float64)), np.float64).reshape(-1, 7)
                v = np.where(np.isfinite(v), v, 0.0)
                sa, ss = principled_volume_coefficients(v[:, 0], v[:, 1:4], v[:, 4:7])
                return np.concatenate([sa, ss], axis=1)
            return factors

        def rho(points):
            v = np.asarray(ev(np.asarray(points, np.float64)), np.float64)
            return np.where(np.isfinite(v), np.maximum(v, 0.0), 0.0)
        return rho

    def _largest(self, m: int):
        """What the majorant grid of medium m bounds: rho, or a colour medium's largest
        factor, at points (K, 3) -> (K,)."""
        raw = self._raw(m)
        if m not in self.colour:
            return raw
        return lambda points: raw(points).max(axis=1)

    def __call__(self, points, field) -> np.ndarray:
        """rho (K,) float64 at world points (K, 3) metres of the media field (K,) int64,
        clipped to each medium's majorant (module doc). Media of a constant colour only
        (``scattering`` serves both)."""
        p = np.asarray(points, np.float64).reshape(-1, 3)
        f = np.asarray(field, np.int64).reshape(-1)
        out = np.zeros(p.shape[0])
        for m in np.unique(f):
            if int(m) in self.colour:
                raise ValueError(f"medium '{self.names[int(m)]}' has a varying colour: its "
                                 f"density is per channel (DensityFields.scattering)")
            sel = np.flatnonzero(f == m)
            out[sel] = self._clipped(int(m), p[sel], self.grids[int(m)].at(p[sel]))
        return out

    def scattering(self, points, field) -> np.ndarray:
        """The factor of the rows' sigma_s at world points (K, 3) metres of the media field
        (K,) int64, clipped as ``__call__``: (K, 1) rho where no medium of a varying colour
        is in the scene (the arithmetic of a constant colour), else (K, 3)."""
        if not self.colour:
            return self(points, field)[:, None]
        p = np.asarray(points, np.float64).reshape(-1, 3)
        f = np.asarray(field, np.int64).reshape(-1)
        out = np.zeros((p.shape[0], 3))
        for m in np.unique(f):
            sel = np.flatnonzero(f == m)
            v = self._clipped(int(m), p[sel], self.grids[int(m)].at(p[sel]))
            out[sel] = v[:, 3:] if int(m) in self.colour else v[:, None]
        return out

    def _clipped(self, m: int, points, bound) -> np.ndarray:
        """rho of medium m at points (K, 3) clipped to bound (K,), the clipping counted (a
        colour medium: its factors (K, 6), each clipped)."""
        v = self._raw(m)(points)
        b = bound if v.ndim == 1 else bound[:, None]
        over = v > b
        if over.any():
            hit = over if v.ndim == 1 else over.any(axis=1)
            merge_clipping(self._clipping, {m: (self.names[m], self.majorant[m],
                                                int(hit.sum()), float(v[over].max()))})
            v = np.minimum(v, b)
        return v

    def segment_majorant(self, field, origins, directions, t0, t1) -> np.ndarray:
        """(N,) float64: the majorant of N segments o + t d, t in [t0, t1] metres (finite),
        of media field (N,) int64: the largest grid value of the cells each crosses."""
        f = np.asarray(field, np.int64).reshape(-1)
        out = np.zeros(f.shape[0])
        o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
        d = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
        a = np.ascontiguousarray(np.broadcast_to(np.asarray(t0, np.float64), f.shape))
        b = np.ascontiguousarray(np.broadcast_to(np.asarray(t1, np.float64), f.shape))
        for m in np.unique(f):
            sel = np.flatnonzero(f == m)
            g = self.grids[int(m)]
            res = np.empty(sel.size)
            _segment_max_kernel(g.cells, g.lo, g.size, o[sel], d[sel], a[sel], b[sel], res)
            out[sel] = res
        return out

    def along(self, field, majorant, het_a=None, het_s=None):
        """The density of N tracked segments as the trackers call it: a function
        (points (K, 3), k (K,) int64 segment index) -> rho (K,) of medium field[k], clipped
        to the point's cell value and to the segment's majorant[k] (the two agree but where
        a point on a cell's face falls on the other side of the DDA; counted as clipping).

        With a medium of a varying colour in the scene the factors are per channel
        (``tracking``'s per-channel densities): het_a, het_s (N, 3) the segments' row
        coefficients given -> (K, 3) extinction factors for ratio tracking (a colour
        medium's (f_a het_a + f_s het_s) / (het_a + het_s)); not given -> (K, 6) the
        absorption's and scattering's factors for delta tracking. Media of a constant
        colour give rho in every column (the same arithmetic)."""
        f = np.asarray(field, np.int64).reshape(-1)
        maj = np.asarray(majorant, np.float64).reshape(-1)
        colour = bool(self.colour) and bool(np.isin(f, list(self.colour)).any())
        if colour and het_a is not None:
            ha = np.asarray(het_a, np.float64).reshape(-1, 3)
            hs = np.asarray(het_s, np.float64).reshape(-1, 3)
            ht = ha + hs

        def rho(points, k):
            p = np.asarray(points, np.float64).reshape(-1, 3)
            k = np.asarray(k, np.int64).reshape(-1)
            width = 1 if not colour else (3 if het_a is not None else 6)
            out = np.zeros(p.shape[0]) if width == 1 else np.zeros((p.shape[0], width))
            fk = f[k]
            for m in np.unique(fk):
                sel = np.flatnonzero(fk == m)
                bound = np.minimum(self.grids[int(m)].at(p[sel]), maj[k[sel]])
                v = self._clipped(int(m), p[sel], bound)
                if width == 1 or int(m) not in self.colour:
                    out[sel] = v if width == 1 else v[:, None]
                elif width == 6:
                    out[sel] = v
                else:
                    kk = k[sel]
                    t = ht[kk]
                    out[sel] = np.where(t > 0, (v[:, :3] * ha[kk] + v[:, 3:] * hs[kk])
                                        / np.where(t > 0, t, 1.0), 0.0)
            return out
        return rho

    def take_clipping(self) -> dict:
        """The clipping since the last call (or since the fields were made), then restarted:
        {medium row: (name, majorant, tracked points clipped, largest density clipped)} of
        the media that clipped (``merge_clipping``'s block; ``warnings`` keeps the totals)."""
        block, self._clipping = self._clipping, {}
        merge_clipping(self._taken, block)
        return block

    def warnings(self) -> list[str]:
        """One message per medium whose majorant a tracked point exceeded (every tracked
        point since the fields were made: the blocks taken and the one since)."""
        total = dict(self._taken)
        merge_clipping(total, self._clipping)
        return clipping_warnings(total)


def merge_clipping(total: dict, block: dict) -> None:
    """Add a block's clipping ({medium row: (name, majorant, tracked points clipped,
    largest density clipped)}, ``DensityFields.take_clipping``) to total, in place."""
    for m, (name, majorant, n, peak) in block.items():
        _, _, n0, peak0 = total.get(m, (name, majorant, 0, 0.0))
        total[m] = (name, majorant, n0 + n, max(peak0, peak))


def clipping_warnings(total: dict) -> list[str]:
    """One message per medium of ``total`` ({medium row: (name, majorant, tracked points
    clipped, largest density clipped)}, ``merge_clipping``) that clipped, by row."""
    return [f"medium '{name}': the density reached {peak:.4g} at "
            f"{n} tracked points, above the majorant of their cells (at most "
            f"{majorant:.4g}; measured per cell of a {GRID}^3 grid x {SAFETY}); "
            f"clipped there (biased: the texture has features finer than the grid)"
            for _, (name, majorant, n, peak) in sorted(total.items()) if n]


class MajorantGrid:
    """Per-cell majorants of one density over the box [lo, hi] (module doc): cells
    (G, G, G) float64, lo (3,) metres, size (3,) metres per cell."""

    def __init__(self, cells, lo, size):
        self.cells = np.ascontiguousarray(cells, np.float64)
        self.lo = np.asarray(lo, np.float64)
        self.size = np.asarray(size, np.float64)

    @classmethod
    def measure(cls, rho, lo, hi, grid: int = GRID, safety: float = SAFETY) -> "MajorantGrid":
        """rho(points (K, 3)) -> (K,) at every cell's corners and centre, per cell the
        maximum, dilated by one cell, times ``safety``."""
        lo = np.asarray(lo, np.float64)
        hi = np.asarray(hi, np.float64)
        size = np.maximum(hi - lo, 1e-12) / grid
        corner_axes = [lo[k] + np.arange(grid + 1) * size[k] for k in range(3)]
        centre_axes = [lo[k] + (np.arange(grid) + 0.5) * size[k] for k in range(3)]
        pc = np.stack(np.meshgrid(*corner_axes, indexing="ij"), -1).reshape(-1, 3)
        pm = np.stack(np.meshgrid(*centre_axes, indexing="ij"), -1).reshape(-1, 3)
        vc = rho(pc).reshape((grid + 1,) * 3)
        cells = rho(pm).reshape((grid,) * 3)
        for dx in (0, 1):
            for dy in (0, 1):
                for dz in (0, 1):
                    cells = np.maximum(cells, vc[dx:dx + grid, dy:dy + grid, dz:dz + grid])
        pad = np.pad(cells, 1)
        dil = cells.copy()
        for dx in range(3):
            for dy in range(3):
                for dz in range(3):
                    dil = np.maximum(dil, pad[dx:dx + grid, dy:dy + grid, dz:dz + grid])
        return cls(safety * dil, lo, size)

    def at(self, points) -> np.ndarray:
        """(K,) the value of the cell holding each point (K, 3) metres (clamped to the
        grid: a point just outside the box reads its nearest cell)."""
        g = np.array(self.cells.shape)
        i = np.clip(np.floor((np.asarray(points, np.float64) - self.lo) / self.size),
                    0, g - 1).astype(np.int64)
        return self.cells[i[:, 0], i[:, 1], i[:, 2]]


@njit(cache=True, error_model="numpy")
def _segment_max_kernel(cells, lo, size, o, d, t0, t1, out):
    """The largest cell value along each segment (Amanatides-Woo DDA over the cells from
    the point at t0 to the point at t1, indices clamped to the grid)."""
    g0, g1, g2 = cells.shape
    gmax = np.array([g0 - 1, g1 - 1, g2 - 1])
    for i in range(o.shape[0]):
        cell = np.empty(3, np.int64)
        step = np.empty(3, np.int64)
        t_next = np.empty(3)
        t_delta = np.empty(3)
        for k in range(3):
            p = o[i, k] + t0[i] * d[i, k]
            c = int(np.floor((p - lo[k]) / size[k]))
            c = min(max(c, 0), gmax[k])
            cell[k] = c
            if d[i, k] > 0.0:
                step[k] = 1
                t_next[k] = t0[i] + (lo[k] + (c + 1) * size[k] - p) / d[i, k]
                t_delta[k] = size[k] / d[i, k]
            elif d[i, k] < 0.0:
                step[k] = -1
                t_next[k] = t0[i] + (lo[k] + c * size[k] - p) / d[i, k]
                t_delta[k] = -size[k] / d[i, k]
            else:
                step[k] = 0
                t_next[k] = np.inf
                t_delta[k] = np.inf
        best = cells[cell[0], cell[1], cell[2]]
        for _ in range(g0 + g1 + g2 + 3):
            k = 0
            if t_next[1] < t_next[k]:
                k = 1
            if t_next[2] < t_next[k]:
                k = 2
            if not (t_next[k] < t1[i]):
                break
            c = cell[k] + step[k]
            if c < 0 or c > gmax[k]:
                break
            cell[k] = c
            t_next[k] += t_delta[k]
            v = cells[cell[0], cell[1], cell[2]]
            if v > best:
                best = v
        out[i] = best


def measure_majorant(rho, lo, hi, grid: int = GRID, safety: float = SAFETY) -> float:
    """SAFETY x the maximum of rho(points (K, 3)) over a grid^3 lattice of cell centres of
    the box [lo, hi] (metres) and its 8 corners (module doc)."""
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    axes = [lo[k] + (np.arange(grid) + 0.5) / grid * (hi[k] - lo[k]) for k in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    corners = np.array([[(lo, hi)[(c >> k) & 1][k] for k in range(3)] for c in range(8)])
    v = rho(np.concatenate([pts, corners]))
    return float(safety * v.max()) if v.size else 0.0


def principled_volume_coefficients(rho, color, absorption_color):
    """Cycles' Principled Volume coefficients at K points (svm_node_principled_volume, as
    photon_engine/export_volumes.py reads it for constant inputs): sigma_s = C rho,
    sigma_a = max(1 - C, 0) max(1 - sqrt(A), 0) rho.

    rho (K,) density (negative taken as 0, as Cycles), color C and absorption_color A
    (K, 3) or (3,). Returns (sigma_a, sigma_s), (K, 3) float64 each, 1/m: the per-point
    coefficients of a medium whose colour varies (a Color / Absorption Color fed by nodes);
    their sum over a constant extinction gives ``tracking.ratio_tracking_batch``'s
    per-channel factors."""
    r = np.maximum(np.asarray(rho, np.float64), 0.0)[:, None]
    c = np.maximum(np.asarray(color, np.float64), 0.0)
    a = np.sqrt(np.maximum(np.asarray(absorption_color, np.float64), 0.0))
    sigma_s = np.broadcast_to(c * r, (r.shape[0], 3))
    sigma_a = np.broadcast_to(np.maximum(1.0 - c, 0.0) * np.maximum(1.0 - a, 0.0) * r,
                              (r.shape[0], 3))
    return np.ascontiguousarray(sigma_a), np.ascontiguousarray(sigma_s)
